#include "field_compare.h"

#include <algorithm>
#include <cmath>

#include "../shaders/interop/probe_update.h"

namespace pc {
namespace {

// One probe's tiles in both fields, summed over the interior texels (decoded irradiance, all
// channels; mean depth).
struct TileSums {
  double irradianceA = 0, irradianceB = 0, irradianceError = 0, irradianceMagnitudeB = 0;
  double depthA = 0, depthB = 0, depthError = 0, depthMagnitudeB = 0;
};

TileSums tileSums(const Field& a, const Field& b, int k, int s) {
  constexpr int ni = gpu::PC_IRRADIANCE_TEXELS, nd = gpu::PC_DEPTH_TEXELS;
  const gpu::CascadeDesc& c = b.cascade(k);
  TileSums t;
  const glm::ivec2 oi = gpu::pcAtlasTileOrigin(c, s, ni + 2);
  for (int y = 1; y <= ni; ++y) {
    for (int x = 1; x <= ni; ++x) {
      const float* ta = a.irradiance.at(oi.x + x, oi.y + y);
      const float* tb = b.irradiance.at(oi.x + x, oi.y + y);
      const glm::vec3 ea = gpu::pcDecodeIrradiance(glm::vec3(ta[0], ta[1], ta[2]));
      const glm::vec3 eb = gpu::pcDecodeIrradiance(glm::vec3(tb[0], tb[1], tb[2]));
      for (int ch = 0; ch < 3; ++ch) {
        t.irradianceA += ea[ch];
        t.irradianceB += eb[ch];
        t.irradianceError += std::abs(double(ea[ch]) - eb[ch]);
        t.irradianceMagnitudeB += std::abs(double(eb[ch]));
      }
    }
  }
  const glm::ivec2 od = gpu::pcAtlasTileOrigin(c, s, nd + 2);
  for (int y = 1; y <= nd; ++y) {
    for (int x = 1; x <= nd; ++x) {
      const double da = a.depth.at(od.x + x, od.y + y)[0], db = b.depth.at(od.x + x, od.y + y)[0];
      t.depthA += da;
      t.depthB += db;
      t.depthError += std::abs(da - db);
      t.depthMagnitudeB += std::abs(db);
    }
  }
  return t;
}

ProbeDifference describe(const Field& a, const Field& b, int k, int s) {
  constexpr int ni = gpu::PC_IRRADIANCE_TEXELS, nd = gpu::PC_DEPTH_TEXELS;
  const TileSums t = tileSums(a, b, k, s);
  ProbeDifference p;
  p.cascade = k;
  p.slot = s;
  p.positionA = a.probePosition(k, s);
  p.positionB = b.probePosition(k, s);
  p.stateA = a.probe(k, s).state;
  p.stateB = b.probe(k, s).state;
  p.irradianceA = t.irradianceA / (3.0 * ni * ni);
  p.irradianceB = t.irradianceB / (3.0 * ni * ni);
  p.depthA = t.depthA / double(nd * nd);
  p.depthB = t.depthB / double(nd * nd);
  p.irradianceError = t.irradianceError;
  p.depthError = t.depthError;
  return p;
}

}  // namespace

FieldDifference compareFields(const Field& a, const Field& b) {
  FieldDifference d;
  double irrNum = 0, irrDen = 0, depNum = 0, depDen = 0;
  for (int k = 0; k < b.cascadeCount() && k < a.cascadeCount(); ++k) {
    const gpu::CascadeDesc& c = b.cascade(k);
    for (int s = 0; s < gpu::pcSlotCount(c); ++s) {
      if (!gpu::pcSlotValid(c, s)) continue;
      const int sa = a.probe(k, s).state, sb = b.probe(k, s).state;
      if (sa != sb) ++d.stateMismatches;
      if (sa != gpu::PC_PROBE_ACTIVE || sb != gpu::PC_PROBE_ACTIVE) continue;
      ++d.probes;
      const TileSums t = tileSums(a, b, k, s);
      irrNum += t.irradianceError;
      irrDen += t.irradianceMagnitudeB;
      depNum += t.depthError;
      depDen += t.depthMagnitudeB;
    }
  }
  d.irradiance = irrDen > 0 ? irrNum / irrDen : 0;
  d.depth = depDen > 0 ? depNum / depDen : 0;
  return d;
}

std::vector<ProbeDifference> largestProbeDifferences(const Field& a, const Field& b, int count) {
  std::vector<ProbeDifference> active, states;
  for (int k = 0; k < b.cascadeCount() && k < a.cascadeCount(); ++k) {
    const gpu::CascadeDesc& c = b.cascade(k);
    for (int s = 0; s < gpu::pcSlotCount(c); ++s) {
      if (!gpu::pcSlotValid(c, s)) continue;
      const int sa = a.probe(k, s).state, sb = b.probe(k, s).state;
      if (sa != sb)
        states.push_back(describe(a, b, k, s));
      else if (sa == gpu::PC_PROBE_ACTIVE)
        active.push_back(describe(a, b, k, s));
    }
  }
  auto largest = [&](double ProbeDifference::*error) {
    std::vector<ProbeDifference> sorted = active;
    const std::size_t n = std::min(sorted.size(), std::size_t(std::max(count, 0)));
    std::partial_sort(
        sorted.begin(), sorted.begin() + std::ptrdiff_t(n), sorted.end(),
        [&](const ProbeDifference& x, const ProbeDifference& y) { return x.*error > y.*error; });
    sorted.resize(n);
    return sorted;
  };
  std::vector<ProbeDifference> out = largest(&ProbeDifference::irradianceError);
  const std::vector<ProbeDifference> depth = largest(&ProbeDifference::depthError);
  out.insert(out.end(), depth.begin(), depth.end());
  out.insert(out.end(), states.begin(), states.end());
  return out;
}

}  // namespace pc
