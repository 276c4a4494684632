// The GPU backend of the Tracer interface: Vulkan ray-tracing pipelines (no ray queries, which
// NVIDIA's data-centre GPUs lack) trace the probe rays and, after a compute pass shaded their
// hits, the shadow rays (a wavefront: shaders/interop/gpu_trace.h); compute shaders blend them
// into the atlases, fix the borders, classify and relocate probes and pack the changed
// bricks. The GPU holds the field between updates; only changed bricks' tiles and the probe
// records come back into the pc::Field, which stays the host mirror the encoder and baked
// files use.
//
// Host edits to a field are picked up at the next update: probe records are compared with
// what the GPU holds, and a different Field object or version uploads the atlases again.
// Base colour and emissive textures are sampled (bindless texture array, bilinear, level 0,
// like the CPU's Texture::sample).
#pragma once

#include <memory>
#include <string>

#include "../common/vulkan/context.h"
#include "../shaders/interop/gpu_trace.h"
#include "../shaders/interop/sdf_grid.h"
#include "ldm_occlusion.h"
#include "tracer.h"

namespace pc {

// How the Vulkan tracer finds the probe and shadow rays' hits.
enum class VulkanTracing {
  // Ray-tracing pipelines against acceleration structures (VK_KHR_ray_tracing_pipeline).
  RayPipelines,
  // The SDF backend: compute shaders sphere-trace a sparse distance field of the scene, built on
  // the GPU (shaders/interop/sdf_grid.h), on any Vulkan device with compute and descriptor
  // indexing, no ray tracing. Hits land exactly on triangles (the nearest triangles of the
  // voxel's corners are tested), so shading, emitters, textures and the blend are the same.
  DistanceField,
};

// The SDF backend's last distance-field build.
struct SdfBuildStats {
  int builds = 0;       // builds so far (the first update, then after instances moved)
  bool update = false;  // the last was an update: only the bricks near moved triangles
  int bricksBuilt = 0;  // bricks the last build or update filled
  double gpuMs = 0;     // the last build's GPU time: both passes
  double cellsMs = 0;   // its coarse-cell pass
  double bricksMs = 0;  // its brick pass
  int triangles = 0;
  int cells = 0;          // coarse cells
  int bricks = 0;         // bricks allocated (near cells; after updates also unused ones)
  float voxel = 0;        // voxel side, metres
  std::size_t bytes = 0;  // the grid's, bricks' and triangles' device memory
};

// The SDF backend's distance field as read back for tests: the header, the cells and the
// allocated bricks' samples, and the triangles (interop/sdf_grid.h).
struct SdfFieldCopy {
  gpu::SdfHeader header{};
  std::vector<gpu::SdfCell> cells;
  std::vector<gpu::SdfSample> samples;
  std::vector<gpu::SdfTriangle> triangles;
};

struct VulkanTracerOptions {
  bool validation = false;      // Khronos validation layer; errors are counted (tests fail on any)
  bool allowCpuDevice = false;  // lavapipe
  std::string deviceNameFilter;
  // Launch the shadow rays over the most the list can hold even where the device could launch
  // exactly the list from a buffer (vkCmdTraceRaysIndirectKHR): the fallback path, for tests
  // and for measuring what the exact launch saves.
  bool boundedShadowLaunch = false;
  // The most bytes the shadow slots' per-ray records may take (each slot holds a shadow ray and
  // its light for every probe ray of an update: 48 bytes a ray). An update with more lights
  // and emissive samples than fit runs its shading and shadow rays in rounds of as many slots
  // as fit, with the same field (gpu_trace.h: pcShadowRounds). 0: a quarter of the device's
  // largest device-local memory heap, at most 8 GiB.
  std::size_t shadowMemoryBudget = 0;
  // The most bytes one per-ray buffer may span (0: the device's maxStorageBufferRange). Passes
  // (maxPassRays) and shadow rounds hold to it; only a single probe with more rays than one
  // buffer spans is refused, with a message naming the limit. Smaller values only serve tests.
  std::size_t maxStorageBufferBytes = 0;
  // The most probe rays one pass of an update traces, shades and blends (0: as many as keep
  // each per-ray buffer within the storage-buffer range and the per-ray records within a
  // quarter of the device-local memory). A larger update runs in slices of its probes, one
  // submission each, every slice lit by the field as the update found it: the same field as
  // one pass. Smaller values serve tests and measurements.
  std::size_t maxPassRays = 0;
  // Failure drills (probecast-server --gpu-fail-submission): the N-th submission (from 1) is
  // not made and reports VK_ERROR_DEVICE_LOST, as a GPU lost in it would; every call from
  // there on fails. 0: never. Serves the tests of what the server does when its GPU fails.
  int failSubmission = 0;
  // Diagnostics (probecast-bench gpu-trace --pipeline-statistics): each pipeline's compiler
  // statistics (registers, shared memory, ...) in the log, where the driver reports them.
  bool pipelineStatistics = false;
  // Diagnostics (probecast-bench gpu-trace --shadow-slot-times): a timestamp pair per shadow
  // slot's launch (a pass "shadow slot N" each) instead of one over them all, and each slot's
  // shadow-ray count in the log. The pairs serialize the launches; single rounds only.
  bool shadowSlotTimes = false;
  VulkanTracing tracing = VulkanTracing::RayPipelines;
  // SDF backend: voxels along the scene's longest side (rounded up to whole bricks of
  // PC_SDF_BRICK_CELLS); the band each sample holds exactly is 4 voxels.
  int sdfVoxels = 128;
  // The occlusion tiles from layered depth maps (ldm_occlusion.h) instead of the probe rays:
  // after each update the updated probes' tiles are replaced by their LDM occlusion, on the
  // host and on the GPU. The LDMs are rebuilt where the field's bounds or (SDF backend) the
  // distance field were. Off by default (docs/LDM.md says why).
  bool ldmOcclusion = false;
  LdmOptions ldm;
};

// Probe rays per pass of an update (the slices' size): at most `maxPassRays` (what the buffers
// and memory hold), and fewer where that lets every one of `shadowSlots` shadow slots fit the
// shadow memory budget and the storage-buffer range in one round, since each further round
// repeats the shade pass over every ray of the pass: but not fewer than about 4 M rays, which
// a large GPU needs to stay busy.
std::size_t vulkanPassRays(std::size_t maxPassRays, int shadowSlots, std::size_t shadowMemoryBudget,
                           std::size_t maxBufferBytes);

class VulkanTracer final : public Tracer {
 public:
  static Result<std::unique_ptr<VulkanTracer>> create(const Scene& scene,
                                                      const TracerOptions& options,
                                                      const VulkanTracerOptions& vulkan);
  ~VulkanTracer() override;
  std::string name() const override;
  // setState, update and traceOnly return an Error where the GPU fails: a lost device, memory
  // it lacks, an update past the device's limits. The field then holds the last completed
  // update, and every later call fails too (tracer.h).
  Status setState(const SceneState& state) override;
  Result<UpdateStats> update(Field& field, const UpdateRequest& request) override;

  // Runs only update()'s trace pass on the same probe rays (closest hits, stored for shading:
  // no shading, shadow rays, blending or readback) and returns its GPU milliseconds: the raw
  // rate the full update is measured against.
  Result<double> traceOnly(Field& field, const UpdateRequest& request);
  // traceOnly's closest hits, in launch order (gpu_trace.h: pcLaunchProbeRay): for tests that
  // compare the backends' hits ray by ray. The request must fit one pass.
  Result<std::vector<gpu::GpuHit>> traceHits(Field& field, const UpdateRequest& request);

  // SDF backend: the last distance-field build, and the field itself (built first where the
  // instances moved since). Errors on the ray-tracing backend.
  const SdfBuildStats& sdfBuildStats() const;
  // With VulkanTracerOptions::ldmOcclusion: the LDMs' last build (empty before the first update).
  const LdmBuildStats* ldmBuildStats() const;
  Result<SdfFieldCopy> readSdf();

  const vk::Context& context() const;
  std::uint32_t validationErrorCount() const { return context().validationErrorCount(); }

  struct Impl;

 private:
  explicit VulkanTracer(std::unique_ptr<Impl> impl);
  void setStateOnce(const SceneState& state);
  UpdateStats updateOnce(Field& field, const UpdateRequest& request);
  double traceOnlyOnce(Field& field, const UpdateRequest& request);
  std::unique_ptr<Impl> impl_;
};

}  // namespace pc
