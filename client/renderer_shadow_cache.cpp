#include "renderer_shadow_cache.h"

#include <algorithm>

namespace pc::client {

bool boxTouchesFrustum(const glm::mat4& viewProj, glm::vec3 lo, glm::vec3 hi) {
  // Each clip plane is linear in the world position, so a box lies outside it exactly when
  // all eight corners do (homogeneous tests: corners behind the eye need no special case).
  int outside[6] = {0, 0, 0, 0, 0, 0};
  for (int i = 0; i < 8; ++i) {
    const glm::vec3 p(i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z);
    const glm::vec4 c = viewProj * glm::vec4(p, 1.0f);
    outside[0] += c.x < -c.w;
    outside[1] += c.x > c.w;
    outside[2] += c.y < -c.w;
    outside[3] += c.y > c.w;
    outside[4] += c.z < 0.0f;
    outside[5] += c.z > c.w;
  }
  return std::none_of(outside, outside + 6, [](int n) { return n == 8; });
}

void worldBox(const glm::mat4& m, const LocalBounds& b, glm::vec3& lo, glm::vec3& hi) {
  lo = glm::vec3(INFINITY);
  hi = glm::vec3(-INFINITY);
  for (int i = 0; i < 8; ++i) {
    const glm::vec3 p(i & 1 ? b.hi.x : b.lo.x, i & 2 ? b.hi.y : b.lo.y, i & 4 ? b.hi.z : b.lo.z);
    const glm::vec3 w = glm::vec3(m * glm::vec4(p, 1.0f));
    lo = glm::min(lo, w);
    hi = glm::max(hi, w);
  }
}

void ShadowCache::reset(std::span<const int> layersPerArray) {
  for (int a = 0; a < kShadowArrays; ++a) {
    const int layers = a < int(layersPerArray.size()) ? layersPerArray[std::size_t(a)] : 0;
    layers_[a].assign(std::size_t(std::max(0, layers)), Layer{});
  }
  models_.clear();
  fresh_ = true;
}

std::vector<ShadowView> ShadowCache::select(const std::vector<ShadowView>& views,
                                            std::span<const glm::mat4> models,
                                            std::span<const LocalBounds> bounds) {
  // World boxes of the draws that moved since the previous frame, where they were and where
  // they are: a layer that sees either must be redrawn.
  std::vector<glm::vec3> movedLo, movedHi;
  const bool sameDraws = models_.size() == models.size();
  for (std::size_t d = 0; sameDraws && d < models.size(); ++d) {
    if (models[d] == models_[d]) continue;
    glm::vec3 lo, hi;
    worldBox(models_[d], bounds[d], lo, hi);
    movedLo.push_back(lo);
    movedHi.push_back(hi);
    worldBox(models[d], bounds[d], lo, hi);
    movedLo.push_back(lo);
    movedHi.push_back(hi);
  }
  std::vector<ShadowView> draw;
  for (const ShadowView& v : views) {
    auto& list = layers_[v.array];
    if (v.layer < 0 || std::size_t(v.layer) >= list.size()) continue;
    Layer& layer = list[std::size_t(v.layer)];
    bool redraw = !sameDraws || !layer.valid || layer.viewProj != v.viewProj;
    for (std::size_t i = 0; !redraw && i < movedLo.size(); ++i)
      redraw = boxTouchesFrustum(v.viewProj, movedLo[i], movedHi[i]);
    if (!redraw) continue;
    layer.valid = true;
    layer.viewProj = v.viewProj;
    draw.push_back(v);
  }
  models_.assign(models.begin(), models.end());
  fresh_ = false;
  return draw;
}

}  // namespace pc::client
