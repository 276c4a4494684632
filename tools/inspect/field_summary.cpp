#include "tools/inspect/field_summary.h"

#include <algorithm>
#include <limits>

#include "shaders/interop/probe_update.h"

namespace pc::inspect {

using namespace pc::gpu;

namespace {

// Calls fn(texel) for every interior texel of a slot's tile in `atlas` (tiles of n interior
// texels and a 1-texel border, addressed as the renderers address them).
template <typename Fn>
void forEachInteriorTexel(const Atlas& atlas, const CascadeDesc& c, int slot, int n, Fn&& fn) {
  const ivec2 origin = pcAtlasTileOrigin(c, slot, n + 2);
  for (int ty = 0; ty < n; ++ty) {
    for (int tx = 0; tx < n; ++tx) fn(atlas.at(origin.x + 1 + tx, origin.y + 1 + ty));
  }
}

}  // namespace

bool holdsData(int state) { return state == PC_PROBE_ACTIVE || state == PC_PROBE_SLEEPING; }

const char* stateName(int state) {
  switch (state) {
    case PC_PROBE_ACTIVE:
      return "active";
    case PC_PROBE_SLEEPING:
      return "sleeping";
    case PC_PROBE_INSIDE:
      return "inside";
    case PC_PROBE_UNINITIALIZED:
      return "uninitialized";
  }
  return "unknown";
}

CascadeSummary summarizeCascade(const Field& field, int k) {
  const CascadeDesc& c = field.cascade(k);
  CascadeSummary s;
  double offsetSum = 0.0, depthSum = 0.0, occlusionSum = 0.0;
  glm::dvec3 irradianceSum(0.0);
  for (int slot = 0; slot < pcSlotCount(c); ++slot) {
    if (!pcSlotValid(c, slot)) continue;
    const ProbeRecord& p = field.probe(k, slot);
    ++s.probes;
    if (p.state >= 0 && p.state < int(s.byState.size())) ++s.byState[std::size_t(p.state)];
    const double offset = double(glm::length(p.offset)) / double(c.spacing);
    offsetSum += offset;
    s.offsetMax = std::max(s.offsetMax, offset);
    if (!holdsData(p.state)) continue;
    ++s.probesWithData;
    forEachInteriorTexel(field.irradiance, c, slot, PC_IRRADIANCE_TEXELS, [&](const float* t) {
      const glm::dvec3 e(pcDecodeIrradiance(vec3(t[0], t[1], t[2])));
      irradianceSum += e;
      s.irradianceMax = glm::max(s.irradianceMax, e);
    });
    forEachInteriorTexel(field.depth, c, slot, PC_DEPTH_TEXELS,
                         [&](const float* t) { depthSum += t[0]; });
    forEachInteriorTexel(field.occlusion, c, slot, PC_OCCLUSION_TEXELS,
                         [&](const float* t) { occlusionSum += t[0]; });
  }
  if (s.probes > 0) s.offsetMean = offsetSum / s.probes;
  if (s.probesWithData > 0) {
    const auto texels = [&](int n) { return double(s.probesWithData) * n * n; };
    s.irradianceMean = irradianceSum / texels(PC_IRRADIANCE_TEXELS);
    s.depthMean = depthSum / texels(PC_DEPTH_TEXELS);
    s.occlusionMean = occlusionSum / texels(PC_OCCLUSION_TEXELS);
  }

  const std::vector<std::uint64_t>& versions = field.brickVersions[std::size_t(k)];
  if (!versions.empty()) {
    const auto [lo, hi] = std::minmax_element(versions.begin(), versions.end());
    s.versionMin = *lo;
    s.versionMax = *hi;
    s.bricksAtVersionZero = int(std::count(versions.begin(), versions.end(), 0u));
  }
  return s;
}

}  // namespace pc::inspect
