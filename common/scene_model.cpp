// Small methods of the scene model: texture sampling, sky, counts, default probe volumes.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <utility>

#include "common/scene.h"
#include "common/scene_loaders.h"

// The one stb_image implementation in pc_common (image.cpp and the OBJ loader use it; tinygltf
// brings its own through libstb). Third-party code: its warnings are not ours to fix.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wall"
#pragma GCC diagnostic ignored "-Wextra"
#pragma GCC diagnostic ignored "-Wpedantic"
#pragma GCC diagnostic ignored "-Wsign-compare"
#pragma GCC diagnostic ignored "-Wunused-but-set-variable"
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#define STB_IMAGE_IMPLEMENTATION
#include <stb_image.h>
#pragma GCC diagnostic pop

namespace pc {

namespace {

int wrapIndex(int i, int n) {
  int r = i % n;
  return r < 0 ? r + n : r;
}

// The texels that whole texel coordinates f and f + 1 read on an axis of `n` texels (the two
// a bilinear lookup blends). Reduced in float before converting, so huge coordinates (tiling
// far from the origin) cannot overflow int.
std::pair<int, int> texelPair(float f, int n, TextureWrap wrap) {
  auto mirrored = [n](float g) {
    const int k = wrapIndex(int(std::fmod(g, 2.0f * float(n))), 2 * n);
    return k < n ? k : 2 * n - 1 - k;
  };
  switch (wrap) {
    case TextureWrap::ClampToEdge:
      return {int(std::clamp(f, 0.0f, float(n - 1))),
              int(std::clamp(f + 1.0f, 0.0f, float(n - 1)))};
    case TextureWrap::MirroredRepeat:
      return {mirrored(f), mirrored(f + 1.0f)};
    case TextureWrap::Repeat:
      break;
  }
  const int i = wrapIndex(int(std::fmod(f, float(n))), n);
  return {i, (i + 1) % n};
}

}  // namespace

namespace scene_detail {
float srgbToLinear(float v) {
  return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
}
}  // namespace scene_detail

// Built once: sampling is on hot paths (ray hits).
const std::array<float, 256>& srgbDecodeTable() {
  static const std::array<float, 256> table = [] {
    std::array<float, 256> t{};
    for (int i = 0; i < 256; ++i) t[i] = scene_detail::srgbToLinear(float(i) / 255.0f);
    return t;
  }();
  return table;
}

glm::vec4 Texture::sample(glm::vec2 uv) const {
  if (width <= 0 || height <= 0 || rgba.size() < std::size_t(width) * height * 4)
    return glm::vec4(1.0f);
  if (!std::isfinite(uv.x) || !std::isfinite(uv.y)) uv = glm::vec2(0.0f);
  // Texel centres sit at half-integer coordinates.
  float x = uv.x * float(width) - 0.5f;
  float y = uv.y * float(height) - 0.5f;
  float fx0 = std::floor(x), fy0 = std::floor(y);
  float tx = x - fx0, ty = y - fy0;
  const auto [x0, x1] = texelPair(fx0, width, wrapU);
  const auto [y0, y1] = texelPair(fy0, height, wrapV);
  const auto& lut = srgbDecodeTable();
  auto texel = [&](int px, int py) {
    const std::uint8_t* p = &rgba[(std::size_t(py) * width + px) * 4];
    if (linear) return glm::vec4(p[0], p[1], p[2], p[3]) / 255.0f;
    return glm::vec4(lut[p[0]], lut[p[1]], lut[p[2]], float(p[3]) / 255.0f);
  };
  glm::vec4 top = glm::mix(texel(x0, y0), texel(x1, y0), tx);
  glm::vec4 bottom = glm::mix(texel(x0, y1), texel(x1, y1), tx);
  return glm::mix(top, bottom, ty);
}

bool coveredAt(const Material& material, const std::vector<Texture>& textures, glm::vec2 uv) {
  if (!material.isCutOut()) return true;
  float alpha = material.baseAlpha;
  const int t = material.alphaTexture;
  if (t >= 0 && std::size_t(t) < textures.size())
    alpha *= textures[t].sample(uv)[std::clamp(material.alphaChannel, 0, 3)];
  return alpha >= material.alphaCutoff;
}

glm::vec3 Sky::radiance(glm::vec3 dir) const {
  float len = glm::length(dir);
  float y = len > 0.0f ? std::clamp(dir.y / len, -1.0f, 1.0f) : 0.0f;
  return y >= 0.0f ? glm::mix(horizon, zenith, y) : glm::mix(horizon, ground, -y);
}

bool Sky::isBlack() const {
  auto black = [](glm::vec3 c) { return c.x <= 0.0f && c.y <= 0.0f && c.z <= 0.0f; };
  return black(zenith) && black(horizon) && black(ground);
}

glm::vec3 Sky::ambientIrradiance() const {
  if (isBlack()) return glm::vec3(0.1f);
  return 3.14159265f * (0.5f * horizon + 0.25f * (zenith + ground));
}

std::size_t Scene::triangleCount() const {
  std::size_t n = 0;
  for (const Instance& inst : instances)
    if (inst.mesh >= 0 && std::size_t(inst.mesh) < meshes.size())
      n += meshes[inst.mesh].triangleCount();
  return n;
}

const Material* Scene::materialOf(const Instance& inst) const {
  if (inst.mesh < 0 || std::size_t(inst.mesh) >= meshes.size()) return nullptr;
  const int m = meshes[inst.mesh].material;
  return m >= 0 && std::size_t(m) < materials.size() ? &materials[m] : nullptr;
}

bool Scene::hasLights() const {
  if (!lights.empty()) return true;
  for (const Instance& inst : instances) {
    const Material* m = materialOf(inst);
    if (m && m->isEmissive()) return true;
  }
  return false;
}

bool Scene::hasCutOuts() const {
  for (const Instance& inst : instances) {
    const Material* m = materialOf(inst);
    if (m && m->isCutOut()) return true;
  }
  return false;
}

std::vector<ProbeVolume> defaultVolumes(const Scene& scene, int maxProbesPerAxis) {
  maxProbesPerAxis = std::max(maxProbesPerAxis, 2);
  glm::vec3 lo = scene.boundsMin, hi = scene.boundsMax;
  glm::vec3 extent = hi - lo;
  float largest = std::max({extent.x, extent.y, extent.z});
  // A scene too small for its spacing to be a normal float (or empty, or unbounded) gets the
  // fallback volume: extent / spacing would overflow and the field's biases underflow.
  const bool degenerate =
      !(largest > 0.0f) || !std::isfinite(largest) ||
      !(largest / float(2 * maxProbesPerAxis) >= std::numeric_limits<float>::min());
  if (degenerate) {
    ProbeVolume v;
    v.origin = glm::vec3(-3.5f);
    v.spacing = 1.0f;
    v.counts = glm::ivec3(8);
    return {v};
  }
  glm::vec3 centre = 0.5f * (lo + hi);
  // Probes sit half a spacing in from the bounds so none lies on an outer wall: along the
  // largest axis n probes span extent - spacing, hence spacing = extent / n.
  auto cascade = [&](float spacing) {
    ProbeVolume v;
    v.spacing = spacing;
    for (int a = 0; a < 3; ++a) {
      // At most the largest axis's count: the ratio is converted only once it is in range.
      const float n = std::ceil(extent[a] / spacing - 1e-3f);
      v.counts[a] = n < float(maxProbesPerAxis) ? std::max(int(n), 2) : maxProbesPerAxis;
    }
    v.origin = centre - 0.5f * spacing * glm::vec3(v.counts - 1);
    return v;
  };
  std::vector<ProbeVolume> out{cascade(largest / float(maxProbesPerAxis))};
  // Large grids get a coarser cascade too, for distant and fallback lookups.
  if (maxProbesPerAxis > 16) out.push_back(cascade(2.0f * largest / float(maxProbesPerAxis)));
  return out;
}

}  // namespace pc
