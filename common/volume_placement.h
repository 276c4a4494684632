// Probe cascades placed from a scene's geometry, for scenes whose sidecar names none, and a
// check of a user's spacing against the geometry. DDGI needs probes spaced at the scale of the
// scene's open spaces (a few probes across a room, a corridor, the gap under a table): coarser
// and light leaks through walls and misses recesses; much finer and the bake's cost grows with
// the cube of the ratio for little gain. The bounds alone do not give that scale (a small room
// and a garden in one file, a long tunnel), so the geometry is measured: the surfaces are
// voxelized, and the distance from every point of enclosed free space to its nearest surface
// is taken (free space enclosed means: with surfaces below and on most sides, and those
// surfaces facing it, so neither the sky above a level nor the inside of solid walls counts).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "scene.h"

namespace pc {

struct GeometryScale {
  bool valid = false;        // false: no geometry, or no enclosed free space was found
  float voxel = 0.0f;        // edge of the analysis voxels (world units)
  float freeSpace = 0.0f;    // median distance from enclosed free space to the nearest surface
  float edgeLength = 0.0f;   // median triangle edge length, area-weighted (reported only)
  glm::vec3 levelMin{0.0f};  // box of the enclosed free space: where the finest probes go
  glm::vec3 levelMax{0.0f};
  double enclosedShare = 0.0;  // share of the bounds' empty voxels that are enclosed free space
};

// Measures the scene at time 0 (instances at their initial transforms; cut-outs count as
// solid). `maxVoxels` bounds the analysis grid.
GeometryScale measureGeometry(const Scene& scene, std::size_t maxVoxels = 2'000'000);

// The spacing the geometry asks for: kSpacingPerFreeSpace times the median free-space distance.
// In a closed cube of side L that distance is about 0.10 L, so the cube gets about 8 probes
// across: the density the hand-written sidecars of the shared rooms use (0.25 in a 2 m box).
inline constexpr float kSpacingPerFreeSpace = 1.2f;
float suggestedSpacing(const GeometryScale& scale);

struct VolumePlan {
  std::vector<ProbeVolume> volumes;  // finest first; defaultVolumes(scene) where !scale.valid
  GeometryScale scale;
  float wantedSpacing = 0.0f;  // suggestedSpacing(scale), before the probe budget
  int probes = 0;
};
// Cascades from the geometry: the finest over the enclosed free space at the suggested
// spacing (widened until it holds at most `probeBudget` probes; then, at that spacing, over
// the whole bounds or past the level by up to half its extent, as far as the budget holds),
// and where the scene reaches
// past that box, a coarser one at twice the spacing (or more, within a quarter of the budget)
// over the whole bounds.
VolumePlan autoVolumes(const Scene& scene, int probeBudget = 16384);

// Where `volumes` (finest first) are coarser than twice the suggested spacing: one line naming
// the scene, its spacing and the suggested one. Nothing when the spacing fits or the scale is
// unknown.
std::optional<std::string> spacingAdvice(const Scene& scene,
                                         const std::vector<ProbeVolume>& volumes,
                                         const GeometryScale& scale);

// The cascades a bake or server uses for `scene`: its sidecar's volumes (with spacingAdvice
// logged as a warning where it applies), else autoVolumes, logged with the spacing chosen.
// `automatic` ignores the sidecar's volumes (to compare the two).
std::vector<ProbeVolume> sceneVolumes(const Scene& scene, bool automatic = false);

// One line describing a plan, for logs and benchmark tables.
std::string describePlan(const Scene& scene, const VolumePlan& plan);

}  // namespace pc
