// Reference path tracer: the ground truth that every other renderer's image is measured
// against. Diffuse and glossy surfaces (glTF's metallic-roughness model, Lambert + GGX:
// shaders/interop/brdf.h; bounces importance-sample it, cpu/material_sampling.h), emission,
// the scene's punctual lights and sky; next-event estimation with the same direct-light code
// as the field update, weighted by the BRDF; Russian roulette.
// Deterministic: each pixel draws from its own seeded generator, so the image depends on the
// seed only, never on the thread count.
#pragma once

#include <cstdint>
#include <optional>

#include "../common/image.h"
#include "../common/log.h"
#include "../common/result.h"
#include "../common/scene.h"
#include "embree_scene.h"
#include "lighting.h"

namespace pc {

struct PathTraceOptions {
  int width = 640, height = 360;
  int spp = 256;                         // camera paths per pixel
  int camera = 0;                        // index into Scene::cameras
  std::optional<Camera> explicitCamera;  // used instead of `camera` when set
  double time = 0.0;                     // animation time of the frame
  std::uint64_t seed = 1;
  // Indirect bounces at most (0: direct light only); a safety cap, as Russian roulette ends
  // paths long before it.
  int maxBounces = 32;
  int emissiveSamples = 1;  // shadow rays toward emissive triangles per hit
};

struct PathTraceResult {
  Image image;  // linear radiance, all samples
  // The image's own noise, from two independent renders of half the samples each (their
  // average is `image`): PSNR between the halves, tone-mapped 8-bit, and the PSNR the full
  // image is expected to have against a noise-free one (halves + 6.02 dB). Zero when spp < 2.
  double halvesPsnr = 0.0;
  double noisePsnr = 0.0;
  double seconds = 0.0;
  int spp = 0;
  std::uint64_t samples = 0;  // camera paths traced in all
};

// Renders with an already built scene; `state` must be the one `scene` was updated to.
PathTraceResult pathTrace(const EmbreeScene& scene, const SceneState& state,
                          const EmissiveLights& emissive, const Camera& camera,
                          const PathTraceOptions& options, Progress* progress = nullptr);

// Builds the Embree scene and lights at options.time and renders the chosen camera.
Result<PathTraceResult> renderReference(const Scene& scene, const PathTraceOptions& options,
                                        Progress* progress = nullptr);

// Tiles the renders are split into (for sizing a Progress).
int pathTraceTileCount(int width, int height);

}  // namespace pc
