// A camera view lit by a probe field, rendered on the CPU: the image a client would show,
// computed with the reference's ray tracer instead of a rasterizer, so it isolates the
// field's own error. Per pixel: jittered primary rays; at the hit, emission + direct light with
// shadow rays through the surface's BRDF (shaders/interop/brdf.h) + the field's irradiance
// through its diffuse part and, on glossy surfaces, the field's split-sum specular
// (shaders/interop/specular_probe.h), both darkened by screen-space ambient occlusion where the
// probes are too coarse to see a contact (cpu/screen_ao.h); escaped rays see the sky.
#pragma once

#include <cstdint>
#include <optional>

#include "../common/field.h"
#include "../common/image.h"
#include "../common/log.h"
#include "../common/result.h"
#include "../common/scene.h"
#include "../shaders/interop/screen_ao.h"
#include "embree_scene.h"
#include "lighting.h"

namespace pc {

struct ProbeLitOptions {
  int width = 640, height = 360;
  int primarySamples = 8;                // jittered camera rays per pixel (anti-aliasing)
  int emissiveSamples = 32;              // stratified shadow rays toward emitters per primary hit
  int camera = 0;                        // index into Scene::cameras
  std::optional<Camera> explicitCamera;  // used instead of `camera` when set
  double time = 0.0;                     // animation time of the frame
  int sampleFlags = 0;  // passed to sampleField (PC_SAMPLE_NO_VISIBILITY: the naive baseline)
  // Radius of the ambient occlusion of the indirect light, as a fraction of the probe spacing
  // (shaders/interop/screen_ao.h); 0: none.
  float aoRadius = gpu::PC_AO_DEFAULT_RADIUS;
  // Glossy surfaces (metallic-roughness with a specular lobe): the field's split-sum specular
  // (shaders/interop/specular_probe.h) besides its irradiance; false leaves the indirect light
  // diffuse alone (the comparison without it). Direct light follows the BRDF either way.
  bool indirectSpecular = true;
  std::uint64_t seed = 1;
};

// Renders with an already built scene; `state` must be the one `scene` was updated to.
Image renderProbeLit(const EmbreeScene& scene, const SceneState& state,
                     const EmissiveLights& emissive, const Field& field, const Camera& camera,
                     const ProbeLitOptions& options, Progress* progress = nullptr);

// Builds the Embree scene and lights at options.time and renders the chosen camera.
Result<Image> renderProbeLit(const Scene& scene, const Field& field, const ProbeLitOptions& options,
                             Progress* progress = nullptr);

// Rows the render is split into (for sizing a Progress).
inline int probeLitProgressTotal(const ProbeLitOptions& options) { return options.height; }

}  // namespace pc
