#include "probe_rest.h"

#include <algorithm>
#include <cmath>

namespace pc {

float probeMeanIrradiance(const Field& field, int cascade, int slot) {
  constexpr int n = gpu::PC_IRRADIANCE_TEXELS;
  const glm::ivec2 o = gpu::pcAtlasTileOrigin(field.cascade(cascade), slot, n + 2) + glm::ivec2(1);
  double sum = 0;
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      const float* t = field.irradiance.at(o.x + x, o.y + y);
      sum += double(t[0]) + double(t[1]) + double(t[2]);
    }
  }
  return float(sum / (3.0 * n * n));
}

void ProbeRest::wakeAll() {
  for (Probe& p : state_) {
    p.signedSum = p.absSum = 0.0f;
    p.samples = 0;
    p.resting = false;
  }
  resting_ = 0;
}

void ProbeRest::wake(std::size_t probe) {
  if (probe >= state_.size()) return;
  Probe& p = state_[probe];
  if (p.resting) --resting_;
  p = Probe{};
}

void ProbeRest::observe(const Field& field, std::span<const ProbeRef> updated) {
  if (!options_.enabled) return;
  if (state_.size() != field.probes.size()) {
    state_.assign(field.probes.size(), Probe{});
    resting_ = 0;
  }
  const float keep = 1.0f - 1.0f / float(std::max(options_.window, 1));
  for (const ProbeRef& ref : updated) {
    Probe& p = state_[std::size_t(field.cascade(ref.cascade).firstProbe) + std::size_t(ref.slot)];
    const float mean = probeMeanIrradiance(field, ref.cascade, ref.slot);
    if (p.mean >= 0.0f) {
      // Sums over about the last `window` updates (exponentially weighted, so no history of
      // changes is stored per probe).
      const float change = mean - p.mean;
      p.signedSum = keep * p.signedSum + change;
      p.absSum = keep * p.absSum + std::abs(change);
      if (p.samples < 0xFFFF) ++p.samples;
    }
    p.mean = mean;
    const bool measured = p.samples >= options_.window;
    const bool negligible = p.absSum <= options_.negligible * std::max(mean, 1.0f);
    const float drift = std::abs(p.signedSum);
    const bool rest =
        measured &&
        (negligible || drift <= (p.resting ? options_.wakeDrift : options_.drift) * p.absSum);
    if (rest != p.resting) {
      p.resting = rest;
      resting_ += rest ? 1 : std::size_t(-1);
    }
  }
}

}  // namespace pc
