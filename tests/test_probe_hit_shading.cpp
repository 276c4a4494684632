// What a probe-ray hit sends back toward the probe (shaders/interop/probe_hit_shading.h),
// against brute-force integration of brdf.h's BRDF: in a white furnace (uniform incident
// radiance L, so irradiance pi L about every normal) the hit must send back exactly the
// BRDF's directional albedo times L, which never exceeds L for a white surface; and a surface
// without a specular lobe must reflect albedo / pi x irradiance, to the bit, as before.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

#include "common/split_sum_table.h"
#include "shaders/interop/probe_hit_shading.h"
#include "test_directions.h"

namespace pc {
namespace {

constexpr double kPi = std::numbers::pi;

using testdir::fromAngles;

struct TestMaterial {
  const char* name;
  glm::vec3 baseColor;
  float metallic;
};

// Radiance reflected toward V under uniform incident radiance 1: the integral of
// pcMaterialBrdf cos over the hemisphere, midpoint quadrature in (cos theta, phi) (uniform in
// cos theta puts the samples where the sharp lobes near the normal need them); 512 x 512
// and 1024 x 1024 agree to 1e-4 for roughness 0.3 and up.
glm::dvec3 furnaceByQuadrature(glm::vec3 V, const TestMaterial& m, float roughness) {
  constexpr int kCos = 512, kPhi = 512;
  const glm::vec3 N(0.0f, 1.0f, 0.0f);
  glm::dvec3 sum(0.0);
  for (int i = 0; i < kCos; ++i) {
    const double mu = (i + 0.5) / kCos;
    const double theta = std::acos(mu);
    for (int j = 0; j < kPhi; ++j) {
      const glm::vec3 L = fromAngles(theta, (j + 0.5) * 2.0 * kPi / kPhi);
      sum += glm::dvec3(gpu::pcMaterialBrdf(N, V, L, m.baseColor, m.metallic, roughness)) * mu;
    }
  }
  return sum * (2.0 * kPi / (double(kCos) * kPhi));
}

const TestMaterial kMaterials[] = {
    {"white dielectric", glm::vec3(1.0f), 0.0f},
    {"white metal", glm::vec3(1.0f), 1.0f},
    {"gold metal", glm::vec3(1.0f, 0.78f, 0.34f), 1.0f},
    {"black dielectric", glm::vec3(0.0f), 0.0f},
    {"half metal", glm::vec3(0.5f, 0.7f, 0.9f), 0.5f},
};

TEST(ProbeHitShading, WhiteFurnaceSendsBackTheBrdfsDirectionalAlbedo) {
  const SplitSumTable& table = splitSumTable();
  const glm::vec3 N(0.0f, 1.0f, 0.0f);
  const float L = 2.0f;               // the furnace's radiance
  const glm::vec3 E(float(kPi) * L);  // irradiance about any normal
  double worst = 0.0;
  int cases = 0;
  for (const TestMaterial& m : kMaterials)
    for (float roughness : {0.3f, 0.5f, 0.75f, 1.0f})
      for (float NdotV : {0.15f, 0.4f, 0.7f, 1.0f}) {
        const glm::vec3 V = fromAngles(std::acos(double(NdotV)), 0.7);
        // In the furnace the irradiance about the lobe's normal is pi L as well.
        const glm::vec2 ab = lookupSplitSum(table, NdotV, roughness);
        const glm::vec3 sent =
            gpu::pcProbeHitIndirect(N, V, m.baseColor, m.metallic, roughness, E, E, ab);
        const glm::dvec3 exact = furnaceByQuadrature(V, m, roughness) * double(L);
        for (int c = 0; c < 3; ++c) {
          const double error = std::abs(double(sent[c]) - exact[c]) / double(L);
          worst = std::max(worst, error);
          // Measured 3.2e-3 at most: the split-sum table's bilinear steps between its nodes.
          EXPECT_LT(error, 5e-3) << m.name << " roughness " << roughness << " N.V " << NdotV
                                 << " channel " << c << ": sent " << sent[c] << ", BRDF integral "
                                 << exact[c];
          // Energy: a surface never sends back more than the furnace's radiance.
          EXPECT_LE(sent[c], L * 1.001f)
              << m.name << " roughness " << roughness << " N.V " << NdotV;
          EXPECT_LE(exact[c], double(L) * 1.001) << m.name << " (the BRDF itself)";
        }
        ++cases;
      }
  std::printf("%d furnace cases: largest |sent - BRDF integral| / L = %.2e\n", cases, worst);
}

// The light samples go through the BRDF for their direction, and the diffuse and specular
// parts of the indirect light are the BRDF's: a metal reflects no diffuse light, a rough
// dielectric reflects less toward grazing views as its coat takes more.
TEST(ProbeHitShading, GlossyHitsWeighLightsByTheBrdf) {
  const glm::vec3 N(0.0f, 1.0f, 0.0f);
  const glm::vec3 V = glm::normalize(glm::vec3(0.6f, 0.8f, 0.0f));
  const glm::vec3 mirror = glm::normalize(glm::vec3(-0.6f, 0.8f, 0.0f));
  const glm::vec3 aside = glm::normalize(glm::vec3(0.0f, 0.8f, 0.6f));
  const glm::vec3 base(0.9f, 0.6f, 0.3f);
  for (float roughness : {0.2f, 0.5f}) {
    EXPECT_EQ(gpu::pcProbeHitLightWeight(N, V, mirror, base, 1.0f, roughness),
              gpu::pcMaterialBrdf(N, V, mirror, base, 1.0f, roughness));
    // A light in the mirror direction reflects more than one off to the side.
    EXPECT_GT(gpu::pcProbeHitLightWeight(N, V, mirror, base, 1.0f, roughness).x,
              2.0f * gpu::pcProbeHitLightWeight(N, V, aside, base, 1.0f, roughness).x);
  }
  // A metal's indirect light is its lobe alone: black where the lobe's irradiance is.
  const glm::vec2 ab = lookupSplitSum(splitSumTable(), 0.8f, 0.5f);
  EXPECT_EQ(gpu::pcProbeHitIndirect(N, V, base, 1.0f, 0.5f, glm::vec3(10.0f), glm::vec3(0.0f), ab),
            glm::vec3(0.0f));
  EXPECT_GT(
      gpu::pcProbeHitIndirect(N, V, base, 1.0f, 0.5f, glm::vec3(0.0f), glm::vec3(10.0f), ab).x,
      0.0f);
}

// No specular lobe (metallic 0, roughness 1): albedo / pi times the irradiance, in the very
// expressions the tracers used before, so diffuse scenes keep their fields to the bit.
TEST(ProbeHitShading, LambertSurfacesReflectAlbedoOverPiExactly) {
  const glm::vec3 N = glm::normalize(glm::vec3(0.2f, 0.9f, -0.1f));
  const glm::vec3 V = glm::normalize(glm::vec3(0.7f, 0.3f, 0.2f));
  const glm::vec3 L = glm::normalize(glm::vec3(-0.3f, 0.8f, 0.4f));
  for (glm::vec3 albedo : {glm::vec3(0.8f), glm::vec3(0.31f, 0.57f, 0.93f), glm::vec3(0.0f)}) {
    const glm::vec3 E(3.7f, 0.21f, 12.5f);
    const glm::vec3 reflectance = albedo * (1.0f / gpu::PC_PI);
    EXPECT_EQ(gpu::pcProbeHitLightWeight(N, V, L, albedo, 0.0f, 1.0f), reflectance);
    EXPECT_EQ(
        gpu::pcProbeHitIndirect(N, V, albedo, 0.0f, 1.0f, E, glm::vec3(99.0f), glm::vec2(0.5f)),
        reflectance * E);
  }
}

}  // namespace
}  // namespace pc
