// Indirect specular light from irradiance probes by the split-sum approximation on spherical
// harmonics (Ikkala 2020, "Real-time path traced spherical harmonics probes", 4.2.2 and
// appendix A), shared by the CPU probe-lit render and the client:
//
//   L_spec(V) ~= S(R) x (F0 x A(N.V, roughness) + B(N.V, roughness))
//
// S(R) is the probe's radiance convolved with the GGX lobe, in the mirror direction R. The
// split sum takes N = V = R for the lobe, which makes it rotationally symmetric about R: a
// zonal function, whose convolution with an L2 SH signal multiplies band l by one number k_l
// (k_0 = 1, the lobe normalised). The lobe is the prefilter's weight D(H) max(0, N.L) at
// alpha = roughness^2, and k_l its normalised Legendre moments; appendix A fits them in
// roughness (pcGgxSpecularZh). tests/test_specular_probe.cpp checks the fit against the
// moments by quadrature: they agree to 1e-3 over the whole range, and at roughness 1 the lobe
// is the clamped cosine (k = 2/3, 1/4).
//
// A probe holds irradiance E, the cosine lobe's convolution of radiance: band l of E is A_l
// times band l of radiance (sh_probe.h). So S = sum_l (k_l / A_l) E_l, with E_l the band-l
// part of E toward R. Bands 0 and 2 are even and band 1 odd, so from E at R and -R and
// at four more directions that make an octahedron with them (a spherical 3-design, whose
// mean is exact for polynomials up to degree 3, so for everything in L0..L2 but band 0):
//   E_0 = mean of the six, E_1(R) = (E(R) - E(-R)) / 2, E_2(R) = (E(R) + E(-R)) / 2 - E_0.
// That is exact where E lies in L2 (SH probes: their tiles are derived from L2 coefficients)
// and close for octahedral tiles, whose irradiance has little above band 2 (A_3 = 0,
// A_4 / A_0 = -1/24).
//
// A and B are the GGX lobe's directional albedo split by Schlick's Fresnel (F0 (1 - Fc) + Fc):
// a small table over N.V x roughness, computed by quadrature of pcGgxSpecular's own terms when
// a renderer starts (common/split_sum_table.h), never shipped as data.
#ifndef PC_SPECULAR_PROBE_H
#define PC_SPECULAR_PROBE_H

#include "brdf.h"
#include "sh_probe.h"

PC_BEGIN

// The split-sum table: PC_SPLIT_SUM_SIZE x PC_SPLIT_SUM_SIZE entries (A, B) at
// N.V = max(i / (size - 1), PC_SPLIT_SUM_MIN_NDOTV) and roughness j / (size - 1), entry
// i + size * j; packed two to a vec4 where a renderer uploads it (FrameUniforms).
PC_CONST int PC_SPLIT_SUM_SIZE = 16;
PC_CONST int PC_SPLIT_SUM_ENTRIES = PC_SPLIT_SUM_SIZE * PC_SPLIT_SUM_SIZE;
PC_CONST float PC_SPLIT_SUM_MIN_NDOTV = 0.02f;

// N.V and roughness of table entry (i, j).
PC_FN float pcSplitSumNdotV(int i) {
  return max(float(i) / float(PC_SPLIT_SUM_SIZE - 1), PC_SPLIT_SUM_MIN_NDOTV);
}
PC_FN float pcSplitSumRoughness(int j) { return float(j) / float(PC_SPLIT_SUM_SIZE - 1); }

// Continuous table coordinates of (N.V, roughness), each in [0, size - 1], for a bilinear
// lookup.
PC_FN vec2 pcSplitSumCoord(float NdotV, float roughness) {
  float n = float(PC_SPLIT_SUM_SIZE - 1);
  return vec2(clamp(NdotV, 0.0f, 1.0f) * n, clamp(roughness, 0.0f, 1.0f) * n);
}

// The ZH coefficients k_1 and k_2 of the GGX prefilter lobe at perceptual roughness r
// (appendix A's fit, its L1 and L2 terms; k_0 = 1). r = 0 gives 1, 1 (the mirror's impulse),
// r = 1 gives 2/3, 1/4 (the clamped cosine).
PC_FN vec2 pcGgxSpecularZh(float roughness) {
  float r = clamp(roughness, 0.0f, 1.0f);
  vec2 zh = vec2(0.27793123f, 0.59372022f);
  zh += vec2(0.905501229f, 10.57518269f) *
        vec2(cos(r * 2.49220829f + 2.88755638f), cos(r * 3.49132073f + 0.56672964f));
  zh += vec2(1.98743320f, 9.52855312f) *
        vec2(cos(r * 1.79537159f + 0.636261278f), cos(r * 3.58608449f + 3.60689811f));
  zh +=
      r * (vec2(1.54054310f / sqrt(0.329615862f + r * r), 4.35171889f / sqrt(0.29109984f + r * r)) +
           vec2(-4.73179141e-04f, -3.58678416f));
  return zh;
}

// S(R) from irradiance at the six octahedron directions about R (see the top): E(R), E(-R),
// and the sum of the other four. Clamped at 0: a truncated series can ring below zero.
PC_FN vec3 pcSpecularFromIrradiance(vec3 eR, vec3 eMinusR, vec3 eSides, vec2 zh) {
  vec3 band0 = (eR + eMinusR + eSides) * (1.0f / 6.0f);
  vec3 band1 = 0.5f * (eR - eMinusR);
  vec3 band2 = 0.5f * (eR + eMinusR) - band0;
  vec3 s = band0 * (1.0f / PC_SH_A0) + band1 * (zh.x / PC_SH_A1) + band2 * (zh.y / PC_SH_A2);
  return max(s, vec3(0.0f));
}

// Mirror direction of V (toward the viewer) about the unit normal N.
PC_FN vec3 pcReflect(vec3 V, vec3 N) { return 2.0f * dot(N, V) * N - V; }

// The direction S is read in: the mirror direction for a sharp lobe, bent toward N as the lobe
// widens. The split sum centres the lobe on R, but a wide GGX lobe clipped by the horizon
// peaks between R and N (at alpha 1 its weight D N.L is the cosine about N); the bend is
// Lagarde and de Rousiers' fit ("Moving Frostbite to PBR", 2014, 4.9.3).
PC_FN vec3 pcSpecularDirection(vec3 N, vec3 V, float roughness) {
  float a = pcGgxAlpha(roughness);
  float sharpness = 1.0f - a;
  return normalize(mix(N, pcReflect(V, N), sharpness * (sqrt(sharpness) + a)));
}

// Radiance toward V reflected from indirect light by the brdf.h material: Lambert on the
// irradiance E, weighted as pcMaterialBrdf weighs it ((1 - metallic) and what the coat's
// Fresnel at N.V leaves), plus the split-sum specular S x (F0 A + B), `ab` the table's
// (A, B) at (N.V, roughness). A point without a specular lobe is Lambert alone, as before.
PC_FN vec3 pcIndirectReflected(vec3 N, vec3 V, vec3 baseColor, float metallic, float roughness,
                               vec3 E, vec3 S, vec2 ab) {
  if (!pcHasSpecularLobe(metallic, roughness)) return baseColor * (1.0f / PC_PI) * E;
  float coat = PC_DIELECTRIC_F0 + (1.0f - PC_DIELECTRIC_F0) * pcSchlickWeight(dot(N, V));
  vec3 diffuse = baseColor * ((1.0f - metallic) * (1.0f - coat) / PC_PI) * E;
  return diffuse + S * (pcSpecularF0(baseColor, metallic) * ab.x + vec3(ab.y));
}

PC_END

#endif
