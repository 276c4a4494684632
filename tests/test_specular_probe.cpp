// The field's split-sum specular (shaders/interop/specular_probe.h): the fitted zonal-harmonic
// coefficients of the GGX prefilter lobe against its Legendre moments by quadrature, the
// split-sum table against a brute-force hemisphere integral of brdf.h's GGX term, the band
// split from six irradiance values against the exact convolution of L2 radiance (directly,
// and through an SH probe's derived tile), and the glossy Cornell box, where the probe-lit
// render with the specular is closer to the path-traced reference than without it.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>

#include "common/field.h"
#include "common/field_shared_sampling.h"
#include "common/image.h"
#include "common/scene.h"
#include "common/scene_glossy.h"
#include "common/split_sum_table.h"
#include "cpu/path_tracer.h"
#include "cpu/probe_lit_render.h"
#include "server/bake.h"
#include "server/embree_tracer.h"
#include "shaders/interop/specular_probe.h"
#include "test_timing.h"

namespace pc {
namespace {

using namespace pc::gpu;
namespace fs = std::filesystem;

constexpr double kPi = 3.14159265358979323846;

// Normalised Legendre moments k_1, k_2 of the prefilter lobe D(H) max(0, cos) about R = N = V
// at perceptual roughness r: integrals over the angle t from R, H halfway between R and L.
glm::dvec2 lobeMoments(double roughness) {
  const double alpha = std::max(roughness * roughness, double(PC_GGX_MIN_ALPHA));
  const double a2 = alpha * alpha;
  const int steps = 200000;
  double m0 = 0, m1 = 0, m2 = 0;
  for (int i = 0; i < steps; ++i) {
    const double t = (i + 0.5) / steps * kPi / 2;
    const double c = std::cos(t), ch = std::cos(t / 2);
    const double d = ch * ch * (a2 - 1) + 1;
    const double w = a2 / (kPi * d * d) * c * std::sin(t);
    m0 += w;
    m1 += w * c;
    m2 += w * 0.5 * (3 * c * c - 1);
  }
  return {m1 / m0, m2 / m0};
}

TEST(SpecularProbe, ZonalFitMatchesTheLobeMoments) {
  double worst = 0;
  for (int i = 0; i <= 20; ++i) {
    const float r = float(i) / 20.0f;
    const glm::vec2 fit = pcGgxSpecularZh(r);
    const glm::dvec2 exact = lobeMoments(r);
    worst = std::max({worst, std::fabs(fit.x - exact.x), std::fabs(fit.y - exact.y)});
    EXPECT_NEAR(fit.x, exact.x, 2e-3) << "k_1 at roughness " << r;
    EXPECT_NEAR(fit.y, exact.y, 2e-3) << "k_2 at roughness " << r;
  }
  std::printf("fit vs quadrature: worst %.2e\n", worst);
  // The ends: a mirror's impulse, and the clamped cosine (A_l / A_0 = 2/3, 1/4).
  EXPECT_NEAR(pcGgxSpecularZh(0.0f).x, 1.0f, 1e-3f);
  EXPECT_NEAR(pcGgxSpecularZh(0.0f).y, 1.0f, 1e-3f);
  EXPECT_NEAR(pcGgxSpecularZh(1.0f).x, 2.0f / 3.0f, 1e-3f);
  EXPECT_NEAR(pcGgxSpecularZh(1.0f).y, 0.25f, 1e-3f);
}

// A and B by brute force: theta-phi midpoints over the hemisphere of L, with pcGgxSpecular
// itself (F0 = 1 gives A + B, F0 = 0 gives B).
glm::dvec2 bruteForceSplitSum(float NdotV, float roughness) {
  const glm::vec3 N(0, 0, 1), V(std::sqrt(1 - NdotV * NdotV), 0, NdotV);
  const float alpha = pcGgxAlpha(roughness);
  const int nt = 512, np = 256;
  double one = 0, zero = 0;
  for (int i = 0; i < nt; ++i) {
    const double t = (i + 0.5) / nt * kPi / 2;
    for (int j = 0; j < np; ++j) {
      const double p = (j + 0.5) / np * kPi;  // symmetric in phi: half the circle, twice
      const glm::vec3 L(float(std::sin(t) * std::cos(p)), float(std::sin(t) * std::sin(p)),
                        float(std::cos(t)));
      const double dw = 2 * std::sin(t) * (kPi / 2 / nt) * (kPi / np);
      one += pcGgxSpecular(N, V, L, glm::vec3(1.0f), alpha).x * L.z * dw;
      zero += pcGgxSpecular(N, V, L, glm::vec3(0.0f), alpha).x * L.z * dw;
    }
  }
  return {one - zero, zero};
}

TEST(SpecularProbe, SplitSumTableMatchesQuadrature) {
  const SplitSumTable& table = splitSumTable();
  for (int j : {5, 9, 15}) {  // roughness 0.33, 0.6, 1: lobes a grid can resolve
    for (int i : {2, 8, 15}) {
      const float NdotV = pcSplitSumNdotV(i), r = pcSplitSumRoughness(j);
      const glm::vec2 entry = table[std::size_t(i + PC_SPLIT_SUM_SIZE * j)];
      const glm::dvec2 exact = bruteForceSplitSum(NdotV, r);
      EXPECT_NEAR(entry.x, exact.x, 0.01) << "A at N.V " << NdotV << ", roughness " << r;
      EXPECT_NEAR(entry.y, exact.y, 0.005) << "B at N.V " << NdotV << ", roughness " << r;
      EXPECT_EQ(lookupSplitSum(table, NdotV, r), entry);  // nodes read back exactly
    }
  }
  // Energy: A + B is the lobe's albedo for F0 = 1, never above 1 (masking loses some).
  for (const glm::vec2& e : table) {
    EXPECT_GE(e.x, 0.0f);
    EXPECT_GE(e.y, 0.0f);
    EXPECT_LE(e.x + e.y, 1.0f + 1e-3f);
  }
  // Smooth and rough at normal incidence: nearly all of it, and visibly less.
  EXPECT_GT(table[std::size_t(PC_SPLIT_SUM_SIZE - 1)].x, 0.95f);
  const glm::vec2 rough = table[std::size_t(PC_SPLIT_SUM_ENTRIES - 1)];
  EXPECT_LT(rough.x + rough.y, 0.9f);
}

// Random L2 radiance (per channel) for the band tests.
ShCoefficients randomRadiance(std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-0.3f, 0.3f);
  ShCoefficients c{};
  for (glm::vec3& v : c) v = glm::vec3(u(rng), u(rng), u(rng));
  c[0] += glm::vec3(2.0f);  // positive overall, so no clamping at zero interferes
  return c;
}

// The GGX-filtered radiance toward R: sum_l k_l L_lm Y_lm(R).
glm::vec3 exactSpecular(const ShCoefficients& c, glm::vec3 R, glm::vec2 zh) {
  glm::vec3 s(0.0f);
  for (int i = 0; i < 9; ++i) s += (i == 0 ? 1.0f : i < 4 ? zh.x : zh.y) * pcShBasis(i, R) * c[i];
  return s;
}

TEST(SpecularProbe, SixIrradianceValuesGiveTheExactL2Convolution) {
  const ShCoefficients c = randomRadiance(7);
  std::mt19937 rng(3);
  std::normal_distribution<float> n;
  for (int k = 0; k < 20; ++k) {
    const glm::vec3 R = glm::normalize(glm::vec3(n(rng), n(rng), n(rng)));
    const glm::vec2 zh = pcGgxSpecularZh(float(k) / 19.0f);
    const glm::vec3 T = pcFrameTangent(R), B = pcFrameBitangent(R);
    const glm::vec3 sides = shIrradiance(c, 9, T) + shIrradiance(c, 9, -T) + shIrradiance(c, 9, B) +
                            shIrradiance(c, 9, -B);
    const glm::vec3 s =
        pcSpecularFromIrradiance(shIrradiance(c, 9, R), shIrradiance(c, 9, -R), sides, zh);
    const glm::vec3 exact = exactSpecular(c, R, zh);
    for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(s[ch], exact[ch], 1e-5f) << "direction " << k;
  }
  // A constant sky of radiance 1: irradiance pi everywhere, specular 1 at every roughness.
  const glm::vec3 pi(PC_PI);
  EXPECT_NEAR(pcSpecularFromIrradiance(pi, pi, 4.0f * pi, pcGgxSpecularZh(0.4f)).x, 1.0f, 1e-6f);
}

// Through a field: pcProbeSpecular on an SH L2 probe (the CPU fetch answers from its
// coefficients: exact) and on the same probe's derived irradiance tile read as an octahedral
// one (gamma-encoded, bilinear: what the client samples), against the exact convolution of
// its coefficients. The tile's interpolation error is small in irradiance, but undoing the
// cosine multiplies band 2 by 4 / pi against band 0's 1 / pi: within 12% of the probe's mean
// radiance on this strongly directional probe (measured 9.9%, at roughness 0.2).
TEST(SpecularProbe, ProbeGivesTheConvolutionOfItsCoefficients) {
  ProbeVolume v;
  v.counts = glm::ivec3(2);
  v.settings.encoding = ProbeEncoding::Sh2;
  Field field = Field::create({v}, FieldSettings{});
  const ShCoefficients c = randomRadiance(11);
  field.shProbe(0, 0) = c;
  deriveShTile(field, 0, 0);
  for (bool tile : {false, true}) {
    if (tile) field.desc.cascades[0].encoding = PC_ENCODING_OCTAHEDRAL;
    std::mt19937 rng(5);
    std::normal_distribution<float> n;
    double worst = 0;
    for (int k = 0; k < 32; ++k) {
      const glm::vec3 R = glm::normalize(glm::vec3(n(rng), n(rng), n(rng)));
      for (float r : {0.2f, 0.6f, 1.0f}) {
        const glm::vec2 zh = pcGgxSpecularZh(r);
        const glm::vec3 s = pcProbeSpecular(field, 0, 0, R, zh);
        const glm::vec3 exact = exactSpecular(c, R, zh);
        for (int ch = 0; ch < 3; ++ch) {
          // Relative to the probe's mean radiance (band 0), the scale an image sees.
          const double rel = std::fabs(s[ch] - exact[ch]) / (c[0][ch] * PC_SH_K0);
          worst = std::max(worst, rel);
          EXPECT_LT(rel, tile ? 0.12 : 1e-5) << "direction " << k << ", roughness " << r;
        }
      }
    }
    std::printf("%s vs exact: worst relative error %.5f\n", tile ? "tile" : "coefficients", worst);
  }
}

// The path-traced reference at 128 paths per pixel, tone mapped.
Result<Image8> referenceImage(const Scene& scene, int width, int height) {
  PathTraceOptions options;
  options.width = width;
  options.height = height;
  options.spp = 128;
  auto reference = renderReference(scene, options);
  if (!reference) return reference.error();
  return tonemap(reference->image, scene.exposure);
}

// McGuire's Cornell box with a glossy floor and metal boxes (roughness 0.3): the probe-lit
// render is closer to the path-traced reference with the field's specular than without it,
// where the metal boxes get no indirect light at all. Tiny size: the comparison, not the
// absolute figure.
TEST(SpecularProbe, GlossyCornellBoxGainsPsnr) {
  test::ScopedTestTimer timer;
  const fs::path path = fs::path(PC_SCENES_DIR) / "mcguire-cornellbox/CornellBox-Original.obj";
  if (!fs::exists(path)) GTEST_SKIP() << path.string() << " is absent";
  const fs::path sidecar = fs::temp_directory_path() / "probecast-test-glossy-cornell.json";
  ASSERT_TRUE(writeGlossyCornellSidecar(
      fs::path(PC_SOURCE_DIR) / "data/sidecars/CornellBox-Original.json", 0.3f, sidecar));
  auto scene = loadScene(path, sidecar);
  fs::remove(sidecar);
  ASSERT_TRUE(scene.ok()) << scene.error().message;
  const int width = 64, height = 48;
  const Result<Image8> ref = referenceImage(*scene, width, height);
  ASSERT_TRUE(ref.ok()) << ref.error().message;
  Field field = Field::create(scene->volumes, FieldSettings{});
  field.sceneHash = scene->hash;
  auto tracer = makeEmbreeTracer(*scene);
  ASSERT_TRUE(tracer.ok());
  BakeOptions options;
  options.updates = 24;
  ASSERT_TRUE(bakeField(field, **tracer, options).ok());
  double psnr[2] = {0, 0};
  for (int with = 0; with < 2; ++with) {
    ProbeLitOptions lit;
    lit.width = width;
    lit.height = height;
    lit.indirectSpecular = with == 1;
    auto image = renderProbeLit(*scene, field, lit);
    ASSERT_TRUE(image.ok());
    psnr[with] = psnr8(tonemap(*image, scene->exposure), ref.value());
  }
  std::printf("glossy Cornell (roughness 0.3): %.2f dB without the specular, %.2f dB with\n",
              psnr[0], psnr[1]);
  EXPECT_GT(psnr[1], psnr[0] + 1.0);
}

}  // namespace
}  // namespace pc
