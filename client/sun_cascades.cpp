#include "sun_cascades.h"

#include <algorithm>
#include <cmath>
#include <glm/gtc/matrix_transform.hpp>

namespace pc::client {
namespace {

constexpr int kCascades = gpu::PC_SUN_CASCADES;
// Map widths come in steps of this factor (of the scene's width as the light sees it): a
// camera that moves or turns a little keeps the same width, hence the same texel grid.
constexpr float kWidthSteps = 8.0f;  // per doubling

struct Box2 {
  glm::vec2 lo{INFINITY}, hi{-INFINITY};
  void add(glm::vec2 p) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  bool empty() const { return !(lo.x < hi.x && lo.y < hi.y); }
};

glm::vec3 boxCorner(glm::vec3 lo, glm::vec3 hi, int i) {
  return glm::vec3(i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z);
}

// The light-space box (x, y) of every camera's view between distances `d0` and `d1`.
Box2 sliceBox(const glm::mat4& lightView, glm::vec3 origin, const ShadowFocus& focus, float d0,
              float d1) {
  Box2 box;
  for (const Camera& cam : focus.cameras) {
    const glm::vec3 f = glm::normalize(cam.forward);
    const glm::vec3 r = glm::normalize(glm::cross(f, cam.up));
    const glm::vec3 u = glm::cross(r, f);
    const float ty = std::tan(0.5f * cam.yfov), tx = ty * focus.aspect;
    for (float d : {d0, d1}) {
      for (int i = 0; i < 4; ++i) {
        const glm::vec3 p =
            cam.position + d * (f + (i & 1 ? tx : -tx) * r + (i & 2 ? ty : -ty) * u);
        box.add(glm::vec2(lightView * glm::vec4(p - origin, 1.0f)));
      }
    }
  }
  return box;
}

}  // namespace

std::array<float, kCascades + 1> sunCascadeSplits(float nearDistance, float farDistance) {
  std::array<float, kCascades + 1> s{};
  const float ratio = farDistance / nearDistance;
  for (int i = 0; i <= kCascades; ++i) {
    const float t = float(i) / float(kCascades);
    const float logSplit = nearDistance * std::pow(ratio, t);
    const float uniformSplit = nearDistance + (farDistance - nearDistance) * t;
    s[std::size_t(i)] = gpu::PC_SUN_CASCADE_LOG_SHARE * logSplit +
                        (1.0f - gpu::PC_SUN_CASCADE_LOG_SHARE) * uniformSplit;
  }
  s.front() = nearDistance;  // exactly, whatever the rounding
  s.back() = farDistance;
  return s;
}

SunCascadeMatrices fitSunCascades(const glm::mat4& lightView, glm::vec3 origin, glm::vec3 lo,
                                  glm::vec3 hi, const ShadowFocus& focus, int mapSize) {
  // The scene as the light sees it; view space looks down -z, so near and far are the negated
  // z extremes.
  glm::vec3 sceneLo(INFINITY), sceneHi(-INFINITY);
  for (int i = 0; i < 8; ++i) {
    const glm::vec3 p = glm::vec3(lightView * glm::vec4(boxCorner(lo, hi, i) - origin, 1.0f));
    sceneLo = glm::min(sceneLo, p);
    sceneHi = glm::max(sceneHi, p);
  }
  auto ortho = [&](glm::vec2 a, glm::vec2 b) {
    return glm::orthoRH_ZO(a.x, b.x, a.y, b.y, -sceneHi.z, -sceneLo.z) * lightView;
  };
  SunCascadeMatrices out;
  out.fill(ortho(glm::vec2(sceneLo), glm::vec2(sceneHi)));
  if (focus.cameras.empty()) return out;

  // The slices span the distances along the view at which the scene lies.
  float nearDistance = INFINITY, farDistance = 0.0f;
  for (const Camera& cam : focus.cameras) {
    const glm::vec3 f = glm::normalize(cam.forward);
    for (int i = 0; i < 8; ++i) {
      const float d = glm::dot(boxCorner(lo, hi, i) - cam.position, f);
      nearDistance = std::min(nearDistance, d);
      farDistance = std::max(farDistance, d);
    }
  }
  nearDistance =
      std::max({nearDistance, focus.nearPlane, gpu::PC_SUN_CASCADE_NEAREST * farDistance});
  if (!(farDistance > nearDistance)) return out;
  const auto splits = sunCascadeSplits(nearDistance, farDistance);

  const float sceneWidth = std::max(sceneHi.x - sceneLo.x, sceneHi.y - sceneLo.y);
  // Room for the filter's taps and the snap on each side, as a share of the map's width.
  const float pad = 2.0f * (gpu::PC_SUN_CASCADE_MARGIN_TEXELS + 2.0f) / float(mapSize);
  for (int c = 0; c < kCascades; ++c) {
    Box2 box =
        sliceBox(lightView, origin, focus, splits[std::size_t(c)], splits[std::size_t(c) + 1]);
    box.lo = glm::max(box.lo, glm::vec2(sceneLo));
    box.hi = glm::min(box.hi, glm::vec2(sceneHi));
    if (box.empty()) continue;  // the whole-scene map
    // A square map, its width the next step up from what the slice needs with its margins.
    const float needed = std::max(box.hi.x - box.lo.x, box.hi.y - box.lo.y) / (1.0f - pad);
    const float steps = std::floor(-kWidthSteps * std::log2(needed / sceneWidth));
    if (steps < 1.0f) continue;  // no finer than the whole-scene map
    const float width = sceneWidth * std::exp2(-steps / kWidthSteps);
    // Corners on whole texels of a grid fixed to the shadow origin.
    const float texel = width / float(mapSize);
    const glm::vec2 corner = glm::floor((0.5f * (box.lo + box.hi) - 0.5f * width) / texel) * texel;
    out[std::size_t(c)] = ortho(corner, corner + glm::vec2(width));
  }
  return out;
}

}  // namespace pc::client
