// Blending one probe's ray results into its tiles on the CPU: irradiance (cosine lobe),
// depth moments (cos^exponent lobe), occlusion (sky visibility within d_max), then the
// probe's classification and relocation. The compute shaders do the same with the same
// shared math (shaders/interop/probe_update.h).
#pragma once

#include <vector>

#include <glm/glm.hpp>

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

// Blends `rays` (with directions `dirs`) into probe (k, slot); returns the largest change of
// an encoded irradiance texel, for change detection.
float blendProbe(Field& field, int k, int slot, const RayResult* rays, const glm::vec3* dirs,
                 int rayCount);

}  // namespace pc
