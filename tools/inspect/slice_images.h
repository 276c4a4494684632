// PNGs of one horizontal slice of a cascade's probes: their irradiance, depth and occlusion
// tiles laid out as a grid in x (columns) and z (rows), and a map of their states.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "common/field.h"
#include "common/result.h"

namespace pc::inspect {

struct SliceOptions {
  int scale = 4;          // image pixels per atlas texel (and per state-map texel)
  float exposure = 1.0f;  // applied to irradiance / pi before the shared tone curve
};

// The state map's colour of a probe state (8-bit sRGB).
struct StateColour {
  unsigned char r, g, b;
};
StateColour stateColour(int state);

// Writes cascade<k>_{irradiance,depth,occlusion,states}_y<y>.png into `dir` for the slice of
// logical probe layer y (0 <= y < counts.y) of cascade k. Returns the paths written.
Result<std::vector<std::filesystem::path>> writeSliceImages(const Field& field, int k, int y,
                                                            const std::filesystem::path& dir,
                                                            const SliceOptions& options);

}  // namespace pc::inspect
