#include "field_compare.h"

#include <cmath>

#include "../shaders/interop/probe_update.h"

namespace pc {

FieldDifference compareFields(const Field& a, const Field& b) {
  FieldDifference d;
  double irrNum = 0, irrDen = 0, depNum = 0, depDen = 0;
  constexpr int ni = gpu::PC_IRRADIANCE_TEXELS, nd = gpu::PC_DEPTH_TEXELS;
  for (int k = 0; k < b.cascadeCount() && k < a.cascadeCount(); ++k) {
    const gpu::CascadeDesc& c = b.cascade(k);
    for (int s = 0; s < gpu::pcSlotCount(c); ++s) {
      if (!gpu::pcSlotValid(c, s)) continue;
      const int sa = a.probe(k, s).state, sb = b.probe(k, s).state;
      if (sa != sb) ++d.stateMismatches;
      if (sa != gpu::PC_PROBE_ACTIVE || sb != gpu::PC_PROBE_ACTIVE) continue;
      ++d.probes;
      const glm::ivec2 oi = gpu::pcAtlasTileOrigin(c, s, ni + 2);
      for (int y = 1; y <= ni; ++y) {
        for (int x = 1; x <= ni; ++x) {
          const float* ta = a.irradiance.at(oi.x + x, oi.y + y);
          const float* tb = b.irradiance.at(oi.x + x, oi.y + y);
          const glm::vec3 ea = gpu::pcDecodeIrradiance(glm::vec3(ta[0], ta[1], ta[2]));
          const glm::vec3 eb = gpu::pcDecodeIrradiance(glm::vec3(tb[0], tb[1], tb[2]));
          for (int ch = 0; ch < 3; ++ch) {
            irrNum += std::abs(double(ea[ch]) - eb[ch]);
            irrDen += std::abs(double(eb[ch]));
          }
        }
      }
      const glm::ivec2 od = gpu::pcAtlasTileOrigin(c, s, nd + 2);
      for (int y = 1; y <= nd; ++y) {
        for (int x = 1; x <= nd; ++x) {
          depNum += std::abs(double(a.depth.at(od.x + x, od.y + y)[0]) - b.depth.at(od.x + x, od.y + y)[0]);
          depDen += std::abs(double(b.depth.at(od.x + x, od.y + y)[0]));
        }
      }
    }
  }
  d.irradiance = irrDen > 0 ? irrNum / irrDen : 0;
  d.depth = depDen > 0 ? depNum / depDen : 0;
  return d;
}

}  // namespace pc
