// Direct light at a surface point with Embree shadow rays, shared by the field update, the
// reference path tracer and the probe-lit render: punctual lights and (per the scene's
// EmissiveMode) emissive triangles, evaluated by the shared light model
// (shaders/interop/light_model.h) that the GPU tracer and the client evaluate too.
#pragma once

#include <cstdint>
#include <glm/glm.hpp>
#include <span>

#include "../common/emissive_lights.h"
#include "../common/light_pack.h"
#include "../common/scene.h"
#include "../shaders/interop/light_model.h"
#include "../shaders/interop/probe_math.h"
#include "embree_scene.h"
#include "random.h"

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

// Rec. 709 luminance of linear RGB.
inline float luminance(glm::vec3 c) { return gpu::pcLuminance(c); }

// Cosine-weighted direction about the unit normal N (pdf = cos / pi).
glm::vec3 sampleCosineHemisphere(glm::vec3 N, float u1, float u2);

}  // namespace pc
