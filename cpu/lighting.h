// Direct light at a surface point, shared by the field update, the reference path tracer and
// the probe-lit render: punctual lights and (per the scene's EmissiveMode) emissive
// triangles, each with shadow rays; plus the sky's radiance for rays that escape.
#pragma once

#include <cstdint>
#include <glm/glm.hpp>
#include <vector>

#include "../common/scene.h"
#include "../shaders/interop/probe_math.h"
#include "embree_scene.h"
#include "random.h"

namespace pc {

// What EmissiveLights needs of a scene that no animation changes, found in one pass over
// every triangle: the triangles whose material glows, with their radiance, and the areas that
// decide whether emitters are sampled as lights. Animations move instances rigidly (rotations
// and paths), which changes no area. Made once per scene: a renderer or tracer that rebuilt
// the lights from every triangle each frame or update spent tens of milliseconds on a
// two-million-triangle scene.
class EmissiveSurfaces {
 public:
  explicit EmissiveSurfaces(const Scene& scene);

 private:
  friend class EmissiveLights;
  struct Source {
    std::size_t instance;
    std::uint32_t i0, i1, i2;
    glm::vec3 radiance;  // mean emitted radiance (textures averaged)
  };
  std::vector<Source> sources_;  // by instance, then triangle
  double emissiveArea_ = 0.0, totalArea_ = 0.0;
};

// Emissive triangles in world space, sampled by area x radiance.
class EmissiveLights {
 public:
  // Picks the emissive triangles that are sampled as lights (EmissiveMode; Auto chooses
  // lights when the emissive area is a small part of the scene's surface), placed at `state`.
  static EmissiveLights build(const Scene& scene, const SceneState& state,
                              const EmissiveSurfaces& surfaces);
  // The same, finding the surfaces first (for a single image or update).
  static EmissiveLights build(const Scene& scene, const SceneState& state);
  bool empty() const { return triangles_.empty(); }
  // True when a hit on this material's emission is already counted by light sampling, so a
  // path must not add it again after a bounce (and the field must not store it).
  bool sampled(int material) const;
  std::size_t count() const { return triangles_.size(); }

  struct Triangle {
    glm::vec3 p0, e1, e2;  // p0 + u e1 + v e2
    glm::vec3 normal;      // unit, front side
    float area;
    glm::vec3 radiance;    // mean emitted radiance (textures averaged)
  };
  const std::vector<Triangle>& triangles() const { return triangles_; }
  const std::vector<float>& cdf() const { return cdf_; }
  float totalPower() const { return totalPower_; }

 private:
  std::vector<Triangle> triangles_;
  std::vector<float> cdf_;  // by power, normalized
  std::vector<bool> sampledMaterials_;
  float totalPower_ = 0.0f;
};

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

// Irradiance E (W/m^2) arriving at P (normal N, unit) directly from lights, shadowed.
// Multiply by albedo / pi for the reflected radiance of a diffuse surface. The lights are
// evaluated at P; the shadow rays leave from `shadowOrigin`, P moved off its surface
// (gpu::pcShadowOrigin, offsetRayOrigin), toward each light or emitter sample. Emitter samples
// draw from `rng`: an Rng, or a probe ray's RayRng (cpu/random.h).
template <class R>
glm::vec3 directIrradiance(const EmbreeScene& scene, const SceneState& state,
                           const EmissiveLights& emissive, glm::vec3 P, glm::vec3 shadowOrigin,
                           glm::vec3 N, R& rng, const DirectLightOptions& options = {});
extern template glm::vec3 directIrradiance<Rng>(const EmbreeScene&, const SceneState&,
                                                const EmissiveLights&, glm::vec3, glm::vec3,
                                                glm::vec3, Rng&, const DirectLightOptions&);
extern template glm::vec3 directIrradiance<RayRng>(const EmbreeScene&, const SceneState&,
                                                   const EmissiveLights&, glm::vec3, glm::vec3,
                                                   glm::vec3, RayRng&, const DirectLightOptions&);
// The same with the shadow rays leaving from P itself (P already off its surface).
template <class R>
glm::vec3 directIrradiance(const EmbreeScene& scene, const SceneState& state,
                           const EmissiveLights& emissive, glm::vec3 P, glm::vec3 N, R& rng,
                           const DirectLightOptions& options = {}) {
  return directIrradiance(scene, state, emissive, P, P, N, rng, options);
}

// Offset along the geometric normal that keeps secondary rays from re-hitting their origin.
glm::vec3 offsetRayOrigin(glm::vec3 P, glm::vec3 geometricNormal);

// Rec. 709 luminance of linear RGB.
inline float luminance(glm::vec3 c) { return gpu::pcLuminance(c); }

// Auto's rule: emitters are sampled as lights when they cover less than this share of the
// scene's surface area (see lighting.cpp for why).
inline constexpr float kEmissiveLightsMaxAreaShare = 0.1f;

// Whether `mode` makes the emissive surfaces of a scene sampled lights, given their area and
// the scene's total surface area.
bool emissiveAsLights(EmissiveMode mode, double emissiveArea, double totalArea);

// Cosine-weighted direction about the unit normal N (pdf = cos / pi).
glm::vec3 sampleCosineHemisphere(glm::vec3 N, float u1, float u2);

}  // namespace pc
