#include "indirect_coverage.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>

#include "camera.h"
#include "render_setup.h"

namespace pc {

IndirectCoverage measureIndirectCoverage(const EmbreeScene& scene, const Field& field,
                                         const Camera& camera, int width, int height, int flags) {
  const PinholeCamera pinhole(camera, width, height);
  const glm::vec3 ambient = scene.scene().sky.ambientIrradiance();
  const auto add = [](IndirectCoverage a, const IndirectCoverage& b) {
    a.surfacePixels += b.surfacePixels;
    a.blackPixels += b.blackPixels;
    a.uncoveredPixels += b.uncoveredPixels;
    return a;
  };
  return tbb::parallel_reduce(
      tbb::blocked_range<int>(0, height, 1), IndirectCoverage{},
      [&](const tbb::blocked_range<int>& r, IndirectCoverage c) {
        for (int y = r.begin(); y != r.end(); ++y) {
          for (int x = 0; x < width; ++x) {
            const glm::vec3 dir = pinhole.direction(x, y);
            Hit hit;
            if (!scene.intersect(pinhole.origin(), dir, 0.0f, INFINITY, hit)) continue;
            const SurfacePoint sp = scene.surface(hit, pinhole.origin(), dir);
            // A black surface is black whatever the field holds.
            if (std::max(sp.albedo.x, std::max(sp.albedo.y, sp.albedo.z)) <= 0.0f) continue;
            ++c.surfacePixels;
            float coverage = 0.0f;
            sampleField(field, sp.position, sp.vertexNormal, -dir, flags, &coverage);
            if (coverage <= 0.0f) ++c.uncoveredPixels;
            const glm::vec4 e = sampleFieldOrAmbient(field, sp.position, sp.vertexNormal, sp.normal,
                                                     -dir, flags, ambient);
            if (!(std::max(e.x, std::max(e.y, e.z)) > 0.0f)) ++c.blackPixels;  // NaN counts
          }
        }
        return c;
      },
      add);
}

Result<IndirectCoverage> measureIndirectCoverage(const Scene& scene, const Field& field,
                                                 const std::optional<Camera>& explicitCamera,
                                                 int cameraIndex, int width, int height, int flags,
                                                 double time) {
  auto setup = prepareCpuRender(scene, width, height, explicitCamera, cameraIndex, time);
  if (!setup) return setup.error();
  return measureIndirectCoverage(*setup->embree, field, setup->camera, width, height, flags);
}

}  // namespace pc
