// The scene's emissive surfaces as lights: the emissive triangles, found once per scene
// (EmissiveSurfaces) and placed at each animation state (EmissiveLights), sampled by area x
// radiance. The tracers and CPU renders sample them with shadow rays (cpu/lighting.h), the
// client stands virtual point lights in for them (client/light_pack.h).
#pragma once

#include <cstddef>
#include <cstdint>
#include <glm/glm.hpp>
#include <vector>

#include "scene.h"

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
    glm::vec3 radiance;  // mean emitted radiance (textures averaged)
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

// Auto's rule: emitters are sampled as lights when they cover less than this share of the
// scene's surface area (see emissive_lights.cpp for why).
inline constexpr float kEmissiveLightsMaxAreaShare = 0.1f;

// Whether `mode` makes the emissive surfaces of a scene sampled lights, given their area and
// the scene's total surface area.
bool emissiveAsLights(EmissiveMode mode, double emissiveArea, double totalArea);

}  // namespace pc
