// What probecast-inspect reports about a baked field: per cascade, its probes by state, how far
// relocation moved them, its brick versions and what the atlas tiles of its probes hold.
#pragma once

#include <array>
#include <cstdint>
#include <glm/glm.hpp>
#include <vector>

#include "common/field.h"

namespace pc::inspect {

struct CascadeSummary {
  int probes = 0;  // real probes, not the padding slots of bricks past the grid's edge
  std::array<int, 4> byState{};  // indexed by PC_PROBE_ACTIVE .. PC_PROBE_UNINITIALIZED
  double offsetMean = 0.0;       // relocation offset length, in units of the spacing
  double offsetMax = 0.0;
  std::uint64_t versionMin = 0, versionMax = 0;
  int bricksAtVersionZero = 0;
  // Over the interior texels of the probes that hold data (active or sleeping: the states a
  // renderer samples). The atlases of other probes hold nothing a renderer reads.
  int probesWithData = 0;
  glm::dvec3 irradianceMean{0.0};  // decoded (encoded^PC_IRRADIANCE_GAMMA), W/m^2
  glm::dvec3 irradianceMax{0.0};   // per channel
  double depthMean = 0.0;          // mean hit distance, world units
  double occlusionMean = 0.0;
};

CascadeSummary summarizeCascade(const Field& field, int k);

// Whether a probe in `state` holds data a renderer samples.
bool holdsData(int state);

// The lower-case name of a probe state ("active", "sleeping", "inside", "uninitialized").
const char* stateName(int state);

}  // namespace pc::inspect
