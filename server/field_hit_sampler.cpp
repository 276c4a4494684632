#include "field_hit_sampler.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#if defined(__SSE2__)
#include <immintrin.h>
#endif

// The shared sampling code, for its cascade coverage, probe states and final resolve.
#include "../common/field_shared_sampling.h"
#include "../shaders/interop/sh_probe.h"

namespace pc {

namespace {

// The lanes below never cross a call boundary of another translation unit, so the vector
// ABI's dependence on -march does not matter here.
#pragma GCC diagnostic ignored "-Wpsabi"

// Eight probes side by side. Every operation below is the one of the shared code
// (probe_sampling.h, probe_math.h, the bilinear fetch of field.cpp) in the same order, lane by
// lane: IEEE rounding makes a lane's result the very float the scalar code computes.
constexpr int kLanes = 8;
using Lanes = float __attribute__((vector_size(kLanes * sizeof(float))));
using IntLanes = std::int32_t __attribute__((vector_size(kLanes * sizeof(std::int32_t))));

Lanes sqrtLanes(Lanes v) {
#if defined(__SSE2__)
  alignas(32) float f[kLanes];
  std::memcpy(f, &v, sizeof v);
  for (int i = 0; i < kLanes; i += 4) _mm_store_ps(f + i, _mm_sqrt_ps(_mm_load_ps(f + i)));
  std::memcpy(&v, f, sizeof v);
#else
  for (int i = 0; i < kLanes; ++i) v[i] = std::sqrt(v[i]);
#endif
  return v;
}

Lanes splat(float x) { return Lanes{} + x; }
Lanes absLanes(Lanes v) { return v >= 0.0f ? v : -v; }
Lanes clamp01(Lanes v) { return v < 0.0f ? splat(0.0f) : (1.0f < v ? splat(1.0f) : v); }
IntLanes clampInt(IntLanes v, int hi) {  // std::clamp(v, 0, hi)
  const IntLanes zero{}, top = zero + hi;
  return v < zero ? zero : (top < v ? top : v);
}

// Up to eight probes with data, in the order the shared code sums them, each with its position
// weight (trilinear in a cage, tent in the wide block).
struct ProbeGroup {
  const FieldHitSampler::Probe* probe[kLanes];
  float weight[kLanes];
  int count = 0;
};

// Bilinear texel coordinates of a continuous tile coordinate (the fetch of field.cpp).
struct BilinearCoord {
  int x0, y0;
  float ax, ay;
};
BilinearCoord bilinearCoord(glm::vec2 tc, int tileSize) {
  const float fx = tc.x - 0.5f, fy = tc.y - 0.5f;
  const int x0 = std::clamp(int(fx), 0, tileSize - 2), y0 = std::clamp(int(fy), 0, tileSize - 2);
  return {x0, y0, std::clamp(fx - float(x0), 0.0f, 1.0f), std::clamp(fy - float(y0), 0.0f, 1.0f)};
}

// What one point needs to weigh probes: the point, its biased position and its normal, and the
// bilinear place of the normal's irradiance texel (the same in every probe's tile).
struct SamplePoint {
  glm::vec3 P, biasedP, N;
  BilinearCoord irradiance;
  glm::vec3 grid;   // biasedP in the cascade's grid units
  glm::ivec3 base;  // the cage's first corner
};

// Adds the group's probes to `sum` and `weightSum` as pcAccumulateProbe does (no occlusion),
// each weighted by its position weight times pcProbeVisibilityWeight.
void accumulate(const Field& field, const ProbeGroup& g, const SamplePoint& s, glm::vec4& sum,
                float& weightSum) {
  Lanes px, py, pz;
  for (int l = 0; l < kLanes; ++l) {
    const glm::vec3& p = g.probe[l < g.count ? l : 0]->position;
    px[l] = p.x, py[l] = p.y, pz[l] = p.z;
  }
  // The backface term: toProbe = normalize(probeP - P).
  const Lanes dx = px - s.P.x, dy = py - s.P.y, dz = pz - s.P.z;
  const Lanes inv = 1.0f / sqrtLanes(dx * dx + dy * dy + dz * dz);
  const Lanes wrap = ((dx * inv) * s.N.x + (dy * inv) * s.N.y + (dz * inv) * s.N.z + 1.0f) * 0.5f;
  Lanes weight = wrap * wrap + 0.2f;

  // The direction from the probe to the biased point, octahedrally encoded (pcTileCoord).
  const Lanes qx = s.biasedP.x - px, qy = s.biasedP.y - py, qz = s.biasedP.z - pz;
  const Lanes dist = sqrtLanes(qx * qx + qy * qy + qz * qz);
  const IntLanes away = dist > 0.0f;
  const Lanes ux = away ? qx / dist : splat(s.N.x), uy = away ? qy / dist : splat(s.N.y),
              uz = away ? qz / dist : splat(s.N.z);
  const Lanes l1 = absLanes(ux) + absLanes(uy) + absLanes(uz);
  Lanes u = ux / l1, v = uy / l1;
  const Lanes foldU = (1.0f - absLanes(v)) * (u >= 0.0f ? splat(1.0f) : splat(-1.0f));
  const Lanes foldV = (1.0f - absLanes(u)) * (v >= 0.0f ? splat(1.0f) : splat(-1.0f));
  u = uz < 0.0f ? foldU : u;
  v = uz < 0.0f ? foldV : v;
  constexpr int n = gpu::PC_DEPTH_TEXELS, tileSize = n + 2;
  const Lanes fx = 1.0f + (u * 0.5f + 0.5f) * float(n) - 0.5f;
  const Lanes fy = 1.0f + (v * 0.5f + 0.5f) * float(n) - 0.5f;
  IntLanes x0 = __builtin_convertvector(fx, IntLanes), y0 = __builtin_convertvector(fy, IntLanes);
  x0 = clampInt(x0, tileSize - 2);
  y0 = clampInt(y0, tileSize - 2);
  const Lanes ax = clamp01(fx - __builtin_convertvector(x0, Lanes));
  const Lanes ay = clamp01(fy - __builtin_convertvector(y0, Lanes));

  // The depth moments, bilinear, gathered lane by lane.
  const int depthRow = field.depth.width * 2;
  Lanes m[2][4];  // [moment][texel 00, 10, 01, 11]
  for (int l = 0; l < kLanes; ++l) {
    const float* t = field.depth.texels.data() + g.probe[l < g.count ? l : 0]->depthTexel +
                     std::size_t(y0[l]) * depthRow + std::size_t(x0[l]) * 2;
    for (int c = 0; c < 2; ++c) {
      m[c][0][l] = t[c], m[c][1][l] = t[2 + c];
      m[c][2][l] = t[depthRow + c], m[c][3][l] = t[depthRow + 2 + c];
    }
  }
  Lanes moment[2];
  for (int c = 0; c < 2; ++c) {
    const Lanes top = m[c][0] + (m[c][1] - m[c][0]) * ax;
    const Lanes bottom = m[c][2] + (m[c][3] - m[c][2]) * ax;
    moment[c] = top + (bottom - top) * ay;
  }

  // Chebyshev visibility, then the weight's floor and the crush of tiny weights.
  const Lanes mean = moment[0];
  const Lanes variance = absLanes(moment[1] - mean * mean);
  const Lanes d = dist - mean;
  const Lanes p = variance / (variance + d * d);
  const Lanes p3 = p * p * p;
  const Lanes chebyshev = dist <= mean ? splat(1.0f) : (p3 < 0.0f ? splat(0.0f) : p3);
  weight *= 0.05f < chebyshev ? chebyshev : splat(0.05f);
  weight = weight < 0.000001f ? splat(0.000001f) : weight;
  const float crush = 0.2f;
  weight = weight < crush ? weight * (weight * weight / (crush * crush)) : weight;
  Lanes position;
  for (int l = 0; l < kLanes; ++l) position[l] = g.weight[l < g.count ? l : 0];
  weight = position * weight;

  // Irradiance toward N, bilinear at the same place of every tile, to the perceptual space.
  const BilinearCoord& b = s.irradiance;
  const int irradianceRow = field.irradiance.width * 3;
  Lanes e[3][4];
  for (int l = 0; l < kLanes; ++l) {
    const float* t = field.irradiance.texels.data() +
                     g.probe[l < g.count ? l : 0]->irradianceTexel +
                     std::size_t(b.y0) * irradianceRow + std::size_t(b.x0) * 3;
    for (int c = 0; c < 3; ++c) {
      e[c][0][l] = t[c], e[c][1][l] = t[3 + c];
      e[c][2][l] = t[irradianceRow + c], e[c][3][l] = t[irradianceRow + 3 + c];
    }
  }
  Lanes perceptual[3];
  for (int c = 0; c < 3; ++c) {
    const Lanes top = e[c][0] + (e[c][1] - e[c][0]) * b.ax;
    const Lanes bottom = e[c][2] + (e[c][3] - e[c][2]) * b.ax;
    Lanes encoded = top + (bottom - top) * b.ay;
    encoded = encoded < 0.0f ? splat(0.0f) : encoded;
    perceptual[c] = encoded * encoded * sqrtLanes(encoded);
  }
  // Summed in the shared code's order.
  for (int l = 0; l < g.count; ++l) {
    sum += weight[l] * glm::vec4(perceptual[0][l], perceptual[1][l], perceptual[2][l], 0.0f);
    weightSum += weight[l];
  }
}

// Collects probes into groups of eight and sums each full group.
struct GroupSummer {
  const Field& field;
  const SamplePoint& point;
  ProbeGroup group;
  glm::vec4 sum{0.0f};
  float weightSum = 0.0f;

  void add(const FieldHitSampler::Probe& probe, float weight) {
    group.probe[group.count] = &probe;
    group.weight[group.count] = weight;
    if (++group.count == kLanes) flush();
  }
  void flush() {
    if (group.count > 0) accumulate(field, group, point, sum, weightSum);
    group.count = 0;
  }
};

int logicalIndex(const gpu::CascadeDesc& c, glm::ivec3 logical) {
  return logical.x + c.counts.x * (logical.y + c.counts.y * logical.z);
}

SamplePoint samplePoint(const gpu::CascadeDesc& c, glm::vec3 P, glm::vec3 N, glm::vec3 V) {
  constexpr int n = gpu::PC_IRRADIANCE_TEXELS;
  SamplePoint s{P, P + N * c.normalBias + V * c.viewBias, N,
                bilinearCoord(gpu::pcTileCoord(N, n), n + 2)};
  s.grid = (s.biasedP - c.origin) / c.spacing;
  s.base = glm::clamp(glm::ivec3(glm::floor(s.grid)), glm::ivec3(0),
                      glm::max(c.counts - glm::ivec3(2), glm::ivec3(0)));
  return s;
}

}  // namespace

FieldHitSampler::FieldHitSampler(const Field& field) : field_(field) {
  probes_.resize(std::size_t(field.cascadeCount()));
  for (int k = 0; k < field.cascadeCount(); ++k) {
    const gpu::CascadeDesc& c = field.cascade(k);
    if (gpu::pcEncodingIsSh(c.encoding)) tiled_ = false;
    std::vector<Probe>& probes = probes_[std::size_t(k)];
    probes.resize(std::size_t(c.counts.x) * c.counts.y * c.counts.z);
    for (int z = 0; z < c.counts.z; ++z)
      for (int y = 0; y < c.counts.y; ++y)
        for (int x = 0; x < c.counts.x; ++x) {
          const glm::ivec3 logical(x, y, z);
          const int slot = gpu::pcProbeSlot(c, gpu::pcPhysicalCoord(c, logical));
          const ProbeRecord& record = field.probe(k, slot);
          const glm::ivec2 irradiance =
              gpu::pcAtlasTileOrigin(c, slot, gpu::PC_IRRADIANCE_TEXELS + 2);
          const glm::ivec2 depth = gpu::pcAtlasTileOrigin(c, slot, gpu::PC_DEPTH_TEXELS + 2);
          probes[std::size_t(logicalIndex(c, logical))] = {
              gpu::pcProbeGridPosition(c, logical) + record.offset,
              gpu::pcProbeHasData(record.state) ? 1u : 0u,
              std::uint32_t((std::size_t(irradiance.y) * field.irradiance.width + irradiance.x) *
                            3),
              std::uint32_t((std::size_t(depth.y) * field.depth.width + depth.x) * 2)};
        }
  }
}

glm::vec4 FieldHitSampler::sampleCascade(int k, glm::vec3 P, glm::vec3 N, glm::vec3 V,
                                         float& weightSum) const {
  const gpu::CascadeDesc& c = field_.cascade(k);
  const SamplePoint point = samplePoint(c, P, N, V);
  const glm::ivec3 base = point.base;
  const glm::vec3 alpha =
      glm::clamp(point.grid - glm::vec3(base), glm::vec3(0.0f), glm::vec3(1.0f));
  const std::vector<Probe>& probes = probes_[std::size_t(k)];
  GroupSummer summer{field_, point};
  for (int i = 0; i < 8; ++i) {
    const glm::ivec3 offset(i & 1, (i >> 1) & 1, (i >> 2) & 1);
    const glm::ivec3 logical = glm::min(base + offset, c.counts - glm::ivec3(1));
    const Probe& probe = probes[std::size_t(logicalIndex(c, logical))];
    if (!probe.hasData) continue;
    const glm::vec3 tri = glm::mix(glm::vec3(1.0f) - alpha, alpha, glm::vec3(offset));
    summer.add(probe, std::max(0.001f, tri.x * tri.y * tri.z));
  }
  summer.flush();
  weightSum = summer.weightSum;
  return gpu::pcResolveProbeSum(summer.sum, summer.weightSum);
}

glm::vec4 FieldHitSampler::sampleCascadeWide(int k, glm::vec3 P, glm::vec3 N, glm::vec3 V,
                                             float& weightSum) const {
  const gpu::CascadeDesc& c = field_.cascade(k);
  const SamplePoint point = samplePoint(c, P, N, V);
  const glm::vec3 grid = point.grid;
  const glm::ivec3 base = point.base;
  const std::vector<Probe>& probes = probes_[std::size_t(k)];
  GroupSummer summer{field_, point};
  for (int i = 0; i < 64; ++i) {
    const glm::ivec3 logical = base + glm::ivec3(i & 3, (i >> 2) & 3, (i >> 4) & 3) - glm::ivec3(1);
    if (logical.x < 0 || logical.y < 0 || logical.z < 0 || logical.x >= c.counts.x ||
        logical.y >= c.counts.y || logical.z >= c.counts.z)
      continue;
    const Probe& probe = probes[std::size_t(logicalIndex(c, logical))];
    if (!probe.hasData) continue;
    const glm::vec3 tent =
        glm::max(glm::vec3(0.0f), glm::vec3(1.0f) - glm::abs(grid - glm::vec3(logical)) * 0.5f);
    summer.add(probe, std::max(0.001f, tent.x * tent.y * tent.z));
  }
  summer.flush();
  weightSum = summer.weightSum;
  return gpu::pcResolveProbeSum(summer.sum, summer.weightSum);
}

glm::vec3 FieldHitSampler::irradiance(glm::vec3 P, glm::vec3 N, glm::vec3 V) const {
  if (!tiled_) return glm::vec3(sampleField(field_, P, N, V, gpu::PC_SAMPLE_NO_OCCLUSION));
  // pcSampleFieldShaded, cascade by cascade, then the wide fallback.
  const gpu::FieldDesc& f = field_.desc;
  glm::vec4 result(0.0f);
  float remaining = 1.0f;
  for (int k = 0; k < f.cascadeCount; ++k) {
    const float w = k == f.cascadeCount - 1 ? 1.0f : gpu::pcCascadeCoverage(f.cascades[k], P);
    if (w <= 0.0f) continue;
    float weightSum = 0.0f;
    const glm::vec4 s = sampleCascade(k, P, N, V, weightSum);
    if (weightSum <= 0.0f) continue;
    result += remaining * w * s;
    remaining *= 1.0f - w;
    if (remaining <= 0.0f) break;
  }
  if (remaining > 0.0f) {
    for (int k = 0; k < f.cascadeCount; ++k) {
      if (k < f.cascadeCount - 1 && gpu::pcCascadeCoverage(f.cascades[k], P) <= 0.0f) continue;
      float weightSum = 0.0f;
      const glm::vec4 s = sampleCascadeWide(k, P, N, V, weightSum);
      if (weightSum <= 0.0f) continue;
      result += remaining * s;
      remaining = 0.0f;
      break;
    }
  }
  const float coverage = 1.0f - remaining;
  return coverage > 0.0f ? glm::vec3(result / coverage) : glm::vec3(0.0f);
}

}  // namespace pc
