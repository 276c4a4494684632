#include "probe_scheduler.h"

#include <algorithm>
#include <limits>

namespace pc {

std::vector<ProbeRef> ProbeScheduler::plan(const Field& field, std::uint64_t tick,
                                           const std::vector<glm::vec3>& viewers,
                                           const std::vector<float>& weights) {
  if (lastUpdate_.size() != field.probes.size()) lastUpdate_.assign(field.probes.size(), 0);
  struct Candidate {
    ProbeRef ref;
    float priority;
  };
  std::vector<Candidate> candidates;
  for (int k = 0; k < field.cascadeCount(); ++k) {
    const gpu::CascadeDesc& c = field.cascade(k);
    for (int s = 0; s < gpu::pcSlotCount(c); ++s) {
      if (!gpu::pcSlotValid(c, s)) continue;
      const std::size_t index = std::size_t(c.firstProbe) + s;
      const ProbeRecord& r = field.probes[index];
      const std::uint64_t last = lastUpdate_[index];
      const bool never = last == 0;
      int period = 1;
      if (r.state == gpu::PC_PROBE_SLEEPING) period = options_.sleepingPeriod;
      if (r.state == gpu::PC_PROBE_INSIDE) period = options_.insidePeriod;
      // Stagger periodic probes by slot so each tick takes an even share.
      const bool due =
          never || period <= 1 || (tick + std::uint64_t(s)) % std::uint64_t(period) == 0;
      if (!due) continue;
      float staleness = never ? 1e6f : float(tick - last);
      float distance = 0.0f;
      if (!viewers.empty()) {
        distance = std::numeric_limits<float>::max();
        glm::vec3 p = field.probePosition(k, s);
        for (std::size_t i = 0; i < viewers.size(); ++i) {
          const float weight = i < weights.size() ? std::max(1.0f, weights[i]) : 1.0f;
          distance = std::min(distance, glm::length(p - viewers[i]) / weight);
        }
      }
      candidates.push_back({{k, s}, staleness / (1.0f + distance / c.spacing)});
    }
  }
  if (options_.budget > 0 && int(candidates.size()) > options_.budget) {
    std::nth_element(
        candidates.begin(), candidates.begin() + options_.budget, candidates.end(),
        [](const Candidate& a, const Candidate& b) { return a.priority > b.priority; });
    candidates.resize(options_.budget);
  }
  std::vector<ProbeRef> plan;
  plan.reserve(candidates.size());
  for (const Candidate& c : candidates) {
    plan.push_back(c.ref);
    lastUpdate_[std::size_t(field.cascade(c.ref.cascade).firstProbe) + c.ref.slot] =
        std::max<std::uint64_t>(tick, 1);
  }
  // Probes sorted by cascade and slot trace with better memory locality.
  std::sort(plan.begin(), plan.end(), [](ProbeRef a, ProbeRef b) {
    return a.cascade != b.cascade ? a.cascade < b.cascade : a.slot < b.slot;
  });
  return plan;
}

}  // namespace pc
