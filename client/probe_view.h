// The probe debug view's settings (what the window's keys and the command line choose) and
// the per-brick flash that marks bricks whose version just changed. The drawing itself is
// client_probe_view.comp over the layout of shaders/interop/probe_view.h.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "field_mirror.h"
#include "shaders/interop/probe_view.h"

namespace pc::client {

enum class ProbeViewMode { Off, Irradiance, State };
// "off", "irradiance" or "state" (command lines).
std::optional<ProbeViewMode> parseProbeViewMode(std::string_view name);
const char* probeViewModeName(ProbeViewMode mode);

struct ProbeViewSettings {
  ProbeViewMode mode = ProbeViewMode::Off;
  int cascade = -1;     // the only cascade drawn; -1: all
  bool offsets = true;  // relocation lines from grid points to relocated probes
  bool on() const { return mode != ProbeViewMode::Off; }
};

// The next cascade choice after `cascade` when cycling all -> 0 -> 1 -> ... -> all.
int nextProbeViewCascade(int cascade, int cascadeCount);
// One overlay line saying what the view shows ("PROBES STATE  CASCADE ALL  LINES").
std::string probeViewStatus(const ProbeViewSettings& settings);

// When each brick's version last changed, and from that each brick's flash (1 just changed,
// fading to 0 over PC_PROBE_VIEW_FLASH_SECONDS). The versions first seen are the baseline: a
// field that was already there when the view started does not flash all at once.
class BrickFlash {
 public:
  // Compares the mirror's versions with those last seen at time `now` (seconds, any steady
  // clock) and returns the flash of every brick, cascades one after another.
  const std::vector<float>& update(const FieldMirror& mirror, double now);
  // Index of each cascade's first brick in update's result.
  gpu::ivec4 brickBase() const { return base_; }

 private:
  std::vector<std::vector<std::uint64_t>> seen_;
  std::vector<std::vector<double>> changed_;  // when each brick's version last changed
  std::vector<float> flash_;
  gpu::ivec4 base_{0};
};

}  // namespace pc::client
