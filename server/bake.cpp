#include "bake.h"

#include <algorithm>
#include <chrono>

namespace pc {

void restartHistory(Field& field) {
  for (ProbeRecord& p : field.probes) p.updates = std::min<std::uint32_t>(p.updates, 1);
}

// Each cascade's hysteresis (its volume's own, or the field's), or all set to one value.
std::vector<float> cascadeHysteresis(const Field& field) {
  std::vector<float> out;
  for (int k = 0; k < field.cascadeCount(); ++k) out.push_back(field.cascade(k).hysteresis);
  return out;
}
void setCascadeHysteresis(Field& field, const std::vector<float>& values) {
  for (int k = 0; k < field.cascadeCount(); ++k) field.desc.cascades[k].hysteresis = values[k];
}

Result<BakeStats> bakeField(Field& field, Tracer& tracer, const BakeOptions& options) {
  BakeStats stats;
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<float> hysteresis = cascadeHysteresis(field);
  const std::vector<float> converging(hysteresis.size(), options.convergeHysteresis);
  const int converge =
      std::clamp(int(options.updates * options.convergeFraction), 0, options.updates);
  UpdateRequest request;
  request.probes = allProbes(field);
  request.shading = options.shading;
  for (int i = 0; i < options.updates; ++i) {
    if (i == 0 && converge > 0) setCascadeHysteresis(field, converging);
    if (i == converge) {
      setCascadeHysteresis(field, hysteresis);
      restartHistory(field);
    }
    request.rotationSeed = options.seed * std::uint32_t(options.updates) + std::uint32_t(i);
    Result<UpdateStats> u = tracer.update(field, request);
    if (!u) {
      setCascadeHysteresis(field, hysteresis);
      return u.error();
    }
    stats.probeRays += u->probeRays;
    stats.shadowRays += u->shadowRays;
    stats.traceMs += u->traceMs;
    stats.blendMs += u->blendMs;
    ++stats.updates;
    if (options.progress && !options.progress(i + 1, options.updates)) {
      stats.stopped = i + 1 < options.updates;
      break;
    }
  }
  setCascadeHysteresis(field, hysteresis);
  stats.ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return stats;
}

}  // namespace pc
