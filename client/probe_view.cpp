#include "probe_view.h"

#include <limits>

namespace pc::client {

std::optional<ProbeViewMode> parseProbeViewMode(std::string_view name) {
  if (name == "off") return ProbeViewMode::Off;
  if (name == "irradiance") return ProbeViewMode::Irradiance;
  if (name == "state") return ProbeViewMode::State;
  return std::nullopt;
}

const char* probeViewModeName(ProbeViewMode mode) {
  switch (mode) {
    case ProbeViewMode::Off:
      return "off";
    case ProbeViewMode::Irradiance:
      return "irradiance";
    case ProbeViewMode::State:
      return "state";
  }
  return "?";
}

int nextProbeViewCascade(int cascade, int cascadeCount) {
  if (cascadeCount <= 0) return -1;
  return cascade + 1 >= cascadeCount ? -1 : cascade + 1;
}

std::string probeViewStatus(const ProbeViewSettings& settings) {
  std::string line = settings.mode == ProbeViewMode::State ? "PROBES STATE" : "PROBES IRRADIANCE";
  line += settings.cascade < 0 ? "  CASCADE ALL" : "  CASCADE " + std::to_string(settings.cascade);
  if (settings.offsets) line += "  LINES";
  return line;
}

const std::vector<float>& BrickFlash::update(const FieldMirror& mirror, double now) {
  const std::vector<std::vector<std::uint64_t>> versions = mirror.brickVersions();
  const bool sameLayout = versions.size() == seen_.size() && [&] {
    for (std::size_t k = 0; k < versions.size(); ++k)
      if (versions[k].size() != seen_[k].size()) return false;
    return true;
  }();
  if (!sameLayout) {
    // A new field (or the first look at one): its versions are the baseline, nothing flashes.
    seen_ = versions;
    changed_.assign(versions.size(), {});
    for (std::size_t k = 0; k < versions.size(); ++k)
      changed_[k].assign(versions[k].size(), -std::numeric_limits<double>::infinity());
  }
  flash_.clear();
  base_ = gpu::ivec4(0);
  for (std::size_t k = 0; k < versions.size(); ++k) {
    if (k < std::size_t(gpu::PC_MAX_CASCADES)) base_[int(k)] = int(flash_.size());
    for (std::size_t b = 0; b < versions[k].size(); ++b) {
      if (versions[k][b] != seen_[k][b]) {
        seen_[k][b] = versions[k][b];
        changed_[k][b] = now;
      }
      flash_.push_back(gpu::pcProbeFlash(float(now - changed_[k][b])));
    }
  }
  return flash_;
}

}  // namespace pc::client
