#include "probe_blend.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <glm/gtc/packing.hpp>
#include <limits>

#include "../shaders/interop/probe_update.h"
#include "../shaders/interop/sh_probe.h"

namespace pc {

using namespace pc::gpu;

namespace {

std::vector<glm::vec3> tileDirections(int n) {
  std::vector<glm::vec3> dirs;
  dirs.reserve(std::size_t(n) * n);
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) dirs.push_back(pcTexelDirection(x, y, n));
  return dirs;
}

// x^e for the depth lobe; integer exponents (the usual case) by squaring, which is far
// cheaper than pow in the innermost loop.
struct LobePower {
  explicit LobePower(float e) : exponent(e), integer(e == std::floor(e) && e >= 0 && e < 1024) {}
  float operator()(float x) const {
    if (!integer) return std::pow(x, exponent);
    float result = 1.0f, base = x;
    for (unsigned n = unsigned(exponent); n; n >>= 1) {
      if (n & 1u) result *= base;
      base *= base;
    }
    return result;
  }
  float exponent;
  bool integer;
};

}  // namespace

TexelTaps TexelTaps::build(const std::vector<glm::vec3>& texelDirs, const glm::vec3* rayDirs,
                           int rayCount, float exponent, float minWeight) {
  TexelTaps taps;
  const LobePower lobe(exponent);
  taps.begin.reserve(texelDirs.size() + 1);
  for (const glm::vec3& t : texelDirs) {
    taps.begin.push_back(std::uint32_t(taps.ray.size()));
    for (int i = 0; i < rayCount; ++i) {
      float c = glm::dot(t, rayDirs[i]);
      if (c <= 0.0f) continue;
      // Weights are kept at half precision: the GPU blend reads each tap as one 32-bit word
      // (ray index, weight's float16 bits), half the bytes of a full-precision tap, and both
      // backends then sum the very same weights. Float16's 11 significant bits shape the lobe
      // to within 0.05%, and each texel is normalized by the sum of these same weights.
      float w = glm::unpackHalf1x16(glm::packHalf1x16(exponent == 1.0f ? c : lobe(c)));
      if (w <= minWeight) continue;
      taps.ray.push_back(std::uint16_t(i));
      taps.weight.push_back(w);
    }
  }
  taps.begin.push_back(std::uint32_t(taps.ray.size()));
  return taps;
}

CosineRows CosineRows::build(const TexelTaps& taps, int rayCount) {
  CosineRows rows;
  rows.stride = (rayCount + kLanes - 1) / kLanes * kLanes;
  const std::size_t texels = taps.begin.empty() ? 0 : taps.begin.size() - 1;
  rows.weight.assign(texels * std::size_t(rows.stride), 0.0f);
  rows.total.assign(texels, 0.0f);
  for (std::size_t t = 0; t < texels; ++t) {
    for (std::uint32_t j = taps.begin[t]; j < taps.begin[t + 1]; ++j) {
      rows.weight[t * std::size_t(rows.stride) + taps.ray[j]] = taps.weight[j];
      rows.total[t] += taps.weight[j];
    }
  }
  return rows;
}

BlendTaps BlendTaps::build(const glm::vec3* rayDirs, int rayCount, float distanceExponent) {
  static_assert(PC_IRRADIANCE_TEXELS == PC_OCCLUSION_TEXELS,
                "the blend sums irradiance and occlusion over the same cosine rows");
  const TexelDirections& t = TexelDirections::get();
  // Depth: weights under 1e-4 of the peak change the moments by less than float rounding of
  // a typical sum; they are most of the pairs, since the cos^50 lobe is narrow.
  BlendTaps taps{TexelTaps::build(t.irradiance, rayDirs, rayCount, 1.0f, 0.0f),
                 TexelTaps::build(t.depth, rayDirs, rayCount, distanceExponent, 1e-4f),
                 TexelTaps::build(t.occlusion, rayDirs, rayCount, 1.0f, 0.0f),
                 {}};
  taps.cosine = CosineRows::build(taps.irradiance, rayCount);
  return taps;
}

const TexelDirections& TexelDirections::get() {
  static const TexelDirections dirs{tileDirections(PC_IRRADIANCE_TEXELS),
                                    tileDirections(PC_DEPTH_TEXELS),
                                    tileDirections(PC_OCCLUSION_TEXELS)};
  return dirs;
}

namespace {

// An SH probe's irradiance update: the rays that met no backface (those see the inside of
// geometry and carry no light, as in the tiles) projected onto the basis, blended with the
// probe's coefficients by the same hysteresis as a tile. The blend is linear in radiance (SH
// coefficients have no gamma-encoded form); the tile, derived afterwards, is encoded as usual.
float blendShProbe(Field& field, int k, int slot, const RayResult* rays, const glm::vec3* dirs,
                   int rayCount, float alpha) {
  glm::vec3 frontDirs[kMaxRaysPerProbe], radiance[kMaxRaysPerProbe];
  int front = 0;
  for (int i = 0; i < rayCount; ++i) {
    if (rays[i].distance < 0.0f) continue;
    frontDirs[front] = dirs[i];
    radiance[front] = rays[i].radiance;
    ++front;
  }
  if (front == 0) return 0.0f;
  const int count = pcShCoefficientCount(field.encoding(k));
  const ShCoefficients sample =
      projectSh({frontDirs, std::size_t(front)}, {radiance, std::size_t(front)}, count);
  ShCoefficients& coefficients = field.shProbe(k, slot);
  for (int i = 0; i < count; ++i) coefficients[i] = glm::mix(sample[i], coefficients[i], alpha);
  return deriveShTile(field, k, slot);
}

}  // namespace

float blendProbe(Field& field, int k, int slot, const RayResult* rays, const glm::vec3* dirs,
                 int rayCount, const BlendTaps& taps) {
  // Field::create and baked-file decoding keep the ray count in range; the per-ray scratch
  // below relies on it.
  if (rayCount < 1 || rayCount > kMaxRaysPerProbe) return 0.0f;
  const CascadeDesc& c = field.cascade(k);
  ProbeRecord& record = field.probe(k, slot);
  const float inf = std::numeric_limits<float>::infinity();

  // ---- classification and relocation statistics ----
  int backfaces = 0;
  float closestBack = inf, closestFront = inf;
  glm::vec3 closestBackDir(0.0f), closestFrontDir(0.0f);
  for (int i = 0; i < rayCount; ++i) {
    float d = rays[i].distance;
    if (d < 0.0f) {
      ++backfaces;
      if (-d < closestBack) closestBack = -d, closestBackDir = dirs[i];
    } else if (d < closestFront) {
      closestFront = d, closestFrontDir = dirs[i];
    }
  }
  const float backfaceFraction = float(backfaces) / float(std::max(rayCount, 1));
  const int oldState = record.state;
  const glm::vec3 oldOffset = record.offset;
  const bool inside = pcProbeInside(backfaceFraction, oldState);
  record.offset =
      pcRelocate(record.offset, inside, closestBack, closestBackDir, closestFront, closestFrontDir,
                 PC_RELOCATE_MIN_FRONTFACE * c.spacing, PC_RELOCATE_MAX_OFFSET * c.spacing);
  const bool moved = glm::length(record.offset - oldOffset) > 0.01f * c.spacing;

  if (inside) {
    // Inside geometry: its tiles describe the inside of a wall; never sampled. History is
    // dropped so that, once relocated out, it starts clean.
    record.state = PC_PROBE_INSIDE;
    record.updates = 0;
    return oldState != PC_PROBE_INSIDE || moved ? inf : 0.0f;
  }
  // No surface within reach of any cage this probe belongs to: nothing shades from it, so it
  // can sleep (traced rarely) until something moves near.
  const float reach = std::sqrt(3.0f) * c.spacing;
  record.state = (backfaces == 0 && closestFront > reach) ? PC_PROBE_SLEEPING : PC_PROBE_ACTIVE;

  const bool hasHistory = record.updates > 0 && !moved;
  // Running mean for the first updates, exponential (hysteresis) after: converges in few
  // updates from nothing, yet keeps the temporal filtering of DDGI.
  const float alpha =
      hasHistory ? std::min(c.hysteresis, float(record.updates) / float(record.updates + 1)) : 0.0f;
  record.updates = hasHistory ? record.updates + 1 : 1;

  float maxChange = (oldState != record.state || moved) ? inf : 0.0f;

  // ---- irradiance, SH cascades: project the rays, blend the coefficients, derive the tile ----
  const bool sh = pcEncodingIsSh(c.encoding);
  if (sh)
    maxChange = std::max(maxChange, blendShProbe(field, k, slot, rays, dirs, rayCount, alpha));
  // ---- irradiance (E = pi * cos-weighted mean radiance; backface rays carry no light) and
  // occlusion (cos-weighted share of rays that travel past d_max), from one pass per texel
  // over the cosine rows ----
  {
    constexpr int n = PC_IRRADIANCE_TEXELS;
    constexpr int kLanes = CosineRows::kLanes;
    using Lanes = float __attribute__((vector_size(kLanes * sizeof(float))));
    const CosineRows& rows = taps.cosine;
    const float dmax = field.desc.occlusionDistance;
    // Per-ray inputs as contiguous arrays, zero past the last ray: radiance of front-face hits
    // and misses, 1 for those (their weight counts), 1 for rays past d_max.
    alignas(16) float red[kMaxRaysPerProbe], green[kMaxRaysPerProbe], blue[kMaxRaysPerProbe];
    alignas(16) float front[kMaxRaysPerProbe], open[kMaxRaysPerProbe];
    for (int i = 0; i < rows.stride; ++i) {
      const bool ray = i < rayCount, isFront = ray && rays[i].distance >= 0.0f;
      red[i] = isFront ? rays[i].radiance.x : 0.0f;
      green[i] = isFront ? rays[i].radiance.y : 0.0f;
      blue[i] = isFront ? rays[i].radiance.z : 0.0f;
      front[i] = isFront ? 1.0f : 0.0f;
      open[i] = ray && rays[i].distance > dmax ? 1.0f : 0.0f;
    }
    const auto load = [](const float* p) {
      Lanes v;
      std::memcpy(&v, p, sizeof v);
      return v;
    };
    const auto sum = [](Lanes v) {
      float s = 0.0f;
      for (int l = 0; l < kLanes; ++l) s += v[l];
      return s;
    };
    const glm::ivec2 irradianceOrigin = pcAtlasTileOrigin(c, slot, n + 2);
    const glm::ivec2 occlusionOrigin = pcAtlasTileOrigin(c, slot, PC_OCCLUSION_TEXELS + 2);
    for (int t = 0; t < n * n; ++t) {
      const float* w = &rows.weight[std::size_t(t) * std::size_t(rows.stride)];
      Lanes r{}, g{}, b{}, frontWeight{}, openWeight{};
      for (int i = 0; i < rows.stride; i += kLanes) {
        const Lanes wi = load(w + i);
        r += wi * load(red + i);
        g += wi * load(green + i);
        b += wi * load(blue + i);
        frontWeight += wi * load(front + i);
        openWeight += wi * load(open + i);
      }
      const int x = t % n, y = t / n;
      const float weight = sum(frontWeight), allWeight = rows.total[std::size_t(t)];
      if (!sh && weight > 0.0f) {
        const glm::vec3 s(sum(r), sum(g), sum(b));
        glm::vec3 sample = pcEncodeIrradiance(PC_PI * s / weight);
        float* texel = field.irradiance.at(irradianceOrigin.x + 1 + x, irradianceOrigin.y + 1 + y);
        glm::vec3 old(texel[0], texel[1], texel[2]);
        glm::vec3 blended = glm::mix(sample, old, alpha);
        glm::vec3 delta = glm::abs(blended - old);
        maxChange = std::max(maxChange, std::max(delta.x, std::max(delta.y, delta.z)));
        texel[0] = blended.x, texel[1] = blended.y, texel[2] = blended.z;
      }
      if (allWeight > 0.0f) {
        float* texel = field.occlusion.at(occlusionOrigin.x + 1 + x, occlusionOrigin.y + 1 + y);
        texel[0] = glm::mix(sum(openWeight) / allWeight, texel[0], alpha);
      }
    }
  }
  // ---- depth moments: sharp lobe; backface hits count at a fraction of their distance ----
  {
    constexpr int n = PC_DEPTH_TEXELS;
    const TexelTaps& tt = taps.depth;
    glm::ivec2 origin = pcAtlasTileOrigin(c, slot, n + 2);
    float distance[kMaxRaysPerProbe];
    for (int i = 0; i < rayCount; ++i) {
      float d = rays[i].distance;
      distance[i] = d < 0.0f ? -d * PC_BACKFACE_DEPTH_SCALE : std::min(d, c.maxRayDistance);
    }
    for (int t = 0; t < n * n; ++t) {
      float m1 = 0.0f, m2 = 0.0f, weight = 0.0f;
      for (std::uint32_t j = tt.begin[t]; j < tt.begin[t + 1]; ++j) {
        const float d = distance[tt.ray[j]], w = tt.weight[j];
        m1 += w * d;
        m2 += w * d * d;
        weight += w;
      }
      if (weight <= 0.0f) continue;
      float* texel = field.depth.at(origin.x + 1 + t % n, origin.y + 1 + t / n);
      texel[0] = glm::mix(m1 / weight, texel[0], alpha);
      texel[1] = glm::mix(m2 / weight, texel[1], alpha);
    }
  }
  field.fixBorders(k, slot);
  return maxChange;
}

}  // namespace pc
