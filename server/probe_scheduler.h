// Chooses the probes to update each tick: active and new probes every tick, sleeping and
// inside-geometry probes now and then (staggered, so their cost spreads evenly), and under a
// budget, the stalest probes nearest a viewer first. Probes in the region of a runtime edit
// (prioritize) come before all of those, nearest the edit first, for their next few updates.
#pragma once

#include <cstdint>
#include <glm/glm.hpp>
#include <vector>

#include "common/scene_edits.h"
#include "probe_rest.h"
#include "tracer.h"

namespace pc {

struct SchedulerOptions {
  int sleepingPeriod = 8;  // ticks between updates of a sleeping probe
  int insidePeriod = 16;   // ticks between retries of a probe inside geometry
  int budget = 0;          // most probes per tick; 0: no limit
};

class ProbeScheduler {
 public:
  explicit ProbeScheduler(SchedulerOptions options = {}) : options_(options) {}
  // `viewers`: world positions of the viewers (empty: no preference). `weights` (empty: all 1;
  // else one per viewer, >= 1): a viewer of weight w counts as w times nearer, so under a
  // budget its surroundings come first in proportion to what its connect token allows.
  // `rest` (null: none rests): a resting probe is due every rest period only, all probes of a
  // brick in the same tick, so that the bricks of a still scene change one at a time.
  std::vector<ProbeRef> plan(const Field& field, std::uint64_t tick,
                             const std::vector<glm::vec3>& viewers = {},
                             const std::vector<float>& weights = {},
                             const ProbeRest* rest = nullptr);
  // Forces every probe into the next plan (scene cut, history reset).
  void resetAll() { lastUpdate_.clear(); }
  // Probes that start over (cascade k's slots that scrolled in, field_scroll.h): they count as
  // never updated, which ranks them before every probe traced before, nearest a viewer first.
  void forget(const Field& field, int k, const std::vector<int>& slots);
  // An edit changed the light within `regions`: the probes there, sleeping or not, come first
  // in each of their next kEditBoostUpdates plans (nearest a region's centre first), so that
  // the field around the change converges before anything else is refreshed.
  void prioritize(const Field& field, const std::vector<EditRegion>& regions);
  // Probes still to be updated first for an edit.
  std::size_t boostedProbes() const;

  static constexpr std::uint8_t kEditBoostUpdates = 16;

 private:
  SchedulerOptions options_;
  std::vector<std::uint64_t> lastUpdate_;  // per field-wide slot; 0 = never
  // Per field-wide slot: plans left at the front for an edit, and the distance to the nearest
  // edit's centre in the cascade's spacings.
  std::vector<std::uint8_t> boost_;
  std::vector<float> boostDistance_;
};

}  // namespace pc
