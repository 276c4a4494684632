// Shared by the codec and protocol tests: small synthetic fields that change like a traced one
// (an update bumps the field version and stamps it on the bricks it changed), and comparisons
// of a mirror against the server's field.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "common/field.h"
#include "protocol/brick_codec.h"
#include "protocol/session_messages.h"

namespace pc::test {

// Two cascades, 8x6x8 and 5x4x5 probes: 2x2x2 and 2x1x2 bricks, some overhanging the grid.
inline Field makeSyntheticLayout() {
  std::vector<ProbeVolume> volumes(2);
  volumes[0].origin = glm::vec3(-2.0f, 0.0f, -2.0f);
  volumes[0].spacing = 0.5f;
  volumes[0].counts = glm::ivec3(8, 6, 8);
  volumes[1].origin = glm::vec3(-4.0f, -1.0f, -4.0f);
  volumes[1].spacing = 2.0f;
  volumes[1].counts = glm::ivec3(5, 4, 5);
  Field f = Field::create(volumes, FieldSettings{});
  f.sceneHash = 0x5eed;
  return f;
}

// Writes smooth, plausible content into one brick's slots: irradiance that varies with the
// direction, the probe and the phase; consistent depth moments; occlusion in [0, 1].
inline void paintBrick(Field& f, int k, int brick, float phase) {
  using namespace gpu;
  const CascadeDesc& c = f.cascade(k);
  const float D = c.maxRayDistance;
  for (int s = 0; s < PC_PROBES_PER_BRICK; ++s) {
    const int slot = brick * PC_PROBES_PER_BRICK + s;
    if (!pcSlotValid(c, slot)) continue;
    const float pf = float(slot % 17) * 0.1f;
    auto tile = [&](Atlas& a, int n, auto&& write) {
      const glm::ivec2 o = pcAtlasTileOrigin(c, slot, n + 2) + glm::ivec2(1);
      for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) write(a.at(o.x + x, o.y + y), pcTexelDirection(x, y, n));
    };
    tile(f.irradiance, PC_IRRADIANCE_TEXELS, [&](float* t, glm::vec3 d) {
      for (int ch = 0; ch < 3; ++ch) {
        t[ch] = 0.6f + 0.3f * std::sin(phase + pf + d.y * 2.0f + float(ch)) + 0.1f * d.x;
      }
    });
    tile(f.depth, PC_DEPTH_TEXELS, [&](float* t, glm::vec3 d) {
      const float mean = D * (0.3f + 0.2f * std::sin(pf + d.z * 3.0f + 0.3f * phase));
      const float sigma = D * 0.02f * (1.5f + std::cos(pf + d.x));
      t[0] = mean;
      t[1] = mean * mean + sigma * sigma;
    });
    tile(f.occlusion, PC_OCCLUSION_TEXELS,
         [&](float* t, glm::vec3 d) { t[0] = 0.5f + 0.45f * std::sin(pf + d.y + 0.2f * phase); });
    ProbeRecord& p = f.probe(k, slot);
    p.offset = glm::vec3(0.05f * std::sin(pf), 0.0f, -0.03f) * c.spacing;
    p.state = (slot % 5 == 0) ? PC_PROBE_SLEEPING : PC_PROBE_ACTIVE;
    f.fixBorders(k, slot);
  }
}

// One "update": repaints a random share of the bricks with a new phase and stamps them with
// the next field version. Returns the number of bricks changed.
inline int evolveField(Field& f, std::mt19937& rng, float share, float phase) {
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  const std::uint64_t next = f.version + 1;
  int changed = 0;
  for (int k = 0; k < f.cascadeCount(); ++k) {
    for (int b = 0; b < gpu::pcBrickCount(f.cascade(k)); ++b) {
      if (f.brickVersions[k][b] != 0 && u(rng) >= share) continue;
      paintBrick(f, k, b, phase + 0.37f * float(b));
      f.brickVersions[k][b] = next;
      ++changed;
    }
  }
  if (changed) f.version = next;
  return changed;
}

// One update of a field whose content does not compress, as a field traced with few rays: every
// brick repainted with noise on every texel and stamped with the next field version. A brick
// of such a field is tens of fragments, as in real scenes.
inline void evolveNoisyField(Field& f, std::mt19937& rng, float phase) {
  std::uniform_real_distribution<float> noise(-0.1f, 0.1f);
  const std::uint64_t next = f.version + 1;
  for (int k = 0; k < f.cascadeCount(); ++k) {
    for (int b = 0; b < gpu::pcBrickCount(f.cascade(k)); ++b) {
      paintBrick(f, k, b, phase + 0.37f * float(b));
      for (int s = 0; s < gpu::PC_PROBES_PER_BRICK; ++s) {
        const int slot = b * gpu::PC_PROBES_PER_BRICK + s;
        if (!gpu::pcSlotValid(f.cascade(k), slot)) continue;
        const glm::ivec2 o =
            gpu::pcAtlasTileOrigin(f.cascade(k), slot, gpu::PC_IRRADIANCE_TEXELS + 2);
        for (int y = 1; y <= gpu::PC_IRRADIANCE_TEXELS; ++y)
          for (int x = 1; x <= gpu::PC_IRRADIANCE_TEXELS; ++x)
            for (int ch = 0; ch < 3; ++ch) f.irradiance.at(o.x + x, o.y + y)[ch] += noise(rng);
        const glm::ivec2 od = gpu::pcAtlasTileOrigin(f.cascade(k), slot, gpu::PC_DEPTH_TEXELS + 2);
        for (int y = 1; y <= gpu::PC_DEPTH_TEXELS; ++y)
          for (int x = 1; x <= gpu::PC_DEPTH_TEXELS; ++x) {
            float* t = f.depth.at(od.x + x, od.y + y);
            t[0] *= 1.0f + noise(rng);
            t[1] = t[0] * t[0] * (1.0f + std::abs(noise(rng)));
          }
        f.fixBorders(k, slot);
      }
      f.brickVersions[k][b] = next;
    }
  }
  f.version = next;
}

// What a client that holds every brick's current version exactly has: the server's field
// through quantization.
inline Field quantizedCopy(const Field& server) {
  auto mirror = mirrorField(sessionInfoFor(server));
  EXPECT_TRUE(mirror.ok());
  Field m = std::move(mirror.value());
  for (int k = 0; k < server.cascadeCount(); ++k) {
    for (int b = 0; b < int(server.brickVersions[k].size()); ++b) {
      if (server.brickVersions[k][b] == 0) continue;
      applyBrick(m, k, b, quantizeBrick(server, k, b));
      m.brickVersions[k][b] = server.brickVersions[k][b];
    }
  }
  return m;
}

// Number of bricks whose version or content differs between the mirror and the quantized
// server field (exact comparison of atlases, records and versions).
inline int differingBricks(const Field& mirror, const Field& quantized) {
  int n = 0;
  for (int k = 0; k < quantized.cascadeCount(); ++k) {
    const gpu::CascadeDesc& c = quantized.cascade(k);
    for (int b = 0; b < int(quantized.brickVersions[k].size()); ++b) {
      bool differs = mirror.brickVersions[k][b] != quantized.brickVersions[k][b];
      for (int s = 0; s < gpu::PC_PROBES_PER_BRICK && !differs; ++s) {
        const int slot = b * gpu::PC_PROBES_PER_BRICK + s;
        auto same = [&](const Atlas& x, const Atlas& y, int tile) {
          const glm::ivec2 o = gpu::pcAtlasTileOrigin(c, slot, tile);
          for (int yy = 0; yy < tile; ++yy)
            for (int xx = 0; xx < tile; ++xx)
              for (int ch = 0; ch < x.channels; ++ch)
                if (x.at(o.x + xx, o.y + yy)[ch] != y.at(o.x + xx, o.y + yy)[ch]) return false;
          return true;
        };
        differs = !same(mirror.irradiance, quantized.irradiance, gpu::PC_IRRADIANCE_TEXELS + 2) ||
                  !same(mirror.depth, quantized.depth, gpu::PC_DEPTH_TEXELS + 2) ||
                  !same(mirror.occlusion, quantized.occlusion, gpu::PC_OCCLUSION_TEXELS + 2) ||
                  mirror.probe(k, slot).offset != quantized.probe(k, slot).offset ||
                  mirror.probe(k, slot).state != quantized.probe(k, slot).state;
      }
      n += differs;
    }
  }
  return n;
}

// One update of a traced field: every brick's light moves a little (a slow phase) and every
// irradiance texel carries ray noise of about 1% of its value, a few of the codec's steps.
inline void evolveWithRayNoise(Field& f, std::mt19937& rng, float phase) {
  evolveField(f, rng, 1.0f, 0.2f * phase);
  std::normal_distribution<float> noise(0.0f, 0.01f);
  for (int k = 0; k < f.cascadeCount(); ++k) {
    for (int slot = 0; slot < gpu::pcBrickCount(f.cascade(k)) * gpu::PC_PROBES_PER_BRICK; ++slot) {
      if (!gpu::pcSlotValid(f.cascade(k), slot)) continue;
      const glm::ivec2 o =
          gpu::pcAtlasTileOrigin(f.cascade(k), slot, gpu::PC_IRRADIANCE_TEXELS + 2);
      for (int y = 1; y <= gpu::PC_IRRADIANCE_TEXELS; ++y)
        for (int x = 1; x <= gpu::PC_IRRADIANCE_TEXELS; ++x)
          for (int ch = 0; ch < 3; ++ch) {
            float& e = f.irradiance.at(o.x + x, o.y + y)[ch];
            e = std::max(0.0f, e * (1.0f + noise(rng)));
          }
      f.fixBorders(k, slot);
    }
  }
}

// The p-th quantile of `v` (0 when empty).
inline double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, std::size_t(p * double(v.size())))];
}

}  // namespace pc::test
