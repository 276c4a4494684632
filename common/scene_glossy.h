// Glossy variants of McGuire's Cornell box (CornellBox-Original.obj) for the specular
// measures (probecast-bench specular, tests/test_specular_probe.cpp): the scene's own sidecar
// plus a materials[] override (docs/SCENES.md) that makes the floor a dielectric and both
// boxes metals of one roughness, written where the caller says.
#pragma once

#include <filesystem>

#include "result.h"

namespace pc {

// The materials the variant makes glossy, and how: name, metallic.
struct GlossyOverride {
  const char* material;
  float metallic;
};
inline constexpr GlossyOverride kGlossyCornellMaterials[] = {
    {"floor", 0.0f}, {"tallBox", 1.0f}, {"shortBox", 1.0f}};

// Writes `out`: the JSON of `baseSidecar` with materials[] set to kGlossyCornellMaterials at
// `roughness`. Errors name the file that could not be read, parsed or written.
Status writeGlossyCornellSidecar(const std::filesystem::path& baseSidecar, float roughness,
                                 const std::filesystem::path& out);

}  // namespace pc
