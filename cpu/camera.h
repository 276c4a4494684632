// Pinhole camera rays for the CPU renders: one ray per pixel position, with an optional
// sub-pixel offset (jitter) for anti-aliasing. Row 0 is the top of the image.
#pragma once

#include <cmath>
#include <cstdint>
#include <glm/glm.hpp>

#include "../common/scene.h"

namespace pc {

class PinholeCamera {
 public:
  PinholeCamera(const Camera& camera, int width, int height)
      : origin_(camera.position), width_(width), height_(height) {
    forward_ = glm::normalize(camera.forward);
    right_ = glm::normalize(glm::cross(forward_, camera.up));
    up_ = glm::cross(right_, forward_);
    const float tanHalf = std::tan(0.5f * camera.yfov);
    // Scale the basis once so a ray is a plain linear combination per pixel.
    up_ *= tanHalf;
    right_ *= tanHalf * float(width) / float(height);
  }

  glm::vec3 origin() const { return origin_; }

  // Unit direction through pixel (x, y) at offset (jx, jy) in [0, 1) inside the pixel;
  // (0.5, 0.5) is the pixel centre.
  glm::vec3 direction(int x, int y, float jx = 0.5f, float jy = 0.5f) const {
    const float sx = 2.0f * (float(x) + jx) / float(width_) - 1.0f;
    const float sy = 1.0f - 2.0f * (float(y) + jy) / float(height_);
    return glm::normalize(forward_ + sx * right_ + sy * up_);
  }

 private:
  glm::vec3 origin_, forward_, right_, up_;
  int width_, height_;
};

// Offset in [0, 1)^2 of primary sample s in its pixel: the first strata^2 samples jittered one
// to a cell of a strata x strata grid, the rest uniform. The reference integrates each pixel
// with hundreds of paths; at high-contrast edges (a window against its frame) a few uniform
// samples leave an error of a sizeable share of the contrast, which would be charged to the
// field. Stratified, the edge error falls as N^-3/4 instead of N^-1/2.
// jx, jy: two uniform numbers in [0, 1).
inline glm::vec2 stratifiedPixelOffset(int s, int strata, float jx, float jy) {
  if (s >= strata * strata) return {jx, jy};
  const float inv = 1.0f / float(strata);
  return {(float(s % strata) + jx) * inv, (float(s / strata) + jy) * inv};
}

// SplitMix64's finalizer: a bijection that scatters nearby inputs over all 64 bits.
inline std::uint64_t mixBits(std::uint64_t z) {
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

// Seed of pixel (x, y) for render pass `pass`, so neighbouring pixels get unrelated random
// streams and an image depends on the seed only (not on which thread drew which pixel).
inline std::uint64_t pixelSeed(std::uint64_t seed, int x, int y, int pass) {
  const std::uint64_t base = mixBits(seed + 0x9E3779B97F4A7C15ULL * (std::uint64_t(pass) + 1));
  return mixBits(base ^ (std::uint64_t(std::uint32_t(x)) << 32 | std::uint32_t(y)));
}

}  // namespace pc
