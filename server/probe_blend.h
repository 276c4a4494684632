// Blending one probe's ray results into its tiles on the CPU: irradiance (cosine lobe),
// depth moments (cos^exponent lobe), occlusion (sky visibility within d_max), then the
// probe's classification and relocation. The compute shaders do the same with the same
// shared math (shaders/interop/probe_update.h).
#pragma once

#include <cstdint>
#include <glm/glm.hpp>
#include <vector>

#include "../common/field.h"

namespace pc {

// What a probe ray brought back: radiance toward the probe and the signed hit distance
// (negative: backface hit; a miss reports +infinity).
struct RayResult {
  glm::vec3 radiance{0.0f};
  float distance = 0.0f;
};

// Texel directions of each tile, computed once.
struct TexelDirections {
  std::vector<glm::vec3> irradiance, depth, occlusion;
  static const TexelDirections& get();
};

// Which rays feed which texel, with what lobe weight. Every probe of an update shares the ray
// directions, so the weights are computed once per update rather than once per probe; only
// taps above a negligible weight are kept (the depth lobe is narrow).
struct TexelTaps {
  std::vector<std::uint32_t> begin;  // texel t's taps: [begin[t], begin[t + 1])
  std::vector<std::uint16_t> ray;
  std::vector<float> weight;
  static TexelTaps build(const std::vector<glm::vec3>& texelDirs, const glm::vec3* rayDirs,
                         int rayCount, float exponent, float minWeight);
};

// The irradiance and occlusion lobes (both cosine over the same 8x8 texel directions, so the
// same weights) as a dense texel x ray matrix, each row padded with zeros to a multiple of
// kLanes rays: the CPU blend sums a texel's row over contiguous per-ray arrays, kLanes rays at
// a time, instead of gathering its taps one by one.
struct CosineRows {
  static constexpr int kLanes = 4;
  int stride = 0;             // rays per row, padded
  std::vector<float> weight;  // texel t, ray i at [t * stride + i]; the taps' weights, else 0
  std::vector<float> total;   // per texel: the sum of its taps' weights, in tap order
  static CosineRows build(const TexelTaps& taps, int rayCount);
};

struct BlendTaps {
  TexelTaps irradiance, depth, occlusion;
  CosineRows cosine;  // irradiance's taps (equal to occlusion's) as dense rows
  static BlendTaps build(const glm::vec3* rayDirs, int rayCount, float distanceExponent);
};

// Blends `rays` (with directions `dirs`, weights `taps` built from the same directions) into
// probe (k, slot); returns the largest change of an encoded irradiance texel, for change
// detection.
float blendProbe(Field& field, int k, int slot, const RayResult* rays, const glm::vec3* dirs,
                 int rayCount, const BlendTaps& taps);

}  // namespace pc
