// The Tracer interface: one field update (trace probe rays, shade hits, blend into the
// atlases, fix borders, classify and relocate probes, mark changed bricks). Three backends
// implement it and must agree within a stated tolerance: Embree on the CPU, Vulkan
// ray-tracing pipelines on a GPU, and a signed-distance-field tracer in Vulkan compute
// (VulkanTracing::DistanceField) for GPUs without ray tracing.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "../common/field.h"
#include "../common/result.h"
#include "../common/scene.h"

namespace pc {

// One probe to update: cascade and slot.
struct ProbeRef {
  int cascade = 0;
  int slot = 0;
};

struct UpdateRequest {
  std::uint32_t rotationSeed = 0;  // picks the random rotation of the ray directions
  std::vector<ProbeRef> probes;    // probes to update this tick (see ProbeScheduler)
  int shading = 0;                 // ShadingFlags
  float changeThreshold = 0.0f;    // encoded-irradiance change that marks a brick changed
};

enum ShadingFlags : int {
  kShadeDefault = 0,
  kShadeNoIndirect = 1,  // single bounce: do not sample the previous field at hits
};

struct UpdateStats {
  double traceMs = 0, shadeMs = 0, blendMs = 0, totalMs = 0;  // trace+shade are fused on the CPU
  // GPU backends: timestamps of each pass in execution order (name, ms) and their sum. The
  // Vulkan tracer's passes: upload, tlas, trace (probe rays to their closest hits), shade
  // (hits and shadow-ray requests), shadow trace, blend (visible light added; blend, borders,
  // classification, relocation), changes (brick detection + packing), readback. Its shadeMs
  // is shade + shadow trace.
  std::vector<std::pair<std::string, double>> gpuPasses;
  double gpuMs = 0;
  std::uint64_t readbackBytes = 0;  // bytes copied back to the host (changed bricks, records)
  std::uint64_t probeRays = 0;
  std::uint64_t shadowRays = 0;
  int probesUpdated = 0;
  int bricksChanged = 0;
};

// setState and update return an Error where the backend can no longer run: a GPU lost or out
// of memory, an update past the device's limits (the message names the call and the error).
// The field is left as the last completed update left it (a backend writes the host field
// only once an update completed), and the tracer fails every later call: the caller goes on
// with another backend (FieldLoopOptions::fallback) or without updates.
class Tracer {
 public:
  virtual ~Tracer() = default;
  virtual std::string name() const = 0;
  // Moves lights and animated instances to `state` (refit or rebuild as needed).
  virtual Status setState(const SceneState& state) = 0;
  // Runs one update on `field`. On return the field's version is bumped when any brick
  // changed, and those bricks carry the new version.
  virtual Result<UpdateStats> update(Field& field, const UpdateRequest& request) = 0;
};

struct TracerOptions {
  int emissiveSamples = 1;  // light samples toward emissive triangles per hit
  // Russian roulette on punctual lights' shadow rays (shaders/interop/shadow_roulette.h): a
  // light below this share of a hit's unshadowed punctual light gets its shadow ray at random,
  // weighted to keep the expected light. 0 traces every shadow ray. The default, 0.25, took
  // pandora's shadow rays from 1.26 M to 0.75 M per update and a 40-light room's 10x fewer,
  // with the probe-lit image's PSNR against the reference unchanged (docs/BENCHMARKS.md).
  float shadowRouletteShare = 0.25f;
};

Result<std::unique_ptr<Tracer>> makeEmbreeTracer(const Scene& scene,
                                                 const TracerOptions& options = {});

struct VulkanTracerOptions;

// The backend by name (--backend): "embree"; "vulkan" (any Vulkan device with ray tracing,
// lavapipe included); "sdf" (any Vulkan device with compute: a distance field sphere-traced in
// compute shaders, lavapipe included); "auto" or "" (a GPU with ray tracing, else a GPU for the
// SDF backend, else Embree, saying in the log which and why).
// `vulkan`, where given, sets the Vulkan backend's options but allowCpuDevice, which the
// backend's name decides.
Result<std::unique_ptr<Tracer>> makeTracer(const Scene& scene, const std::string& backend,
                                           const TracerOptions& options = {},
                                           const VulkanTracerOptions* vulkan = nullptr);

// Every probe of the field, for full updates.
std::vector<ProbeRef> allProbes(const Field& field);

}  // namespace pc
