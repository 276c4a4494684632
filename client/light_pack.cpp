#include "light_pack.h"

#include <algorithm>
#include <cmath>
#include <glm/gtc/matrix_transform.hpp>

namespace pc::client {
namespace {

// Cube faces in the order the shaders pick them (+x, -x, +y, -y, +z, -z).
constexpr glm::vec3 kFaceDirs[6] = {{1, 0, 0},  {-1, 0, 0}, {0, 1, 0},
                                    {0, -1, 0}, {0, 0, 1},  {0, 0, -1}};
constexpr glm::vec3 kFaceUps[6] = {{0, 1, 0}, {0, 1, 0}, {0, 0, 1},
                                   {0, 0, 1}, {0, 1, 0}, {0, 1, 0}};
// Receivers move along their normal by this many shadow texels before the lookup.
constexpr float kNormalOffsetTexels = 1.5f;

struct Bounds {
  glm::vec3 lo, hi;
  float diagonal() const { return glm::length(hi - lo); }
  glm::vec3 corner(int i) const {
    return glm::vec3(i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z);
  }
};

Bounds sceneBounds(const Scene& scene) {
  Bounds b{scene.boundsMin, scene.boundsMax};
  // Animated instances may leave the bounds of time 0: a margin keeps them in the sun's map.
  const glm::vec3 pad = glm::vec3(0.05f * std::max(b.diagonal(), 1e-3f));
  return {b.lo - pad, b.hi + pad};
}

float farthestCorner(const Bounds& b, glm::vec3 p) {
  float d = 0.0f;
  for (int i = 0; i < 8; ++i) d = std::max(d, glm::length(b.corner(i) - p));
  return d;
}

// A layer to render with `fromOrigin`, a view-projection of offsets from `origin`.
ShadowView shadowView(int array, int layer, const glm::mat4& fromOrigin, glm::vec3 origin) {
  ShadowView v;
  v.array = array;
  v.layer = layer;
  v.fromOrigin = fromOrigin;
  v.origin = origin;
  v.viewProj = fromOrigin * glm::translate(glm::mat4(1.0f), -origin);
  return v;
}

// Six 90-degree faces around `position`; faces whose whole frustum lies behind `front` (an
// emitter's normal) are left out since nothing there receives light.
void addCube(LightSet& set, gpu::GpuLight& light, int array, glm::vec3 position, float nearPlane,
             float farPlane, int size, const glm::vec3* front) {
  int& layers = set.layers[array];
  light.shadowArray = array;
  light.shadowLayer = layers;
  light.shadowMatrix = int(set.matrices.size());
  light.shadowTexel = 1.0f / float(size);
  light.normalOffset = kNormalOffsetTexels * 2.0f / float(size);  // 2 tan(45 deg) / size
  const glm::mat4 proj = glm::perspectiveRH_ZO(glm::radians(90.0f), 1.0f, nearPlane, farPlane);
  for (int f = 0; f < 6; ++f) {
    const glm::mat4 m = proj * glm::lookAtRH(glm::vec3(0.0f), kFaceDirs[f], kFaceUps[f]);
    set.matrices.push_back(m);
    if (!front || glm::dot(kFaceDirs[f], *front) > -0.99f)
      set.views.push_back(shadowView(array, layers + f, m, position));
  }
  layers += 6;
}

void addPunctual(LightSet& set, const Light& l, const Bounds& bounds, const ShadowSettings& s,
                 const ShadowFocus& focus) {
  gpu::GpuLight g = packLight(l);
  const float diag = std::max(bounds.diagonal(), 1e-3f);
  const float nearPlane = 1e-3f * diag;
  float farPlane = farthestCorner(bounds, l.position) * 1.01f + nearPlane;
  if (l.range > 0.0f) farPlane = std::min(farPlane, l.range);
  farPlane = std::max(farPlane, 2.0f * nearPlane);
  if (l.type == LightType::Point) {
    addCube(set, g, kPointShadowArray, l.position, nearPlane, farPlane, s.pointSize, nullptr);
  } else if (l.type == LightType::Spot) {
    const float fov = std::min(2.0f * l.outerConeAngle + 0.05f, glm::radians(170.0f));
    glm::vec3 up(0.0f, 1.0f, 0.0f);
    if (std::abs(glm::dot(up, g.direction)) > 0.99f) up = glm::vec3(1.0f, 0.0f, 0.0f);
    const glm::mat4 m = glm::perspectiveRH_ZO(fov, 1.0f, nearPlane, farPlane) *
                        glm::lookAtRH(glm::vec3(0.0f), g.direction, up);
    g.shadowArray = kLargeShadowArray;
    g.shadowLayer = set.layers[kLargeShadowArray]++;
    g.shadowMatrix = int(set.matrices.size());
    g.shadowTexel = 1.0f / float(s.largeSize);
    g.normalOffset = kNormalOffsetTexels * 2.0f * std::tan(0.5f * fov) / float(s.largeSize);
    set.matrices.push_back(m);
    set.views.push_back(shadowView(kLargeShadowArray, g.shadowLayer, m, g.position));
  } else {
    // The sun: cascaded orthographic maps fitted to the views (sun_cascades.h).
    const glm::vec3 centre = 0.5f * (bounds.lo + bounds.hi);
    glm::vec3 up(0.0f, 1.0f, 0.0f);
    if (std::abs(glm::dot(up, g.direction)) > 0.99f) up = glm::vec3(1.0f, 0.0f, 0.0f);
    // The shadow origin: the maps' eye, where the light's position would be. Fixed by the
    // scene's bounds, so the cascades' texel grids stay put while the camera moves.
    g.position = centre - g.direction * diag;
    const glm::mat4 view = glm::lookAtRH(glm::vec3(0.0f), g.direction, up);
    const SunCascadeMatrices cascades = fitSunCascades(
        view, g.position, bounds.lo, bounds.hi, s.sunCascades ? focus : ShadowFocus{}, s.largeSize);
    g.shadowArray = kLargeShadowArray;
    g.shadowLayer = set.layers[kLargeShadowArray];
    g.shadowMatrix = int(set.matrices.size());
    g.shadowTexel = 1.0f / float(s.largeSize);
    g.normalOffset = gpu::PC_SUN_NORMAL_OFFSET_TEXELS;  // in texels of each cascade's map
    for (int c = 0; c < gpu::PC_SUN_CASCADES; ++c) {
      set.matrices.push_back(cascades[std::size_t(c)]);
      set.views.push_back(
          shadowView(kLargeShadowArray, g.shadowLayer + c, cascades[std::size_t(c)], g.position));
    }
    set.layers[kLargeShadowArray] += gpu::PC_SUN_CASCADES;
  }
  set.lights.push_back(g);
}

void addAreaLight(LightSet& set, glm::vec3 position, glm::vec3 normal, glm::vec3 power,
                  float patchArea, const Bounds& bounds, const ShadowSettings& s) {
  gpu::GpuLight g{};
  g.type = gpu::PC_LIGHT_AREA;
  const float diag = std::max(bounds.diagonal(), 1e-3f);
  // Lifted off the emitter so its own surface never shadows it.
  g.position = position + normal * (1e-4f * diag);
  g.direction = normal;
  g.power = power;
  g.range = patchArea;  // squared distance where the patch stops brightening (see the shader)
  const float nearPlane = 1e-3f * diag;
  const float farPlane = farthestCorner(bounds, g.position) * 1.01f + nearPlane;
  addCube(set, g, kSmallShadowArray, g.position, nearPlane, farPlane, s.smallSize, &normal);
  set.lights.push_back(g);
  ++set.areaLightCount;
}

}  // namespace

LightSet buildLights(const Scene& scene, const SceneState& state, const EmissiveLights& emitters,
                     const ShadowSettings& settings, const ShadowFocus& focus) {
  LightSet set;
  const Bounds bounds = sceneBounds(scene);
  for (const Light& l : state.lights) addPunctual(set, l, bounds, settings, focus);
  if (emitters.empty() || settings.areaLights <= 0) return set;

  const auto& tris = emitters.triangles();
  const auto& cdf = emitters.cdf();
  const int budget = settings.areaLights;
  if (int(tris.size()) <= budget) {
    // Few emitter triangles: subdivide each into k x k similar triangles (centroids spread
    // evenly), k from the triangle's share of the power.
    for (std::size_t t = 0; t < tris.size(); ++t) {
      const auto& tri = tris[t];
      const float share = cdf[t] - (t > 0 ? cdf[t - 1] : 0.0f);
      const int k = std::max(1, int(std::lround(std::sqrt(float(budget) * share))));
      const float patch = tri.area / float(k * k);
      const glm::vec3 power = tri.radiance * patch;
      for (int i = 0; i < k; ++i) {
        for (int j = 0; i + j < k; ++j) {
          // Upward sub-triangle (i, j) and, where it exists, the downward one beside it.
          const glm::vec2 up((float(i) + 1.0f / 3.0f) / float(k),
                             (float(j) + 1.0f / 3.0f) / float(k));
          addAreaLight(set, tri.p0 + up.x * tri.e1 + up.y * tri.e2, tri.normal, power, patch,
                       bounds, settings);
          if (i + j < k - 1) {
            const glm::vec2 down((float(i) + 2.0f / 3.0f) / float(k),
                                 (float(j) + 2.0f / 3.0f) / float(k));
            addAreaLight(set, tri.p0 + down.x * tri.e1 + down.y * tri.e2, tri.normal, power, patch,
                         bounds, settings);
          }
        }
      }
    }
    return set;
  }
  // Many emitter triangles: stratified picks by power; each pick carries 1/budget of it.
  for (int i = 0; i < budget; ++i) {
    const float u = (float(i) + 0.5f) / float(budget);
    const std::size_t t = std::min<std::size_t>(
        std::upper_bound(cdf.begin(), cdf.end(), u) - cdf.begin(), tris.size() - 1);
    const auto& tri = tris[t];
    const float p = cdf[t] - (t > 0 ? cdf[t - 1] : 0.0f);
    if (p <= 0.0f) continue;
    const glm::vec3 centroid = tri.p0 + (tri.e1 + tri.e2) / 3.0f;
    const float area = tri.area / (p * float(budget));
    addAreaLight(set, centroid, tri.normal, tri.radiance * area, area, bounds, settings);
  }
  return set;
}

}  // namespace pc::client
