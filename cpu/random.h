// Small, fast, seedable random numbers for the CPU tracers (PCG32).
#pragma once

#include <cstdint>

#include "../shaders/interop/probe_math.h"

namespace pc {

class Rng {
 public:
  explicit Rng(std::uint64_t seed, std::uint64_t stream = 1) : inc_((stream << 1u) | 1u) {
    next();
    state_ += seed;
    next();
  }
  std::uint32_t next() {
    std::uint64_t old = state_;
    state_ = old * 6364136223846793005ULL + inc_;
    auto xorshifted = static_cast<std::uint32_t>(((old >> 18u) ^ old) >> 27u);
    auto rot = static_cast<std::uint32_t>(old >> 59u);
    return (xorshifted >> rot) | (xorshifted << ((-rot) & 31));
  }
  // Uniform in [0, 1).
  float uniform() { return static_cast<float>(next() >> 8) * (1.0f / 16777216.0f); }

 private:
  std::uint64_t state_ = 0;
  std::uint64_t inc_;
};

// One probe ray's random stream in a field update, the GPU shade pass's own
// (gpu::pcRayRandomSeed): keyed by the ray, not drawn in sequence over a probe's rays, so the
// Embree and Vulkan backends light a hit with the same emitter samples.
class RayRng {
 public:
  RayRng(std::uint32_t seed, std::uint32_t rayIndex)
      : state_(gpu::pcRayRandomSeed(seed, rayIndex)) {}
  // Uniform in [0, 1).
  float uniform() {
    state_ = gpu::pcHash(state_);
    return gpu::pcHashToFloat(state_);
  }

 private:
  std::uint32_t state_;
};

}  // namespace pc
