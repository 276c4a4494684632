// Importance sampling of the surface BRDF (shaders/interop/brdf.h) for the reference path
// tracer's bounces: one lobe is chosen at random, the diffuse one by the cosine, the specular
// one by GGX's distribution of visible normals, and the sample is weighted by the density of
// drawing its direction through either lobe (one-sample multiple importance sampling), so
// its weight f cos / pdf stays bounded whichever lobe dominates.
#pragma once

#include <glm/glm.hpp>

#include "surface_brdf.h"

namespace pc {

struct MaterialSample {
  glm::vec3 dir{0.0f};     // unit, toward where the path continues
  glm::vec3 weight{0.0f};  // f(V, dir) cos / pdf
  float pdf = 0.0f;        // over solid angle
};

// The chance of drawing from the specular lobe at this point for the view direction V:
// its Schlick reflectance against the diffuse albedo, by luminance.
float specularLobeChance(const SurfaceBrdf& brdf, glm::vec3 V);
// The density (over solid angle) with which sampleMaterial draws L.
float materialPdf(const SurfaceBrdf& brdf, glm::vec3 V, glm::vec3 L);
// Draws a direction from three uniform numbers; false where the draw leaves the surface's
// upper hemisphere or has no density (the path ends there).
bool sampleMaterial(const SurfaceBrdf& brdf, glm::vec3 V, float uLobe, float u1, float u2,
                    MaterialSample& out);

}  // namespace pc
