// A surface point's BRDF as the CPU renders evaluate and sample it: the shading normal and
// the metallic-roughness terms at the point, evaluated by the shared formulas
// (shaders/interop/brdf.h) that a GPU renderer uses too.
#pragma once

#include <glm/glm.hpp>

#include "../shaders/interop/brdf.h"

namespace pc {

struct SurfaceBrdf {
  glm::vec3 normal{0.0f, 0.0f, 1.0f};  // unit shading normal, on the viewer's side
  glm::vec3 baseColor{0.0f};
  float metallic = 0.0f;
  float roughness = 1.0f;

  bool hasSpecularLobe() const { return gpu::pcHasSpecularLobe(metallic, roughness); }
  // f(V, L), no cosine; V toward the viewer, L toward the light, both unit.
  glm::vec3 eval(glm::vec3 V, glm::vec3 L) const {
    return gpu::pcMaterialBrdf(normal, V, L, baseColor, metallic, roughness);
  }
};

}  // namespace pc
