#include "probe_lit_render.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "../common/split_sum_table.h"
#include "camera.h"
#include "path_tracer.h"
#include "render_setup.h"
#include "screen_ao.h"

namespace pc {
namespace {

constexpr float kInvPi = 0.318309886f;
// Pass number of the probe-lit render's per-pixel seeds, distinct from the path tracer's
// passes so the two renders never share random streams.
constexpr int kProbeLitPass = 16;

}  // namespace

Image renderProbeLit(const EmbreeScene& scene, const SceneState& state,
                     const EmissiveLights& emissive, const Field& field, const Camera& camera,
                     const ProbeLitOptions& options, Progress* progress) {
  const int width = options.width, height = options.height;
  const int primary = std::max(1, options.primarySamples);
  const int strata = int(std::sqrt(double(primary)));
  const DirectLightOptions directOptions{std::max(1, options.emissiveSamples)};
  const SplitSumTable& table = splitSumTable();
  const std::vector<gpu::GpuLight> lights = packLights(state);
  const PinholeCamera pinhole(camera, width, height);
  const Sky& sky = scene.scene().sky;
  const glm::vec3 ambient = sky.ambientIrradiance();
  Image image(width, height);
  // One occlusion value per pixel, from the surfaces under the pixel centres (what a client's
  // visibility buffer holds), applied to every primary sample of the pixel as the client does.
  std::vector<float> ao;
  if (options.aoRadius > 0.0f && field.desc.cascadeCount > 0)
    ao = screenAmbientOcclusion(traceViewSurfaces(scene, pinhole, width, height), pinhole, field,
                                options.aoRadius);

  tbb::parallel_for(tbb::blocked_range<int>(0, height, 1), [&](const tbb::blocked_range<int>& r) {
    for (int y = r.begin(); y != r.end(); ++y) {
      for (int x = 0; x < width; ++x) {
        Rng rng(pixelSeed(options.seed, x, y, kProbeLitPass));
        glm::vec3 sum(0.0f);
        for (int s = 0; s < primary; ++s) {
          const glm::vec3 origin = pinhole.origin();
          const float jx = rng.uniform(), jy = rng.uniform();
          const glm::vec2 j = stratifiedPixelOffset(s, strata, jx, jy);
          const glm::vec3 dir = pinhole.direction(x, y, j.x, j.y);
          Hit hit;
          if (!scene.intersect(origin, dir, 0.0f, INFINITY, hit)) {
            sum += sky.radiance(dir);
            continue;
          }
          const SurfacePoint sp = scene.surface(hit, origin, dir);
          // Lights at the hit point, shadow rays from it moved off its triangle, as in the
          // field update and the reference (path_tracer.cpp).
          const glm::vec3 P = gpu::pcShadowOrigin(sp.position, sp.geometricNormal, sp.extent);
          const SurfaceBrdf brdf{sp.normal, sp.albedo, sp.metallic, sp.roughness};
          const bool glossy = brdf.hasSpecularLobe();
          const glm::vec3 V = -dir;
          // Lambert surfaces keep the irradiance form (same samples, same sums as before).
          const glm::vec3 direct = glossy
                                       ? directReflected(scene, lights, emissive, sp.position, P,
                                                         brdf, V, rng, directOptions)
                                       : sp.albedo * kInvPi *
                                             directIrradiance(scene, lights, emissive, sp.position,
                                                              P, sp.normal, rng, directOptions);
          // The field's sampler applies its own normal and view biases, so it gets the
          // surface point itself; V points from the surface back toward the camera. Its biases
          // and probe visibility follow the vertex normal, its irradiance lookup the shading
          // normal (probe_sampling.h). Where no probe near the point holds data, the ambient
          // term stands in, as in the client.
          glm::vec3 specular(0.0f);
          const bool withSpecular = glossy && options.indirectSpecular;
          const glm::vec4 sampled =
              withSpecular
                  ? sampleFieldOrAmbientLit(field, sp.position, sp.vertexNormal, sp.normal, V,
                                            options.sampleFlags, ambient,
                                            gpu::pcSpecularDirection(sp.normal, V, sp.roughness),
                                            sp.roughness, specular)
                  : sampleFieldOrAmbient(field, sp.position, sp.vertexNormal, sp.normal, V,
                                         options.sampleFlags, ambient);
          const glm::vec2 ab =
              withSpecular
                  ? lookupSplitSum(table, std::max(glm::dot(sp.normal, V), 0.0f), sp.roughness)
                  : glm::vec2(0.0f);
          glm::vec3 indirect =
              gpu::pcIndirectReflected(sp.normal, V, sp.albedo, sp.metallic, sp.roughness,
                                       glm::vec3(sampled.x, sampled.y, sampled.z), specular, ab);
          const float visibility = ao.empty() ? 1.0f : ao[std::size_t(y) * width + x];
          if (visibility < 1.0f) indirect *= gpu::pcAoMultiBounce(visibility, sp.albedo);
          const glm::vec3 L = sp.emission + direct + indirect;
          if (std::isfinite(L.x) && std::isfinite(L.y) && std::isfinite(L.z)) sum += L;
        }
        image.at(x, y) = sum / float(primary);
      }
      if (progress) progress->advance();
    }
  });
  return image;
}

Result<Image> renderProbeLit(const Scene& scene, const Field& field, const ProbeLitOptions& options,
                             Progress* progress) {
  auto setup = prepareCpuRender(scene, options.width, options.height, options.explicitCamera,
                                options.camera, options.time);
  if (!setup) return setup.error();
  return renderProbeLit(*setup->embree, setup->state, setup->emissive, field, setup->camera,
                        options, progress);
}

}  // namespace pc
