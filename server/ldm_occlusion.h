// The occlusion field from deterministically directed layered depth maps (LDMs,
// shaders/interop/ldm.h, docs/LDM.md): on any Vulkan device with compute, no ray tracing.
// build() rasterizes the scene's triangles into `directions` orthographic LDMs over a box,
// every depth layer of every pixel kept and sorted; occlusion() gives each probe's occlusion
// tile (the cos-weighted share of directions that travel past d_max, Field::occlusion) from
// those LDMs. The SDF backend takes its occlusion tiles from here (VulkanTracerOptions::
// ldmOcclusion); probecast-bench ldm measures them against Embree's.
#pragma once

#include <glm/glm.hpp>
#include <memory>
#include <span>
#include <vector>

#include "../common/field.h"
#include "../common/result.h"
#include "../common/scene.h"
#include "../common/vulkan/context.h"
#include "../shaders/interop/ldm.h"
#include "tracer.h"

namespace pc {

struct LdmOptions {
  // LDMs; each is traced both ways, so the probes see 2 x directions directions. 32 (64
  // directions) keeps the error near that of 256 random rays at a fraction of the cost
  // (docs/LDM.md); at most PC_LDM_MAX_DIRECTIONS.
  int directions = 32;
  // Pixels a side of each LDM (rounded up to a multiple of 8, at most 2048). A pixel's centre
  // line stands in for every probe that projects into the pixel: the pixel should be small
  // against d_max.
  int resolution = 128;
};

struct LdmBuildStats {
  int directions = 0, resolution = 0, triangles = 0;
  std::uint64_t layers = 0;  // depth layers (nodes) over all pixels of all LDMs
  int maxLayers = 0;         // the most one pixel holds
  int longLists = 0;         // pixels sorted in place (more than PC_LDM_SORT_LOCAL layers)
  int attempts = 0;          // rasterizations (more than 1: the node buffer grew)
  std::size_t bytes = 0;     // device memory of the lists
  float pixel = 0.0f;        // a pixel's side, metres
};

class LdmOcclusion {
 public:
  // On `ctx`, which must outlive it. Fails where the shaders cannot be loaded.
  static Result<std::unique_ptr<LdmOcclusion>> create(const vk::Context& ctx,
                                                      const LdmOptions& options);
  ~LdmOcclusion();
  LdmOcclusion(const LdmOcclusion&) = delete;
  LdmOcclusion& operator=(const LdmOcclusion&) = delete;

  // Builds the LDMs of world-space `triangles` over the box [lo, hi]: every point whose
  // occlusion will be asked for, grown by d_max (ldmFieldBounds). Triangles outside the box
  // change nothing there and may be left out (ldmSceneTriangles does).
  Status build(std::span<const gpu::LdmTriangle> triangles, glm::vec3 lo, glm::vec3 hi);
  // Occlusion tiles of points `positions` within `dmax` metres: PC_OCCLUSION_TEXELS^2 values
  // per point, row-major, interior texels only. Points outside the built box see no surface.
  Result<std::vector<float>> occlusion(std::span<const glm::vec3> positions, float dmax);
  // The sorted depths of every pixel of LDM `direction` (row-major pixels), for tests.
  Result<std::vector<std::vector<float>>> layers(int direction);

  const LdmBuildStats& stats() const { return stats_; }
  // The LDMs' direction `i` (each traced both ways).
  glm::vec3 direction(int i) const;

  struct Impl;

 private:
  explicit LdmOcclusion(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
  LdmBuildStats stats_;
};

// The world-space triangles of `scene` in `state` (the instances' transforms; where it is
// empty, each instance's own), those whose bounds meet [lo, hi] only. Alpha cut-outs are
// solid here: an LDM layer has no texture coordinates.
std::vector<gpu::LdmTriangle> ldmSceneTriangles(const Scene& scene, const SceneState& state,
                                                glm::vec3 lo, glm::vec3 hi);
// The box the LDMs of `field` must cover: every cascade's probes, each as far as relocation
// may move it, grown by d_max.
void ldmFieldBounds(const Field& field, glm::vec3& lo, glm::vec3& hi);
// The positions of `probes` in `field`, relocated.
std::vector<glm::vec3> ldmProbePositions(const Field& field, std::span<const ProbeRef> probes);
// Writes `tiles` (occlusion()'s output for `probes`) into the field's occlusion tiles, interior
// and border, replacing what was there: LDM occlusion is exact for its directions, with no
// noise for hysteresis to filter. Probes inside geometry are left as the tracer left them.
void writeLdmOcclusion(Field& field, std::span<const ProbeRef> probes,
                       std::span<const float> tiles);

}  // namespace pc
