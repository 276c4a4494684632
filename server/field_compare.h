// How far two fields of the same layout are apart: the figure the GPU and CPU backends are
// held to (tests, probecast-bench gpu-trace).
#pragma once

#include <vector>

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

// One probe of two fields side by side: where the backends part, for finding out why.
struct ProbeDifference {
  int cascade = 0, slot = 0;
  glm::vec3 positionA{0.0f}, positionB{0.0f};  // world, relocated
  int stateA = 0, stateB = 0;
  // Mean decoded irradiance over the tile's interior texels and channels, and mean depth.
  double irradianceA = 0, irradianceB = 0, depthA = 0, depthB = 0;
  // What the probe adds to compareFields' numerators: sum |a - b| over the interior texels
  // (and channels) of decoded irradiance and of mean depth.
  double irradianceError = 0, depthError = 0;
};

// The `count` probes active in both that add most to compareFields' irradiance numerator,
// largest first; then the `count` that add most to its depth numerator; then every real probe
// whose state differs.
std::vector<ProbeDifference> largestProbeDifferences(const Field& a, const Field& b, int count);

}  // namespace pc
