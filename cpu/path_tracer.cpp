#include "path_tracer.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>

#include "camera.h"
#include "material_sampling.h"
#include "render_setup.h"

namespace pc {
namespace {

constexpr float kInvPi = 0.318309886f;
constexpr int kTileSize = 16;
constexpr int kRouletteStart = 3;  // bounces before Russian roulette may end a path
// 10 log10(4): averaging two halves halves the variance of each, and their difference has
// twice it, so the full image's error power is a quarter of the halves' difference power.
constexpr double kHalvesToFullDb = 6.0206;

bool finite(glm::vec3 v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

struct Tracer {
  const EmbreeScene& scene;
  std::vector<gpu::GpuLight> lights;  // packLights of the state
  const EmissiveLights& emissive;
  DirectLightOptions direct;
  int maxBounces;

  // Radiance arriving at `origin` along `dir` (one path, one sample).
  glm::vec3 radiance(glm::vec3 origin, glm::vec3 dir, Rng& rng) const {
    const Sky& sky = scene.scene().sky;
    glm::vec3 L(0.0f), throughput(1.0f);
    for (int bounce = 0;; ++bounce) {
      Hit hit;
      if (!scene.intersect(origin, dir, 0.0f, INFINITY, hit)) {
        L += throughput * sky.radiance(dir);
        break;
      }
      const SurfacePoint sp = scene.surface(hit, origin, dir);
      // Emission seen directly always counts; after a bounce only when light sampling did
      // not already count it at the previous vertex.
      if (bounce == 0 || !emissive.sampled(sp.material)) L += throughput * sp.emission;

      // The lights are evaluated at the hit point; the shadow rays and the path's next ray leave
      // from it moved off its triangle (pcShadowOrigin), as in the field update. An offset of
      // 256 float steps of the point's own coordinates, as before, grows with the distance
      // from the world's origin: 3000 units out it lit the built-in room as from 0.06 above
      // its surfaces, 7.7% brighter than at the origin.
      // Light cosines and the bounce see the shading normal (normal-mapped where the material
      // has a map); the offsets keep the geometric one.
      const glm::vec3 P = gpu::pcShadowOrigin(sp.position, sp.geometricNormal, sp.extent);
      const SurfaceBrdf brdf{sp.normal, sp.albedo, sp.metallic, sp.roughness};
      if (brdf.hasSpecularLobe()) {
        // Glossy: the light samples weighted by the whole BRDF, the bounce drawn from it.
        const glm::vec3 V = -dir;
        L += throughput *
             directReflected(scene, lights, emissive, sp.position, P, brdf, V, rng, direct);
        if (bounce >= maxBounces) break;
        MaterialSample next;
        const float uLobe = rng.uniform(), u1 = rng.uniform(), u2 = rng.uniform();
        if (!sampleMaterial(brdf, V, uLobe, u1, u2, next)) break;
        dir = next.dir;
        if (glm::dot(dir, sp.geometricNormal) <= 0.0f) break;
        throughput *= next.weight;
      } else {
        const glm::vec3 E =
            directIrradiance(scene, lights, emissive, sp.position, P, sp.normal, rng, direct);
        L += throughput * sp.albedo * kInvPi * E;
        if (bounce >= maxBounces) break;

        // Cosine-weighted continuation: the pdf cancels the cosine and the 1/pi of the diffuse
        // BRDF, leaving the albedo as the throughput factor.
        dir = sampleCosineHemisphere(sp.normal, rng.uniform(), rng.uniform());
        // A shading normal may send the ray below the real surface; such a path would pass
        // through it, so it ends here instead.
        if (glm::dot(dir, sp.geometricNormal) <= 0.0f) break;
        throughput *= sp.albedo;
      }
      if (bounce + 1 >= kRouletteStart) {
        const float keep = std::min(0.95f, std::max({throughput.x, throughput.y, throughput.z}));
        if (keep <= 0.0f || rng.uniform() >= keep) break;
        throughput /= keep;
      }
      origin = P;
    }
    return L;
  }
};

}  // namespace

int pathTraceTileCount(int width, int height) {
  return ((width + kTileSize - 1) / kTileSize) * ((height + kTileSize - 1) / kTileSize);
}

PathTraceResult pathTrace(const EmbreeScene& scene, const SceneState& state,
                          const EmissiveLights& emissive, const Camera& camera,
                          const PathTraceOptions& options, Progress* progress) {
  const auto start = std::chrono::steady_clock::now();
  const int width = options.width, height = options.height;
  const int spp = std::max(1, options.spp);
  // Two independent passes over the same pixels: their average is the image, their
  // difference measures its noise.
  const int passSpp[2] = {spp / 2, spp - spp / 2};

  const Tracer tracer{scene, packLights(state), emissive,
                      DirectLightOptions{options.emissiveSamples}, options.maxBounces};
  const PinholeCamera pinhole(camera, width, height);
  Image halves[2] = {Image(width, height), Image(width, height)};

  const int tilesX = (width + kTileSize - 1) / kTileSize;
  const int tiles = pathTraceTileCount(width, height);
  tbb::parallel_for(tbb::blocked_range<int>(0, tiles, 1), [&](const tbb::blocked_range<int>& r) {
    for (int tile = r.begin(); tile != r.end(); ++tile) {
      const int x0 = (tile % tilesX) * kTileSize, y0 = (tile / tilesX) * kTileSize;
      for (int y = y0; y < std::min(y0 + kTileSize, height); ++y) {
        for (int x = x0; x < std::min(x0 + kTileSize, width); ++x) {
          for (int pass = 0; pass < 2; ++pass) {
            Rng rng(pixelSeed(options.seed, x, y, pass), std::uint64_t(pass) + 1);
            glm::vec3 sum(0.0f);
            for (int s = 0; s < passSpp[pass]; ++s) {
              const float jx = rng.uniform(), jy = rng.uniform();
              const glm::vec3 L =
                  tracer.radiance(pinhole.origin(), pinhole.direction(x, y, jx, jy), rng);
              if (finite(L)) sum += L;  // a NaN would poison the pixel for good
            }
            if (passSpp[pass] > 0) halves[pass].at(x, y) = sum / float(passSpp[pass]);
          }
        }
      }
      if (progress) progress->advance();
    }
  });

  PathTraceResult result;
  result.image = Image(width, height);
  for (std::size_t i = 0; i < result.image.pixels.size(); ++i) {
    result.image.pixels[i] =
        (halves[0].pixels[i] * float(passSpp[0]) + halves[1].pixels[i] * float(passSpp[1])) /
        float(spp);
  }
  if (passSpp[0] > 0) {
    const float exposure = scene.scene().exposure;
    result.halvesPsnr = psnr8(tonemap(halves[0], exposure), tonemap(halves[1], exposure));
    result.noisePsnr = result.halvesPsnr + kHalvesToFullDb;
  }
  result.spp = spp;
  result.samples = std::uint64_t(width) * std::uint64_t(height) * std::uint64_t(spp);
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

Result<PathTraceResult> renderReference(const Scene& scene, const PathTraceOptions& options,
                                        Progress* progress) {
  auto setup = prepareCpuRender(scene, options.width, options.height, options.explicitCamera,
                                options.camera, options.time);
  if (!setup) return setup.error();
  return pathTrace(*setup->embree, setup->state, setup->emissive, setup->camera, options, progress);
}

Result<CpuRenderSetup> prepareCpuRender(const Scene& scene, int width, int height,
                                        const std::optional<Camera>& explicitCamera,
                                        int cameraIndex, double time) {
  if (width <= 0 || height <= 0) return Error{"image size must be positive"};
  CpuRenderSetup setup;
  if (explicitCamera) {
    setup.camera = *explicitCamera;
  } else {
    Result<Camera> chosen = sceneCamera(scene, cameraIndex);
    if (!chosen) return chosen.error();
    setup.camera = chosen.value();
  }
  auto embree = EmbreeScene::create(scene);
  if (!embree) return embree.error();
  setup.embree = std::move(embree).value();
  setup.state = evaluateScene(scene, time);
  setup.embree->update(setup.state);
  setup.emissive = EmissiveLights::build(scene, setup.state);
  return setup;
}

}  // namespace pc
