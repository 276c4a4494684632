// How far two fields of the same layout are apart: the figure the GPU and CPU backends are
// held to (tests, probecast-bench gpu-trace).
#pragma once

#include "../common/field.h"

namespace pc {

struct FieldDifference {
  // sum |a - b| / sum |b| over the interior texels of probes active in both fields: decoded
  // irradiance (all channels) and mean depth.
  double irradiance = 0, depth = 0;
  int probes = 0;           // active in both
  int stateMismatches = 0;  // real probes whose state differs
};

// `b` is the reference. The fields must share their layout (same volumes and settings).
FieldDifference compareFields(const Field& a, const Field& b);

}  // namespace pc
