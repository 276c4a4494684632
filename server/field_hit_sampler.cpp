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

// Four probes side by side. Every operation below is the one of the shared code
// (probe_sampling.h, probe_math.h, the bilinear fetch of field.cpp) in the same order, lane by
// lane: IEEE rounding makes a lane's result the very float the scalar code computes. The
// texels are read with SSE loads and transposes (x86-64-v2 has SSE4.2); elsewhere the shared
// code runs as it is (FieldHitSampler::irradiance).
#if defined(__SSE4_1__)
constexpr bool kLanesAvailable = true;
#else
constexpr bool kLanesAvailable = false;
#endif
constexpr int kLanes = 4;
using Lanes = float __attribute__((vector_size(kLanes * sizeof(float))));
using IntLanes = std::int32_t __attribute__((vector_size(kLanes * sizeof(std::int32_t))));

Lanes splat(float x) { return Lanes{} + x; }
Lanes absLanes(Lanes v) { return v >= 0.0f ? v : -v; }
Lanes clamp01(Lanes v) { return v < 0.0f ? splat(0.0f) : (1.0f < v ? splat(1.0f) : v); }
IntLanes clampInt(IntLanes v, int hi) {  // std::clamp(v, 0, hi)
  const IntLanes zero{}, top = zero + hi;
  return v < zero ? zero : (top < v ? top : v);
}

// Up to four probes with data, in the order the shared code sums them, each with its position
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
// bilinear place of the lookup normal's irradiance texel (the same in every probe's tile).
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
#if defined(__SSE4_1__)
  // Position and depth tile of each probe: the first four words of its record, transposed.
  __m128 px, py, pz, depthTexel;
  {
    __m128 r[kLanes];
    for (int l = 0; l < kLanes; ++l) r[l] = _mm_loadu_ps(&g.probe[l < g.count ? l : 0]->position.x);
    _MM_TRANSPOSE4_PS(r[0], r[1], r[2], r[3]);
    px = r[0], py = r[1], pz = r[2], depthTexel = r[3];
  }
  // The backface term: toProbe = normalize(probeP - P).
  const Lanes dx = px - s.P.x, dy = py - s.P.y, dz = pz - s.P.z;
  const Lanes inv = 1.0f / Lanes(_mm_sqrt_ps(dx * dx + dy * dy + dz * dz));
  const Lanes wrap = ((dx * inv) * s.N.x + (dy * inv) * s.N.y + (dz * inv) * s.N.z + 1.0f) * 0.5f;
  Lanes weight = wrap * wrap + 0.2f;

  // The direction from the probe to the biased point, octahedrally encoded (pcTileCoord).
  const Lanes qx = s.biasedP.x - px, qy = s.biasedP.y - py, qz = s.biasedP.z - pz;
  const Lanes dist = _mm_sqrt_ps(qx * qx + qy * qy + qz * qz);
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
  const IntLanes x0 = clampInt(__builtin_convertvector(fx, IntLanes), tileSize - 2);
  const IntLanes y0 = clampInt(__builtin_convertvector(fy, IntLanes), tileSize - 2);
  const Lanes ax = clamp01(fx - __builtin_convertvector(x0, Lanes));
  const Lanes ay = clamp01(fy - __builtin_convertvector(y0, Lanes));

  // The depth moments, bilinear: each probe's two texel pairs (rows y0 and y0 + 1, texels x0
  // and x0 + 1, two moments each) in one load per row, transposed into lanes.
  const int depthRow = field.depth.width * 2;
  alignas(16) std::int32_t at[kLanes];
  const IntLanes offsets = (IntLanes)depthTexel + y0 * depthRow + x0 * 2;  // bits, not values
  _mm_store_si128(reinterpret_cast<__m128i*>(at), (__m128i)offsets);
  __m128 r0[kLanes], r1[kLanes];
  for (int l = 0; l < kLanes; ++l) {
    const float* t = field.depth.texels.data() + std::uint32_t(at[l]);
    r0[l] = _mm_loadu_ps(t);
    r1[l] = _mm_loadu_ps(t + depthRow);
  }
  _MM_TRANSPOSE4_PS(r0[0], r0[1], r0[2], r0[3]);  // t00 mean, t00 square, t10 mean, t10 square
  _MM_TRANSPOSE4_PS(r1[0], r1[1], r1[2], r1[3]);  // t01 ..., t11 ...
  Lanes moment[2];
  for (int c = 0; c < 2; ++c) {
    const Lanes t00 = r0[c], t10 = r0[2 + c], t01 = r1[c], t11 = r1[2 + c];
    const Lanes top = t00 + (t10 - t00) * ax;
    const Lanes bottom = t01 + (t11 - t01) * ax;
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
  weight = Lanes(_mm_loadu_ps(g.weight)) * weight;
  alignas(16) float w[kLanes];
  _mm_store_ps(w, weight);

  // Each probe's irradiance toward N, bilinear at the same place of every tile, its three
  // channels in one register (the fourth lane, a neighbour's channel, is dropped at the end),
  // to the perceptual space and summed in the shared code's order.
  const BilinearCoord& b = s.irradiance;
  const int irradianceRow = field.irradiance.width * 3;
  const std::size_t texel = std::size_t(b.y0) * irradianceRow + std::size_t(b.x0) * 3;
  __m128 total = _mm_setr_ps(sum.x, sum.y, sum.z, 0.0f);
  for (int l = 0; l < g.count; ++l) {
    const float* t = field.irradiance.texels.data() + g.probe[l]->irradianceTexel + texel;
    // Loads of texel x0 and (from two floats before it) texel x0 + 1: nothing past the tile.
    const Lanes t00 = _mm_loadu_ps(t), t01 = _mm_loadu_ps(t + irradianceRow);
    const Lanes t10 = _mm_shuffle_ps(_mm_loadu_ps(t + 2), _mm_loadu_ps(t + 2), 0xF9);
    const Lanes t11 = _mm_shuffle_ps(_mm_loadu_ps(t + irradianceRow + 2),
                                     _mm_loadu_ps(t + irradianceRow + 2), 0xF9);
    const Lanes top = t00 + (t10 - t00) * b.ax;
    const Lanes bottom = t01 + (t11 - t01) * b.ax;
    Lanes e = top + (bottom - top) * b.ay;
    e = e < 0.0f ? splat(0.0f) : e;
    const Lanes perceptual = e * e * Lanes(_mm_sqrt_ps(e));
    total = Lanes(total) + w[l] * perceptual;
    weightSum += w[l];
  }
  sum = glm::vec4(total[0], total[1], total[2], sum.w);
#else
  (void)field, (void)g, (void)s, (void)sum, (void)weightSum;
#endif
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

SamplePoint samplePoint(const gpu::CascadeDesc& c, glm::vec3 P, glm::vec3 N, glm::vec3 Ns,
                        glm::vec3 V) {
  constexpr int n = gpu::PC_IRRADIANCE_TEXELS;
  SamplePoint s{P, P + N * c.normalBias + V * c.viewBias, N,
                bilinearCoord(gpu::pcTileCoord(Ns, n), n + 2)};
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
              std::uint32_t((std::size_t(depth.y) * field.depth.width + depth.x) * 2),
              std::uint32_t((std::size_t(irradiance.y) * field.irradiance.width + irradiance.x) *
                            3),
              gpu::pcProbeHasData(record.state) ? 1u : 0u};
        }
  }
}

glm::vec4 FieldHitSampler::sampleCascade(int k, glm::vec3 P, glm::vec3 N, glm::vec3 Ns, glm::vec3 V,
                                         float& weightSum) const {
  const gpu::CascadeDesc& c = field_.cascade(k);
  const SamplePoint point = samplePoint(c, P, N, Ns, V);
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

glm::vec4 FieldHitSampler::sampleCascadeWide(int k, glm::vec3 P, glm::vec3 N, glm::vec3 Ns,
                                             glm::vec3 V, float& weightSum) const {
  const gpu::CascadeDesc& c = field_.cascade(k);
  const SamplePoint point = samplePoint(c, P, N, Ns, V);
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
  return irradiance(P, N, N, V);
}

glm::vec3 FieldHitSampler::irradiance(glm::vec3 P, glm::vec3 N, glm::vec3 Ns, glm::vec3 V) const {
  if (!tiled_ || !kLanesAvailable) {
    float coverage = 0.0f;
    return glm::vec3(gpu::pcSampleFieldShaded(field_, field_.desc, P, N, Ns, V,
                                              gpu::PC_SAMPLE_NO_OCCLUSION, coverage));
  }
  // pcSampleFieldShaded, cascade by cascade, then the wide fallback.
  const gpu::FieldDesc& f = field_.desc;
  glm::vec4 result(0.0f);
  float remaining = 1.0f;
  for (int k = 0; k < f.cascadeCount; ++k) {
    const float w = k == f.cascadeCount - 1 ? 1.0f : gpu::pcCascadeCoverage(f.cascades[k], P);
    if (w <= 0.0f) continue;
    float weightSum = 0.0f;
    const glm::vec4 s = sampleCascade(k, P, N, Ns, V, weightSum);
    if (weightSum <= 0.0f) continue;
    result += remaining * w * s;
    remaining *= 1.0f - w;
    if (remaining <= 0.0f) break;
  }
  if (remaining > 0.0f) {
    for (int k = 0; k < f.cascadeCount; ++k) {
      if (k < f.cascadeCount - 1 && gpu::pcCascadeCoverage(f.cascades[k], P) <= 0.0f) continue;
      float weightSum = 0.0f;
      const glm::vec4 s = sampleCascadeWide(k, P, N, Ns, V, weightSum);
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
