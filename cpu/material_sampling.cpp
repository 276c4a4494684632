#include "material_sampling.h"

#include <algorithm>
#include <cmath>

#include "lighting.h"

namespace pc {
namespace {

constexpr float kInvPi = 0.318309886f;

// `local` (normal along +Z) in the world frame about N.
glm::vec3 toWorld(glm::vec3 N, glm::vec3 local) {
  return local.x * gpu::pcFrameTangent(N) + local.y * gpu::pcFrameBitangent(N) + local.z * N;
}

glm::vec3 toLocal(glm::vec3 N, glm::vec3 world) {
  return {glm::dot(world, gpu::pcFrameTangent(N)), glm::dot(world, gpu::pcFrameBitangent(N)),
          glm::dot(world, N)};
}

}  // namespace

float specularLobeChance(const SurfaceBrdf& brdf, glm::vec3 V) {
  if (!brdf.hasSpecularLobe()) return 0.0f;
  const float NdotV = std::max(glm::dot(brdf.normal, V), 0.0f);
  const float specular =
      luminance(gpu::pcFresnelSchlick(gpu::pcSpecularF0(brdf.baseColor, brdf.metallic), NdotV));
  const float diffuse =
      (1.0f - brdf.metallic) * luminance(brdf.baseColor) * (1.0f - gpu::PC_DIELECTRIC_F0);
  const float total = specular + diffuse;
  return total > 0.0f ? specular / total : 0.5f;
}

float materialPdf(const SurfaceBrdf& brdf, glm::vec3 V, glm::vec3 L) {
  const float NdotL = glm::dot(brdf.normal, L);
  if (!(NdotL > 0.0f)) return 0.0f;
  const float chance = specularLobeChance(brdf, V);
  float pdf = (1.0f - chance) * NdotL * kInvPi;
  if (chance > 0.0f) {
    const glm::vec3 H = glm::normalize(V + L);
    pdf += chance * gpu::pcGgxVndfPdf(glm::dot(brdf.normal, V),
                                      std::max(glm::dot(brdf.normal, H), 0.0f),
                                      gpu::pcGgxAlpha(brdf.roughness));
  }
  return pdf;
}

bool sampleMaterial(const SurfaceBrdf& brdf, glm::vec3 V, float uLobe, float u1, float u2,
                    MaterialSample& out) {
  const glm::vec3 N = brdf.normal;
  if (!(glm::dot(N, V) > 0.0f)) return false;
  if (uLobe < specularLobeChance(brdf, V)) {
    const glm::vec3 H =
        toWorld(N, gpu::pcSampleGgxVndf(toLocal(N, V), gpu::pcGgxAlpha(brdf.roughness), u1, u2));
    out.dir = glm::reflect(-V, H);
  } else {
    out.dir = sampleCosineHemisphere(N, u1, u2);
  }
  const float cosine = glm::dot(N, out.dir);
  if (!(cosine > 0.0f)) return false;
  out.pdf = materialPdf(brdf, V, out.dir);
  if (!(out.pdf > 0.0f)) return false;
  out.weight = brdf.eval(V, out.dir) * (cosine / out.pdf);
  return true;
}

}  // namespace pc
