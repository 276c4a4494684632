// Converging a field from nothing, for baked files and for measurements that need a
// converged field. Two phases: a short hysteresis first, so the multi-bounce recurrence
// (each update adds a bounce) settles in tens of updates rather than hundreds; then the
// configured hysteresis with a fresh running mean, which averages away the ray noise.
#pragma once

#include <cstdint>
#include <functional>

#include "tracer.h"

namespace pc {

struct BakeOptions {
  int updates = 96;
  float convergeFraction = 0.5f;  // share of updates in the short-hysteresis phase
  float convergeHysteresis = 0.5f;
  std::uint32_t seed = 1;  // rotation seeds are seed * updates + i
  int shading = kShadeDefault;
  // Called after each update; false stops the bake there (BakeStats::stopped).
  std::function<bool(int done, int total)> progress;
};

struct BakeStats {
  double ms = 0;
  std::uint64_t probeRays = 0, shadowRays = 0;
  int updates = 0;
  double traceMs = 0, blendMs = 0;
  bool stopped = false;  // the progress callback stopped the bake before its last update
};

// The tracer's Error where an update fails: the field is then as the last completed update
// left it, part way to converged.
Result<BakeStats> bakeField(Field& field, Tracer& tracer, const BakeOptions& options);

// Restarts every probe's running mean, keeping its current value as one sample.
void restartHistory(Field& field);

}  // namespace pc
