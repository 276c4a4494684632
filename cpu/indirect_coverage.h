// Which pixels of a camera view get no indirect light from a field: the check behind "never
// black". Each pixel's centre ray finds its surface, and the field is sampled there as the
// probe-lit render and the client sample it (sampleFieldOrAmbient); a surface that reflects
// light (albedo above zero) whose indirect irradiance comes out zero is counted.
#pragma once

#include <optional>

#include "../common/field.h"
#include "../common/result.h"
#include "../common/scene.h"
#include "embree_scene.h"

namespace pc {

struct IndirectCoverage {
  int surfacePixels = 0;  // pixels whose centre ray hits a surface with albedo above zero
  int blackPixels = 0;    // ... of which the field gives no indirect light at all
  // ... of which no probe near the surface holds data (the field's coverage is 0 before the
  // ambient term stands in)
  int uncoveredPixels = 0;
};

// `flags`: PC_SAMPLE_* (PC_SAMPLE_NO_FALLBACK shows what the fallback saves).
IndirectCoverage measureIndirectCoverage(const EmbreeScene& scene, const Field& field,
                                         const Camera& camera, int width, int height, int flags);

// Builds the Embree scene at animation time `time` and measures `explicitCamera` when set, else
// the scene's camera `cameraIndex`.
Result<IndirectCoverage> measureIndirectCoverage(const Scene& scene, const Field& field,
                                                 const std::optional<Camera>& explicitCamera,
                                                 int cameraIndex, int width, int height, int flags,
                                                 double time = 0.0);

}  // namespace pc
