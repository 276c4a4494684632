#include "screen_ao.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>

// The estimator's inputs on the CPU: the traced surface buffer and the camera's rays.
namespace pc::gpu {
struct AoInputs {
  const pc::ViewSurfaces& surfaces;
  const pc::PinholeCamera& camera;
};
inline vec4 pcAoSurface(const AoInputs& in, ivec2 pixel) {
  const pc::ViewSurfaces& s = in.surfaces;
  if (pixel.x < 0 || pixel.y < 0 || pixel.x >= s.width || pixel.y >= s.height) return vec4(0.0f);
  return s.position[std::size_t(pixel.y) * s.width + pixel.x];
}
inline vec3 pcAoNormal(const AoInputs& in, ivec2 pixel) {
  return in.surfaces.normal[std::size_t(pixel.y) * in.surfaces.width + pixel.x];
}
inline vec3 pcAoRay(const AoInputs& in, vec2 pixel) {
  const float fx = std::floor(pixel.x), fy = std::floor(pixel.y);
  return in.camera.direction(int(fx), int(fy), pixel.x - fx, pixel.y - fy);
}
}  // namespace pc::gpu
#define PC_AO_PARAM const AoInputs &in,
#define PC_AO_ARG in,
#include "../shaders/interop/screen_ao_horizons.h"

namespace pc {

ViewSurfaces traceViewSurfaces(const EmbreeScene& scene, const PinholeCamera& camera, int width,
                               int height) {
  ViewSurfaces s;
  s.width = width;
  s.height = height;
  s.eye = camera.origin();
  const std::size_t n = std::size_t(width) * height;
  s.position.assign(n, glm::vec4(0.0f));
  s.normal.assign(n, glm::vec3(0.0f));
  s.albedo.assign(n, glm::vec3(0.0f));
  tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& r) {
    for (int y = r.begin(); y != r.end(); ++y) {
      for (int x = 0; x < width; ++x) {
        const glm::vec3 dir = camera.direction(x, y);
        Hit hit;
        if (!scene.intersect(camera.origin(), dir, 0.0f, INFINITY, hit)) continue;
        const SurfacePoint sp = scene.surface(hit, camera.origin(), dir);
        const std::size_t i = std::size_t(y) * width + x;
        // From the ray and its length, not sp.position - eye: no cancellation far from the
        // world's origin (the client stores the same).
        s.position[i] = glm::vec4(dir * hit.t, 1.0f);
        s.normal[i] = sp.vertexNormal;  // the surface's shape, as the client's AO reads it
        s.albedo[i] = sp.albedo;
      }
    }
  });
  return s;
}

std::vector<float> screenAmbientOcclusion(const ViewSurfaces& surfaces, const PinholeCamera& camera,
                                          const Field& field, float radiusScale) {
  std::vector<float> ao(surfaces.position.size(), 1.0f);
  if (radiusScale <= 0.0f || field.desc.cascadeCount <= 0) return ao;
  const gpu::AoInputs in{surfaces, camera};
  tbb::parallel_for(
      tbb::blocked_range<int>(0, surfaces.height), [&](const tbb::blocked_range<int>& r) {
        for (int y = r.begin(); y != r.end(); ++y) {
          for (int x = 0; x < surfaces.width; ++x) {
            const std::size_t i = std::size_t(y) * surfaces.width + x;
            const glm::vec4 p = surfaces.position[i];
            if (p.w <= 0.0f) continue;
            const glm::vec3 rel(p);
            const float radius = gpu::pcAoRadius(field.desc, surfaces.eye + rel, radiusScale);
            ao[i] = gpu::pcScreenAo(in, glm::ivec2(x, y), rel, surfaces.normal[i], radius);
          }
        }
      });
  return ao;
}

}  // namespace pc
