// Sampling the previous field at probe-ray hits with the shared code of
// interop/probe_sampling.h. The fetches read the atlas buffers bilinearly exactly as the CPU's
// (common/field.cpp): the tile border guarantees all four texels lie inside the tile.
#ifndef PC_FIELD_SAMPLING_GLSL
#define PC_FIELD_SAMPLING_GLSL

#define PC_FIELD_READONLY
#include "field_buffers.glsl"

// Bilinear weights and the top-left texel of the 2x2 footprint at tile coordinate `tc`.
void pcBilinearSetup(vec2 tc, int tileSize, out ivec2 t0, out vec2 a) {
  float fx = tc.x - 0.5f, fy = tc.y - 0.5f;
  t0 = ivec2(clamp(int(floor(fx)), 0, tileSize - 2), clamp(int(floor(fy)), 0, tileSize - 2));
  a = clamp(vec2(fx - float(t0.x), fy - float(t0.y)), vec2(0.0f), vec2(1.0f));
}

vec3 pcIrradianceTexel(ivec2 p) { return irradianceTexels[pcIrradianceIndex(p)].xyz; }
vec2 pcDepthTexel(ivec2 p) { return depthTexels[pcDepthIndex(p)]; }

#define PC_FIELD_PARAM
#define PC_FIELD_ARG

vec3 pcFetchIrradiance(int cascade, int slot, vec3 dir) {
  const int n = PC_IRRADIANCE_TEXELS;
  ivec2 o = pcAtlasTileOrigin(field.cascades[cascade], slot, n + 2);
  ivec2 t0;
  vec2 a;
  pcBilinearSetup(pcTileCoord(dir, n), n + 2, t0, a);
  ivec2 p = o + t0;
  vec3 top = mix(pcIrradianceTexel(p), pcIrradianceTexel(p + ivec2(1, 0)), a.x);
  vec3 bottom = mix(pcIrradianceTexel(p + ivec2(0, 1)), pcIrradianceTexel(p + ivec2(1, 1)), a.x);
  return mix(top, bottom, a.y);
}

vec2 pcFetchDepth(int cascade, int slot, vec3 dir) {
  const int n = PC_DEPTH_TEXELS;
  ivec2 o = pcAtlasTileOrigin(field.cascades[cascade], slot, n + 2);
  ivec2 t0;
  vec2 a;
  pcBilinearSetup(pcTileCoord(dir, n), n + 2, t0, a);
  ivec2 p = o + t0;
  vec2 top = mix(pcDepthTexel(p), pcDepthTexel(p + ivec2(1, 0)), a.x);
  vec2 bottom = mix(pcDepthTexel(p + ivec2(0, 1)), pcDepthTexel(p + ivec2(1, 1)), a.x);
  return mix(top, bottom, a.y);
}

float pcFetchOcclusion(int cascade, int slot, vec3 dir) {
  const int n = PC_OCCLUSION_TEXELS;
  ivec2 o = pcAtlasTileOrigin(field.cascades[cascade], slot, n + 2);
  ivec2 t0;
  vec2 a;
  pcBilinearSetup(pcTileCoord(dir, n), n + 2, t0, a);
  ivec2 p = o + t0;
  float top = mix(occlusionTexels[pcOcclusionIndex(p)], occlusionTexels[pcOcclusionIndex(p + ivec2(1, 0))], a.x);
  float bottom = mix(occlusionTexels[pcOcclusionIndex(p + ivec2(0, 1))],
                     occlusionTexels[pcOcclusionIndex(p + ivec2(1, 1))], a.x);
  return mix(top, bottom, a.y);
}

vec4 pcFetchProbe(int cascade, int slot) {
  GpuProbeRecord r = probes[field.cascades[cascade].firstProbe + slot];
  return vec4(r.offset, float(r.state));
}

#include "interop/probe_sampling.h"

#endif
