// The glossy BRDF (shaders/interop/brdf.h) and its importance sampling
// (cpu/material_sampling.h): GGX's distribution is normalised, the specular lobe with F = 1
// loses energy only to masking (near none when smooth), importance sampling and its pdf agree
// with uniform sampling, and the reference path tracer renders a glossy floor under a uniform
// sky at the directional albedo found by quadrature.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>

#include "common/scene.h"
#include "cpu/material_sampling.h"
#include "cpu/path_tracer.h"
#include "cpu/random.h"
#include "test_directions.h"
#include "test_meshes.h"

namespace pc {
namespace {

constexpr double kPi = std::numbers::pi;

using testdir::fromAngles;

glm::vec3 viewAt(float cosTheta) { return fromAngles(std::acos(double(cosTheta)), 0.3); }

// Directional albedo of `brdf` for V, integral of f cos over the hemisphere, by midpoint
// quadrature in (theta, phi).
glm::dvec3 albedoByQuadrature(const SurfaceBrdf& brdf, glm::vec3 V) {
  constexpr int kTheta = 1024, kPhi = 2048;
  const double dTheta = 0.5 * kPi / kTheta, dPhi = 2.0 * kPi / kPhi;
  glm::dvec3 sum(0.0);
  for (int i = 0; i < kTheta; ++i) {
    const double theta = (i + 0.5) * dTheta;
    const double measure = std::cos(theta) * std::sin(theta) * dTheta * dPhi;
    for (int j = 0; j < kPhi; ++j)
      sum += glm::dvec3(brdf.eval(V, fromAngles(theta, (j + 0.5) * dPhi))) * measure;
  }
  return sum;
}

// Mean and standard error of an estimator's samples (red channel).
struct Estimate {
  double mean = 0.0, error = 0.0;
};

template <class Draw>
Estimate estimate(int n, Draw draw) {
  double sum = 0.0, sumSq = 0.0;
  for (int i = 0; i < n; ++i) {
    const double x = draw();
    sum += x;
    sumSq += x * x;
  }
  const double mean = sum / n;
  return {mean, std::sqrt(std::max(0.0, sumSq / n - mean * mean) / n)};
}

// The unit hemisphere about +Y, uniformly (pdf 1 / 2 pi).
glm::vec3 uniformHemisphere(Rng& rng) {
  const double cosTheta = rng.uniform(), phi = 2.0 * kPi * rng.uniform();
  return fromAngles(std::acos(cosTheta), phi);
}

const glm::vec3 kUp(0.0f, 1.0f, 0.0f);

// The directional albedo (red) from sampleMaterial's draws, each weighted f cos / pdf.
Estimate sampledAlbedo(const SurfaceBrdf& brdf, glm::vec3 V, Rng& rng, int n = 100000) {
  return estimate(n, [&] {
    MaterialSample s;
    const float uLobe = rng.uniform(), u1 = rng.uniform(), u2 = rng.uniform();
    return sampleMaterial(brdf, V, uLobe, u1, u2, s) ? double(s.weight.x) : 0.0;
  });
}

TEST(GgxBrdf, DistributionIsNormalised) {
  // The integral of D(h) cos(theta_h) over the hemisphere is 1 for every roughness.
  for (float alpha : {0.02f, 0.1f, 0.3f, 0.7f, 1.0f}) {
    constexpr int kSteps = 400000;
    const double dTheta = 0.5 * kPi / kSteps;
    double sum = 0.0;
    for (int i = 0; i < kSteps; ++i) {
      const double theta = (i + 0.5) * dTheta;
      sum += gpu::pcGgxD(float(std::cos(theta)), alpha) * std::cos(theta) * std::sin(theta);
    }
    sum *= 2.0 * kPi * dTheta;
    EXPECT_NEAR(sum, 1.0, 2e-3) << "alpha " << alpha;
  }
}

// A white metal (F0 = 1, so Schlick's F is 1 everywhere): the lobe's albedo is what masking
// and shadowing leave, never above 1, and close to 1 when the surface is smooth.
TEST(GgxBrdf, WhiteFurnaceOfTheSpecularLobe) {
  Rng rng(7);
  for (float roughness : {0.1f, 0.3f, 0.6f, 1.0f}) {
    for (float cosView : {1.0f, 0.5f, 0.2f}) {
      const SurfaceBrdf brdf{kUp, glm::vec3(1.0f), 1.0f, roughness};
      const glm::vec3 V = viewAt(cosView);
      ASSERT_FLOAT_EQ(specularLobeChance(brdf, V), 1.0f);  // no diffuse lobe to draw
      const Estimate e = sampledAlbedo(brdf, V, rng);
      std::printf("GGX furnace roughness %.1f cos(view) %.1f: albedo %.4f +- %.4f\n", roughness,
                  cosView, e.mean, e.error);
      EXPECT_LE(e.mean, 1.0 + 3.0 * e.error + 1e-4);
      if (roughness <= 0.1f) {
        EXPECT_GT(e.mean, 0.98) << "cos(view) " << cosView;
      }
      if (roughness >= 1.0f && cosView <= 0.2f) {
        EXPECT_LT(e.mean, 0.9);  // masking and shadowing cost energy
      }
    }
  }
}

// A white dielectric (base colour 1, metallic 0) reflects at most what arrives, whatever its
// roughness and the view: the diffuse base gets only what the coat's Fresnel lets through
// toward the viewer.
TEST(GgxBrdf, WhiteDielectricReflectsAtMostWhatArrives) {
  Rng rng(5);
  for (float roughness : {0.05f, 0.3f, 0.6f, 0.95f}) {
    for (float cosView : {1.0f, 0.5f, 0.1f}) {
      const SurfaceBrdf brdf{kUp, glm::vec3(1.0f), 0.0f, roughness};
      const glm::vec3 V = viewAt(cosView);
      const Estimate e = sampledAlbedo(brdf, V, rng);
      std::printf("white dielectric roughness %.2f cos(view) %.1f: albedo %.4f +- %.4f\n",
                  roughness, cosView, e.mean, e.error);
      EXPECT_LE(e.mean, 1.0 + 3.0 * e.error + 1e-4);
      // Away from grazing it loses little; at grazing views a rough lobe's masking costs
      // what the coat took from the base (0.45 at roughness 0.95, cos 0.1).
      if (cosView >= 0.5f) {
        EXPECT_GT(e.mean, 0.95);
      }
    }
  }
}

// The directional albedo two ways: uniform directions weighted by f cos x 2 pi, and
// sampleMaterial's draws weighted by f cos / pdf. They agree only if the sampler draws with
// the density materialPdf states. And the density integrates to the share of draws that
// stay above the surface.
TEST(MaterialSampling, ImportanceAndUniformSamplingAgree) {
  struct Case {
    glm::vec3 baseColor;
    float metallic, roughness, cosView;
  };
  const Case cases[] = {{glm::vec3(0.8f), 0.0f, 0.5f, 0.9f},
                        {glm::vec3(0.8f), 0.0f, 0.3f, 0.3f},
                        {glm::vec3(1.0f, 0.78f, 0.34f), 1.0f, 0.4f, 0.7f},
                        {glm::vec3(0.5f, 0.6f, 0.7f), 0.5f, 0.7f, 0.5f},
                        {glm::vec3(0.9f), 0.2f, 0.25f, 0.95f}};
  Rng rng(11);
  for (const Case& c : cases) {
    const SurfaceBrdf brdf{kUp, c.baseColor, c.metallic, c.roughness};
    const glm::vec3 V = viewAt(c.cosView);
    const int n = 400000;
    const Estimate uniform = estimate(n, [&] {
      const glm::vec3 L = uniformHemisphere(rng);
      return double(brdf.eval(V, L).x * L.y) * 2.0 * kPi;
    });
    int accepted = 0;
    const Estimate importance = estimate(n, [&] {
      MaterialSample s;
      const float uLobe = rng.uniform(), u1 = rng.uniform(), u2 = rng.uniform();
      if (!sampleMaterial(brdf, V, uLobe, u1, u2, s)) return 0.0;
      ++accepted;
      EXPECT_NEAR(s.pdf, materialPdf(brdf, V, s.dir), 1e-4f * s.pdf);
      return double(s.weight.x);
    });
    const Estimate pdfMass = estimate(
        n, [&] { return double(materialPdf(brdf, V, uniformHemisphere(rng))) * 2.0 * kPi; });
    const double quadrature = albedoByQuadrature(brdf, V).x;
    const double acceptance = double(accepted) / n;
    std::printf(
        "metallic %.1f roughness %.2f cos(view) %.2f: albedo quadrature %.4f, uniform "
        "%.4f +- %.4f, importance %.4f +- %.4f; pdf mass %.4f +- %.4f, accepted %.4f\n",
        c.metallic, c.roughness, c.cosView, quadrature, uniform.mean, uniform.error,
        importance.mean, importance.error, pdfMass.mean, pdfMass.error, acceptance);
    const double both = std::hypot(uniform.error, importance.error);
    EXPECT_NEAR(uniform.mean, importance.mean, 4.0 * both + 1e-4);
    EXPECT_NEAR(importance.mean, quadrature, 4.0 * importance.error + 2e-3 * quadrature);
    EXPECT_NEAR(pdfMass.mean, acceptance, 4.0 * pdfMass.error + 4.0 / std::sqrt(double(n)));
    // Importance sampling is the point: it must be the less noisy of the two here.
    EXPECT_LT(importance.error, uniform.error);
  }
}

// A square floor of half-side `half` at y = 0 facing up, with the terms of `brdf`.
Scene floorScene(float half, const SurfaceBrdf& brdf) {
  Scene scene;
  Mesh floor;
  testmesh::addQuad(floor, {-half, 0, -half}, {-half, 0, half}, {half, 0, half}, {half, 0, -half});
  scene.meshes.push_back(floor);
  Material material;
  material.baseColor = brdf.baseColor;
  material.metallic = brdf.metallic;
  material.roughness = brdf.roughness;
  scene.materials.push_back(material);
  scene.instances.push_back(Instance{.mesh = 0});
  return scene;
}

// A camera `distance` from the origin along `toCamera`, looking at it.
Camera lookingAtOrigin(glm::vec3 toCamera, float distance, float yfov) {
  Camera camera;
  camera.position = distance * toCamera;
  camera.forward = -toCamera;
  camera.up = glm::normalize(glm::cross(glm::cross(camera.forward, kUp), camera.forward));
  camera.yfov = yfov;
  return camera;
}

PathTraceResult render(const Scene& scene, const Camera& camera, int size, int spp,
                       int maxBounces) {
  PathTraceOptions options;
  options.width = options.height = size;
  options.spp = spp;
  options.maxBounces = maxBounces;
  options.explicitCamera = camera;
  auto result = renderReference(scene, options);
  EXPECT_TRUE(result.ok()) << result.error().message;
  return result.ok() ? std::move(result).value() : PathTraceResult{};
}

// A large glossy floor under a uniform sky of radiance Ls, seen at 60 degrees from its normal
// through a narrow lens: every camera path bounces once into the sky, so the image is
// Ls x the floor's directional albedo for that view, whatever lobe each path drew.
TEST(PathTracer, GlossyFloorUnderUniformSkyMatchesQuadrature) {
  const SurfaceBrdf brdf{kUp, glm::vec3(0.9f, 0.6f, 0.3f), 0.5f, 0.4f};
  const float Ls = 2.0f;
  Scene scene = floorScene(50.0f, brdf);
  scene.sky.zenith = scene.sky.horizon = scene.sky.ground = glm::vec3(Ls);
  const glm::vec3 toCamera = fromAngles(kPi / 3.0, 0.0);
  const PathTraceResult result = render(scene, lookingAtOrigin(toCamera, 2.0f, 0.02f), 8, 2048, 1);
  glm::dvec3 mean(0.0);
  for (const glm::vec3& p : result.image.pixels) mean += glm::dvec3(p);
  mean /= double(result.image.pixels.size());

  const glm::dvec3 expected = double(Ls) * albedoByQuadrature(brdf, toCamera);
  std::printf("glossy floor: rendered (%.4f %.4f %.4f), quadrature (%.4f %.4f %.4f)\n", mean.x,
              mean.y, mean.z, expected.x, expected.y, expected.z);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(mean[k], expected[k], 0.01 * expected[k]) << k;
}

// A point light straight above a glossy floor, seen from the side without bounces: a pixel
// shows the BRDF for the light's direction times the irradiance, light samples weighted by
// the same BRDF the bounces sample.
TEST(PathTracer, GlossyDirectLightIsTheBrdfTimesIrradiance) {
  const SurfaceBrdf brdf{kUp, glm::vec3(0.7f), 0.0f, 0.6f};
  Scene scene = floorScene(10.0f, brdf);
  Light light;
  light.position = {0, 1, 0};
  light.intensity = 10.0f;
  scene.lights.push_back(light);
  const glm::vec3 toCamera = fromAngles(kPi / 4.0, 0.0);
  const PathTraceResult result = render(scene, lookingAtOrigin(toCamera, 1.5f, 0.002f), 2, 2, 0);
  // The pixels look at the origin: the light 1 above it, irradiance 10 W/m^2.
  const float expected = brdf.eval(toCamera, kUp).x * 10.0f;
  // The lobe matters here: the image is not Lambert's.
  EXPECT_GT(std::abs(expected - brdf.baseColor.x / float(kPi)), 0.01f * expected);
  ASSERT_EQ(result.image.pixels.size(), 4u);
  for (const glm::vec3& p : result.image.pixels) EXPECT_NEAR(p.x, expected, 0.01f * expected);
}

}  // namespace
}  // namespace pc
