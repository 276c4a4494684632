// Helpers shared by the fuzz targets and the seed generator: a small deterministic field, the
// base brick residual payloads refer to, and the fix-ups that let mutated inputs get past the
// checks meant for transmission errors (length prefixes, checksums) to the parsing behind them.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "common/field.h"
#include "protocol/brick_codec.h"
#include "protocol/connect_token.h"
#include "protocol/datagram_seal.h"

namespace pc::fuzz {

// Two cascades (4x4x4 and 3x2x3 probes) with contents that depend on `seed`: irradiance in
// [0.5, 1.5], depth moments consistent with a mean and a spread, occlusion in [0.1, 0.9], small
// relocation offsets and every probe state.
inline Field smallField(unsigned seed) {
  std::vector<ProbeVolume> volumes(2);
  volumes[0].origin = glm::vec3(-1.0f, 0.0f, -1.0f);
  volumes[0].spacing = 0.5f;
  volumes[0].counts = glm::ivec3(4, 4, 4);
  volumes[1].origin = glm::vec3(-2.0f, -1.0f, -2.0f);
  volumes[1].spacing = 2.0f;
  volumes[1].counts = glm::ivec3(3, 2, 3);
  FieldSettings settings;
  settings.raysPerProbe = 64;
  Field f = Field::create(volumes, settings);

  // Smooth in the texel index, so that payloads compress to a few kilobytes.
  const float phase = 0.1f * float(seed);
  for (std::size_t i = 0; i < f.irradiance.texels.size(); ++i)
    f.irradiance.texels[i] = 1.0f + 0.5f * std::sin(phase + 0.01f * float(i));
  for (std::size_t i = 0; i + 1 < f.depth.texels.size(); i += 2) {
    const float mean = 1.5f + std::sin(phase + 0.002f * float(i)), spread = 0.1f;
    f.depth.texels[i] = mean;
    f.depth.texels[i + 1] = mean * mean + spread * spread;
  }
  for (std::size_t i = 0; i < f.occlusion.texels.size(); ++i)
    f.occlusion.texels[i] = 0.5f + 0.4f * std::cos(phase + 0.03f * float(i));
  for (std::size_t i = 0; i < f.probes.size(); ++i) {
    ProbeRecord& p = f.probes[i];
    p.offset = 0.05f * glm::vec3(std::sin(float(i)), std::cos(float(i)), 0.0f);
    p.state = int(i % 4);
    p.updates = std::uint32_t(i);
  }
  for (std::size_t k = 0; k < f.brickVersions.size(); ++k)
    for (std::size_t b = 0; b < f.brickVersions[k].size(); ++b) f.brickVersions[k][b] = 1 + b;
  f.version = 7;
  f.sceneHash = 0x5eedf00dull;
  return f;
}

// The base every residual payload in the brick target is decoded against.
inline const QuantizedBrick& baseBrick() {
  static const QuantizedBrick base = quantizeBrick(smallField(1), 0, 0);
  return base;
}

// A copy of a size-prefixed buffer whose 4-byte little-endian prefix announces the rest.
inline std::vector<std::uint8_t> withFittedPrefix(const std::uint8_t* data, std::size_t size) {
  std::vector<std::uint8_t> out(data, data + size);
  if (out.size() >= 4) {
    const std::uint32_t n = std::uint32_t(out.size() - 4);
    for (int i = 0; i < 4; ++i) out[i] = std::uint8_t(n >> (8 * i));
  }
  return out;
}

// The token target's verify key and clock, and the sealed datagram target's key and session:
// fixed, so that the seeds made with them verify and open in every run.
inline const KeyPair& tokenKeys() {
  static const KeyPair keys = [] {
    std::array<std::uint8_t, 32> seed;
    seed.fill(0x5e);
    return keyPairFromSeed(seed);
  }();
  return keys;
}
inline constexpr std::int64_t kTokenNow = 1'800'000'000;
inline DatagramKey sealKey() {
  DatagramKey key;
  for (std::size_t i = 0; i < key.size(); ++i) key[i] = std::uint8_t(0xc0 + i);
  return key;
}
inline constexpr std::uint32_t kSealSession = 17;

}  // namespace pc::fuzz
