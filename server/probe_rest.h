// Probes at rest: once the scene stops changing, a probe whose irradiance has stopped moving is
// updated rarely (every RestOptions::period ticks, a whole brick at a time) instead of every
// tick, so a still scene costs little tracing and, since a brick changes only when one of its
// probes is updated, almost nothing to stream. Any change of the scene's state (a light, an
// instance, an emitter, an edit) wakes every probe for the next update.
//
// When has a probe stopped moving? Its blended irradiance follows the light with a lag
// (hysteresis), and ray noise moves it a little every update whatever the scene does. Neither a
// threshold on the change per update (it would depend on the noise, the hysteresis and the
// ray count) nor a fixed settling time (tens of updates at a hysteresis of 0.97) tells the two
// apart; the direction of the changes does. While a probe still converges, its mean irradiance
// moves one way update after update; once converged, the changes are noise and cancel. Over the
// last RestOptions::window updates of a probe, the signed changes of its mean irradiance summed
// against their magnitudes summed measure that drift: about 1 while it converges, about
// 1/sqrt(window) for noise alone. A probe rests once its drift is below RestOptions::drift (or
// its changes are negligible) with the scene unchanged meanwhile, and wakes where a refresh
// finds it drifting again (RestOptions::wakeDrift). This is the probe variability RTXGI
// measures per volume, made per probe and independent of the irradiance's scale.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "common/field.h"
#include "tracer.h"

namespace pc {

struct RestOptions {
  bool enabled = true;
  int period = 64;         // ticks between updates of a resting probe (staggered by brick)
  int window = 16;         // updates of a probe over which its drift is measured
  float drift = 0.5f;      // |sum of changes| / sum of |changes| below which a probe has settled
  float wakeDrift = 0.9f;  // ... and above which a resting probe wakes
  // Changes of the mean irradiance below this share of it (of 1 for a mean below 1, in the
  // atlas's encoded units) count as none: a dark probe's.
  float negligible = 1e-4f;
};

class ProbeRest {
 public:
  explicit ProbeRest(RestOptions options = {}) : options_(options) {}

  // The scene's state changed: every probe is awake, and its history of changes starts again.
  void wakeAll();
  // One probe (field-wide slot index) starts over: awake, no history of changes.
  void wake(std::size_t probe);
  // After an update: the probes it traced, read from the field they were blended into.
  void observe(const Field& field, std::span<const ProbeRef> updated);
  // A probe (field-wide slot index) rests: the scheduler leaves it to its period.
  bool resting(std::size_t probe) const {
    return options_.enabled && probe < state_.size() && state_[probe].resting;
  }
  std::size_t restingProbes() const { return resting_; }
  const RestOptions& options() const { return options_; }

 private:
  struct Probe {
    float mean = -1.0f;  // mean irradiance at the last update (< 0: none yet)
    float signedSum = 0.0f, absSum = 0.0f;
    std::uint16_t samples = 0;
    bool resting = false;
  };
  RestOptions options_;
  std::vector<Probe> state_;
  std::size_t resting_ = 0;
};

// Mean of a probe's irradiance texels (all channels, linear), the quantity ProbeRest follows.
float probeMeanIrradiance(const Field& field, int cascade, int slot);

}  // namespace pc
