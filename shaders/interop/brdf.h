// The surface BRDF, once for every renderer: glTF's metallic-roughness model as Lambert
// diffuse weighted by (1 - metallic) and by what the dielectric coat's Fresnel leaves, plus a
// GGX (Trowbridge-Reitz) specular lobe with Smith's height-correlated masking-shadowing and
// Schlick's Fresnel, F0 = mix(0.04, baseColor, metallic). The reference path tracer
// (cpu/path_tracer.cpp, cpu/material_sampling.cpp) evaluates and samples it from here; a GPU
// renderer that shades glossy surfaces includes the same functions, so the formulas cannot drift
// apart.
//
// Metallic 0 with roughness 1 is the plain diffuse surface (Material::isDiffuseOnly): Lambert
// alone, without the dielectric's 4% lobe, so scenes without metallic-roughness data render
// as they always did.
#ifndef PC_BRDF_H
#define PC_BRDF_H

#include "field_desc.h"
#include "pc_interop.h"

PC_BEGIN

// The smallest GGX alpha: a perfect mirror's lobe is a delta that float evaluation cannot
// hold, so roughness 0 is drawn as a very sharp lobe instead.
PC_CONST float PC_GGX_MIN_ALPHA = 1e-3f;
// Reflectance at normal incidence of a dielectric of index 1.5 (glTF's default).
PC_CONST float PC_DIELECTRIC_F0 = 0.04f;

// Whether a point with these terms has a specular lobe at all.
PC_FN bool pcHasSpecularLobe(float metallic, float roughness) {
  return metallic > 0.0f || roughness < 1.0f;
}

// GGX alpha from glTF's perceptual roughness (alpha = roughness^2).
PC_FN float pcGgxAlpha(float roughness) { return max(roughness * roughness, PC_GGX_MIN_ALPHA); }

PC_FN vec3 pcSpecularF0(vec3 baseColor, float metallic) {
  return mix(vec3(PC_DIELECTRIC_F0), baseColor, metallic);
}

// Schlick's weight (1 - cos)^5 at the angle whose cosine is `cosTheta` (between V and H).
PC_FN float pcSchlickWeight(float cosTheta) {
  float m = clamp(1.0f - cosTheta, 0.0f, 1.0f);
  float m2 = m * m;
  return m2 * m2 * m;
}

// Schlick's approximation of the Fresnel reflectance.
PC_FN vec3 pcFresnelSchlick(vec3 F0, float cosTheta) {
  return F0 + (vec3(1.0f) - F0) * pcSchlickWeight(cosTheta);
}

// GGX normal distribution D(h) for cos(N, H) = NdotH: integrates to 1 against NdotH over
// the hemisphere of half-vectors.
PC_FN float pcGgxD(float NdotH, float alpha) {
  float a2 = alpha * alpha;
  float d = NdotH * NdotH * (a2 - 1.0f) + 1.0f;
  return a2 / (PC_PI * d * d);
}

// Smith's masking term G1 for one direction at cos(N, V) = NdotV.
PC_FN float pcSmithG1(float NdotV, float alpha) {
  float a2 = alpha * alpha;
  return 2.0f * NdotV / (NdotV + sqrt(a2 + (1.0f - a2) * NdotV * NdotV));
}

// Smith's height-correlated masking-shadowing over the BRDF's denominator:
// V = G2(L, V) / (4 NdotL NdotV), so the specular BRDF is D x V x F.
PC_FN float pcSmithVisibility(float NdotL, float NdotV, float alpha) {
  float a2 = alpha * alpha;
  float gv = NdotL * sqrt(NdotV * NdotV * (1.0f - a2) + a2);
  float gl = NdotV * sqrt(NdotL * NdotL * (1.0f - a2) + a2);
  float sum = gv + gl;
  return sum > 0.0f ? 0.5f / sum : 0.0f;
}

// The GGX specular BRDF (no cosine) for unit N, V (toward the viewer) and L (toward the
// light); zero where either lies below the surface.
PC_FN vec3 pcGgxSpecular(vec3 N, vec3 V, vec3 L, vec3 F0, float alpha) {
  float NdotL = dot(N, L), NdotV = dot(N, V);
  if (!(NdotL > 0.0f) || !(NdotV > 0.0f)) return vec3(0.0f);
  vec3 h = V + L;
  float hLength = length(h);
  if (!(hLength > 0.0f)) return vec3(0.0f);
  h = h / hLength;
  float NdotH = max(dot(N, h), 0.0f);
  return pcFresnelSchlick(F0, dot(V, h)) *
         (pcGgxD(NdotH, alpha) * pcSmithVisibility(NdotL, NdotV, alpha));
}

// The whole BRDF (no cosine): the GGX lobe with Schlick's F0 = mix(0.04, baseColor,
// metallic), plus Lambert x (1 - metallic) x (1 - F), F the dielectric coat's own Schlick
// reflectance (F0 0.04) toward the viewer, at N.V: what the coat reflects toward V does not
// come from the diffuse base, so a white surface never reflects more than arrives. (glTF's
// appendix B takes F at the half-vector instead, which lets a smooth white dielectric reflect
// 1.5 times what arrives at grazing views. F at N.V makes the BRDF not reciprocal, which a
// path tracer that starts at the camera does not need.) Lambert alone where the point has
// no specular lobe. Zero where L lies below the surface.
PC_FN vec3 pcMaterialBrdf(vec3 N, vec3 V, vec3 L, vec3 baseColor, float metallic, float roughness) {
  if (!(dot(N, L) > 0.0f)) return vec3(0.0f);
  if (!pcHasSpecularLobe(metallic, roughness)) return baseColor * (1.0f / PC_PI);
  float coat = PC_DIELECTRIC_F0 + (1.0f - PC_DIELECTRIC_F0) * pcSchlickWeight(dot(N, V));
  vec3 diffuse = baseColor * ((1.0f - metallic) * (1.0f - coat) / PC_PI);
  return diffuse + pcGgxSpecular(N, V, L, pcSpecularF0(baseColor, metallic), pcGgxAlpha(roughness));
}

// A half-vector drawn from the distribution of visible normals (Heitz 2018, "Sampling the
// GGX Distribution of Visible Normals"), in the frame where the normal is +Z and `Ve` (unit,
// Ve.z > 0) is the view direction. Its density over half-vectors is
// G1(V) max(0, V.H) D(H) / V.z.
PC_FN vec3 pcSampleGgxVndf(vec3 Ve, float alpha, float u1, float u2) {
  // The view direction in the hemisphere configuration (alpha stretched to 1).
  vec3 Vh = normalize(vec3(alpha * Ve.x, alpha * Ve.y, Ve.z));
  float lensq = Vh.x * Vh.x + Vh.y * Vh.y;
  vec3 T1 = lensq > 0.0f ? vec3(-Vh.y, Vh.x, 0.0f) * (1.0f / sqrt(lensq)) : vec3(1.0f, 0.0f, 0.0f);
  vec3 T2 = cross(Vh, T1);
  // A point on the projected disk, the half of it behind Vh squeezed.
  float r = sqrt(u1);
  float phi = 2.0f * PC_PI * u2;
  float t1 = r * cos(phi);
  float t2 = r * sin(phi);
  float s = 0.5f * (1.0f + Vh.z);
  t2 = (1.0f - s) * sqrt(max(0.0f, 1.0f - t1 * t1)) + s * t2;
  vec3 Nh = T1 * t1 + T2 * t2 + Vh * sqrt(max(0.0f, 1.0f - t1 * t1 - t2 * t2));
  // Back to the ellipsoid configuration.
  return normalize(vec3(alpha * Nh.x, alpha * Nh.y, max(0.0f, Nh.z)));
}

// The density over directions L of reflecting V about a half-vector drawn by
// pcSampleGgxVndf: G1(V) D(H) / (4 NdotV) (the 1 / (4 V.H) Jacobian cancels V.H).
PC_FN float pcGgxVndfPdf(float NdotV, float NdotH, float alpha) {
  if (!(NdotV > 0.0f)) return 0.0f;
  return pcSmithG1(NdotV, alpha) * pcGgxD(NdotH, alpha) / (4.0f * NdotV);
}

// An orthonormal frame about the unit normal N without branches on the dominant axis (Duff et
// al. 2017): the tangent and the bitangent, N = cross(tangent, bitangent).
PC_FN vec3 pcFrameTangent(vec3 N) {
  float s = N.z >= 0.0f ? 1.0f : -1.0f;
  float a = -1.0f / (s + N.z);
  float b = N.x * N.y * a;
  return vec3(1.0f + s * N.x * N.x * a, s * b, -s * N.x);
}
PC_FN vec3 pcFrameBitangent(vec3 N) {
  float s = N.z >= 0.0f ? 1.0f : -1.0f;
  float a = -1.0f / (s + N.z);
  float b = N.x * N.y * a;
  return vec3(b, s + N.y * N.y * a, -N.y);
}

PC_END

#endif
