// The split-sum table of shaders/interop/specular_probe.h: the GGX lobe's directional albedo
// split by Schlick's Fresnel into a scale A (on F0) and a bias B, over N.V x roughness,
// computed from brdf.h's own terms by quadrature when a renderer first asks for it.
#pragma once

#include <array>
#include <glm/glm.hpp>

#include "../shaders/interop/specular_probe.h"

namespace pc {

using SplitSumTable = std::array<glm::vec2, gpu::PC_SPLIT_SUM_ENTRIES>;

// (A, B) at N.V and roughness: the integrals over the hemisphere of L of
// D V_smith (1 - Fc) N.L and D V_smith Fc N.L, Fc = (1 - V.H)^5, by `samples` half-vectors
// from the distribution of visible normals on a Hammersley set.
glm::vec2 integrateSplitSum(float NdotV, float roughness, int samples);

// The table (PC_SPLIT_SUM_SIZE^2 entries, entry i + size * j), computed once per process.
const SplitSumTable& splitSumTable();

// Bilinear lookup at (N.V, roughness), as the client's shader reads its uploaded copy.
glm::vec2 lookupSplitSum(const SplitSumTable& table, float NdotV, float roughness);

}  // namespace pc
