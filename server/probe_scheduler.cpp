#include "probe_scheduler.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace pc {

namespace {
// Priority of a probe near an edit, over one viewer-distance unit; staleness is at most 1e6.
constexpr float kBoostPriority = 1e12f;
}  // namespace

std::vector<ProbeRef> ProbeScheduler::plan(const Field& field, std::uint64_t tick,
                                           const std::vector<glm::vec3>& viewers,
                                           const std::vector<float>& weights,
                                           const ProbeRest* rest) {
  if (lastUpdate_.size() != field.probes.size()) lastUpdate_.assign(field.probes.size(), 0);
  if (boost_.size() != field.probes.size()) {
    boost_.assign(field.probes.size(), 0);
    boostDistance_.assign(field.probes.size(), 0.0f);
  }
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
      // Stagger periodic probes by slot so each tick takes an even share; resting probes by
      // brick, so that a still scene's bricks change one at a time.
      std::uint64_t phase = std::uint64_t(s);
      if (rest && rest->resting(index) && rest->options().period > period) {
        period = rest->options().period;
        phase = std::uint64_t(s / gpu::PC_PROBES_PER_BRICK) * 7919u + std::uint64_t(k) * 104729u;
      }
      const bool boosted = boost_[index] > 0;
      const bool due =
          never || boosted || period <= 1 || (tick + phase) % std::uint64_t(period) == 0;
      if (!due) continue;
      if (boosted) {
        // Above any staleness (at most 1e6 for a probe never updated): an edit's region first.
        candidates.push_back({{k, s}, kBoostPriority / (1.0f + boostDistance_[index])});
        continue;
      }
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
    const std::size_t index = std::size_t(field.cascade(c.ref.cascade).firstProbe) + c.ref.slot;
    lastUpdate_[index] = std::max<std::uint64_t>(tick, 1);
    if (boost_[index] > 0) --boost_[index];
  }
  // Probes sorted by cascade and slot trace with better memory locality.
  std::sort(plan.begin(), plan.end(), [](ProbeRef a, ProbeRef b) {
    return a.cascade != b.cascade ? a.cascade < b.cascade : a.slot < b.slot;
  });
  return plan;
}

void ProbeScheduler::forget(const Field& field, int k, const std::vector<int>& slots) {
  const std::size_t first = std::size_t(field.cascade(k).firstProbe);
  for (int s : slots) {
    const std::size_t index = first + std::size_t(s);
    if (index < lastUpdate_.size()) lastUpdate_[index] = 0;
    if (index < boost_.size()) boost_[index] = 0;
  }
}

void ProbeScheduler::prioritize(const Field& field, const std::vector<EditRegion>& regions) {
  if (boost_.size() != field.probes.size()) {
    boost_.assign(field.probes.size(), 0);
    boostDistance_.assign(field.probes.size(), 0.0f);
  }
  for (int k = 0; k < field.cascadeCount(); ++k) {
    const gpu::CascadeDesc& c = field.cascade(k);
    for (int s = 0; s < gpu::pcSlotCount(c); ++s) {
      if (!gpu::pcSlotValid(c, s)) continue;
      const glm::vec3 p = field.probePosition(k, s);
      float nearest = std::numeric_limits<float>::infinity();
      for (const EditRegion& r : regions) {
        const float d = glm::length(p - r.center);
        if (d <= r.radius) nearest = std::min(nearest, d);  // false for NaN
      }
      if (!std::isfinite(nearest)) continue;
      const std::size_t index = std::size_t(c.firstProbe) + s;
      const float distance = nearest / c.spacing;
      // A probe in two edits' regions keeps the nearer one's rank.
      boostDistance_[index] =
          boost_[index] > 0 ? std::min(boostDistance_[index], distance) : distance;
      boost_[index] = kEditBoostUpdates;
    }
  }
}

std::size_t ProbeScheduler::boostedProbes() const {
  return std::size_t(std::count_if(boost_.begin(), boost_.end(), [](auto b) { return b > 0; }));
}

}  // namespace pc
