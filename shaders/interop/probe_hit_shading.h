// The radiance a probe-ray hit sends back along the ray (toward the probe, V = -rayDir), once
// for every tracer that shades hits: the Embree update (server/embree_tracer.cpp) and the
// Vulkan shade pass that the ray-tracing and distance-field backends share
// (shaders/probe_shade.comp). A probe stores what the surfaces around it send toward it, so a
// hit must reflect as the material of brdf.h does, or the field holds a Lambert world that
// the reference path tracer and the client do not draw.
//
// Direct light: each light sample's irradiance times the whole BRDF for its direction
// (pcProbeHitLightWeight), so highlights of lights land in the probes where the reference
// has them and the energy is exact per sample.
//
// Indirect light, from the previous field: the diffuse part is exact, Lambert on the
// irradiance E about N times (1 - metallic) and what the dielectric coat's Fresnel at N.V
// leaves, as pcMaterialBrdf weighs it. The specular part is the split sum of
// specular_probe.h, S x (F0 A + B): (F0 A + B) is the lobe's directional albedo from the
// split-sum table, so the energy the lobe reflects is right; S, the light around the lobe, is
// read as the irradiance about the lobe's direction (pcSpecularDirection) over pi. That is the
// lobe's radiance for roughness 1 (where the GGX prefilter is the clamped cosine) and a
// blurred one below; a probe ray's hit needs energy more than sharpness, since the probe
// convolves what its rays bring back with the cosine once more. It costs one more field
// sample per glossy hit, not the six reads per probe of the client's exact band split
// (pcSampleFieldLit), which measured no closer to the reference (docs/BENCHMARKS.md).
//
// The diffuse weight is the coat's (1 - F(N.V)) of brdf.h, not (1 - directional albedo of the
// lobe): the field must hold what the reference renders, and the reference evaluates brdf.h.
// A white dielectric under uniform light then sends back (1 - F(N.V)) + 0.04 A + B <= 1
// (tests/test_probe_hit_shading.cpp integrates it).
//
// A point without a specular lobe (metallic 0, roughness 1: every material without
// metallic-roughness data but glTF's, whose default metallic is 1) is Lambert alone, with the
// very expressions the tracers used before: albedo / pi x (direct + indirect irradiance).
#ifndef PC_PROBE_HIT_SHADING_H
#define PC_PROBE_HIT_SHADING_H

#include "specular_probe.h"

PC_BEGIN

// Radiance toward V per unit of irradiance arriving from direction L (unit, toward the
// light): what a light sample's irradiance (its cosine included) is multiplied by.
PC_FN vec3 pcProbeHitLightWeight(vec3 N, vec3 V, vec3 L, vec3 baseColor, float metallic,
                                 float roughness) {
  if (!pcHasSpecularLobe(metallic, roughness)) return baseColor * (1.0f / PC_PI);
  return pcMaterialBrdf(N, V, L, baseColor, metallic, roughness);
}

// The normal whose field irradiance stands in for the light around the specular lobe.
PC_FN vec3 pcProbeHitSpecularNormal(vec3 N, vec3 V, float roughness) {
  return pcSpecularDirection(N, V, roughness);
}

// Radiance toward V reflected from the field's indirect light: E the irradiance about N,
// `lobeE` the irradiance about pcProbeHitSpecularNormal (unused without a lobe), `ab` the
// split-sum table's (A, B) at (max(N.V, 0), roughness).
PC_FN vec3 pcProbeHitIndirect(vec3 N, vec3 V, vec3 baseColor, float metallic, float roughness,
                              vec3 E, vec3 lobeE, vec2 ab) {
  return pcIndirectReflected(N, V, baseColor, metallic, roughness, E, lobeE * (1.0f / PC_PI), ab);
}

PC_END

#endif
