// Direct light at a surface point with Embree shadow rays, shared by the field update, the
// reference path tracer and the probe-lit render: punctual lights and (per the scene's
// EmissiveMode) emissive triangles, evaluated by the shared light model
// (shaders/interop/light_model.h) that the GPU tracer and the client evaluate too.
#pragma once

#include <cstdint>
#include <glm/glm.hpp>
#include <span>
#include <vector>

#include "../common/emissive_lights.h"
#include "../common/light_pack.h"
#include "../common/scene.h"
#include "../shaders/interop/light_model.h"
#include "../shaders/interop/probe_math.h"
#include "embree_scene.h"
#include "random.h"
#include "surface_brdf.h"

namespace pc {

struct DirectLightOptions {
  int emissiveSamples = 1;  // shadow rays toward emissive triangles per call
  // When set, incremented by the number of shadow rays traced (ray budgets and Mrays/s).
  std::uint64_t* shadowRayCount = nullptr;
  // Russian roulette on the punctual lights' shadow rays (shaders/interop/shadow_roulette.h):
  // the share of a hit's unshadowed punctual light below which a light's shadow ray is drawn
  // at random (0: never), with the ray's key (pcShadowRouletteKey). Probe updates only:
  // renders keep every shadow ray.
  float shadowRouletteShare = 0.0f;
  std::uint32_t shadowRouletteKey = 0;
};

// One light sample at a surface point and the shadow ray that decides it: unoccluded, the
// sample adds `irradiance` to the point's punctual sum (emitter false) or to its emitter sum
// (emitter true), which directIrradiance divides by the sample count.
struct ShadowSample {
  glm::vec3 origin{0.0f}, dir{0.0f};
  float far = 0.0f;
  glm::vec3 irradiance{0.0f};
  bool emitter = false;
};

// The light samples of directIrradiance at P, each with its shadow ray, in the order
// directIrradiance sums them, without tracing them: callers that trace many points' shadow
// rays together. Appends to `out`; returns how many it appended. Draws from `rng` as
// directIrradiance does.
template <class R>
std::size_t directLightSamples(std::span<const gpu::GpuLight> lights,
                               const EmissiveLights& emissive, glm::vec3 P, glm::vec3 shadowOrigin,
                               glm::vec3 N, R& rng, const DirectLightOptions& options,
                               std::vector<ShadowSample>& out);
extern template std::size_t directLightSamples<RayRng>(std::span<const gpu::GpuLight>,
                                                       const EmissiveLights&, glm::vec3, glm::vec3,
                                                       glm::vec3, RayRng&,
                                                       const DirectLightOptions&,
                                                       std::vector<ShadowSample>&);

// Irradiance E (W/m^2) arriving at P (normal N, unit) directly from `lights` (packLights of
// the state) and the emitters, shadowed.
// Multiply by albedo / pi for the reflected radiance of a diffuse surface. The lights are
// evaluated at P; the shadow rays leave from `shadowOrigin`, P moved off its surface
// (gpu::pcShadowOrigin), toward each light or emitter sample. Emitter samples
// draw from `rng`: an Rng, or a probe ray's RayRng (cpu/random.h).
template <class R>
glm::vec3 directIrradiance(const EmbreeScene& scene, std::span<const gpu::GpuLight> lights,
                           const EmissiveLights& emissive, glm::vec3 P, glm::vec3 shadowOrigin,
                           glm::vec3 N, R& rng, const DirectLightOptions& options = {});
extern template glm::vec3 directIrradiance<Rng>(const EmbreeScene&, std::span<const gpu::GpuLight>,
                                                const EmissiveLights&, glm::vec3, glm::vec3,
                                                glm::vec3, Rng&, const DirectLightOptions&);
extern template glm::vec3 directIrradiance<RayRng>(const EmbreeScene&,
                                                   std::span<const gpu::GpuLight>,
                                                   const EmissiveLights&, glm::vec3, glm::vec3,
                                                   glm::vec3, RayRng&, const DirectLightOptions&);
// The same with the shadow rays leaving from P itself (P already off its surface).
template <class R>
glm::vec3 directIrradiance(const EmbreeScene& scene, std::span<const gpu::GpuLight> lights,
                           const EmissiveLights& emissive, glm::vec3 P, glm::vec3 N, R& rng,
                           const DirectLightOptions& options = {}) {
  return directIrradiance(scene, lights, emissive, P, P, N, rng, options);
}

// Radiance reflected toward V (unit, toward the viewer) at P by a surface with `brdf`, from
// the same light samples and shadow rays as directIrradiance: each unshadowed sample's
// irradiance times the BRDF for its direction. For a Lambert surface it equals
// albedo / pi x directIrradiance.
template <class R>
glm::vec3 directReflected(const EmbreeScene& scene, std::span<const gpu::GpuLight> lights,
                          const EmissiveLights& emissive, glm::vec3 P, glm::vec3 shadowOrigin,
                          const SurfaceBrdf& brdf, glm::vec3 V, R& rng,
                          const DirectLightOptions& options = {});
extern template glm::vec3 directReflected<Rng>(const EmbreeScene&, std::span<const gpu::GpuLight>,
                                               const EmissiveLights&, glm::vec3, glm::vec3,
                                               const SurfaceBrdf&, glm::vec3, Rng&,
                                               const DirectLightOptions&);

// Rec. 709 luminance of linear RGB.
inline float luminance(glm::vec3 c) { return gpu::pcLuminance(c); }

// Cosine-weighted direction about the unit normal N (pdf = cos / pi).
glm::vec3 sampleCosineHemisphere(glm::vec3 N, float u1, float u2);

}  // namespace pc
