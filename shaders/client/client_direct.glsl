// Direct light at a surface point: punctual lights and emitter stand-ins with their shadow maps
// (3x3 PCF from four gathers). Evaluated in the compute pass that also samples the field, not in
// a fragment shader: the raster pass only writes visibility ids, which keeps the raster work
// small where graphics units are few (an H100: docs/BENCHMARKS.md), and surfaces are shaded
// once per distinct triangle of a pixel.
// Needs client_common.glsl first.
#include "../interop/brdf.h"
#include "../interop/sun_cascades.h"

layout(set = 0, binding = PC_CLIENT_BIND_LIGHTS, std430) readonly buffer LightBlock { GpuLight lights[]; };
layout(set = 0, binding = PC_CLIENT_BIND_SHADOW_MATRICES, std430) readonly buffer ShadowBlock {
  mat4 shadowMatrices[];
};
layout(set = 0, binding = PC_CLIENT_BIND_SHADOW_MAPS) uniform sampler2DArrayShadow shadowMaps[3];

// Cube face of direction v, in the order the client renders them: +x, -x, +y, -y, +z, -z.
int cubeFace(vec3 v) {
  vec3 a = abs(v);
  if (a.x >= a.y && a.x >= a.z) return v.x >= 0.0 ? 0 : 1;
  if (a.y >= a.z) return v.y >= 0.0 ? 2 : 3;
  return v.z >= 0.0 ? 4 : 5;
}

// Share of the light that reaches the point at `uv` (depth `ref`) of a shadow map layer, with
// 3x3 percentage-closer filtering: the mean of nine bilinear 2x2 comparisons one texel apart.
// Those nine taps cover a 4x4 block of texels with per-axis weights (1 - f, 1, 1, f) (f: the
// bilinear fraction), so four gathered comparisons of that block, weighted here, give the same
// filter with four fetches instead of nine.
float filteredShadow(int array, int layer, vec2 uv, float ref, float texel) {
  vec3 coord = vec3(uv, float(layer));
  // Gather components: x (low u, high v), y (high u, high v), z (high u, low v), w (low, low).
  vec4 a = textureGatherOffset(shadowMaps[array], coord, ref, ivec2(-1, -1));
  vec4 b = textureGatherOffset(shadowMaps[array], coord, ref, ivec2(1, -1));
  vec4 c = textureGatherOffset(shadowMaps[array], coord, ref, ivec2(-1, 1));
  vec4 d = textureGatherOffset(shadowMaps[array], coord, ref, ivec2(1, 1));
  vec4 all4 = a + b + c + d;
  float total = all4.x + all4.y + all4.z + all4.w;
  if (total == 0.0 || total == 16.0) return total / 16.0;  // fully shadowed or fully lit
  vec2 f = fract(uv / texel - 0.5);
  vec2 lo = 1.0 - f;  // weight of the lowest texel row/column; the middle two weigh 1
  float sum = dot(a, vec4(lo.x, 1.0, 1.0, lo.x) * vec4(1.0, 1.0, lo.y, lo.y)) +
              dot(b, vec4(1.0, f.x, f.x, 1.0) * vec4(1.0, 1.0, lo.y, lo.y)) +
              dot(c, vec4(lo.x, 1.0, 1.0, lo.x) * vec4(f.y, f.y, 1.0, 1.0)) +
              dot(d, vec4(1.0, f.x, f.x, 1.0) * vec4(f.y, f.y, 1.0, 1.0));
  return sum / 9.0;
}

// The sun's cascade `c` at P: its visibility, and how far inside the map P lies
// (pcSunCascadeWeight: below 0 outside). The receiver moves along its normal by
// PC_SUN_NORMAL_OFFSET_TEXELS of this map's texels (an orthographic map's x and y rows have
// length 2 / its width and height; the larger texel counts), so surfaces do not shadow
// themselves at any cascade's resolution.
float sunCascade(GpuLight l, vec3 P, vec3 N, int c, out float visibility) {
  mat4 m = shadowMatrices[l.shadowMatrix + c];
  float rows =
      min(length(vec3(m[0][0], m[1][0], m[2][0])), length(vec3(m[0][1], m[1][1], m[2][1])));
  float texelWorld = 2.0 * l.shadowTexel / rows;
  vec3 ndc = (m * vec4(P + N * (l.normalOffset * texelWorld) - l.position, 1.0)).xyz;
  vec2 uv = ndc.xy * 0.5 + 0.5;
  float weight = pcSunCascadeWeight(uv, ndc.z, l.shadowTexel);
  visibility = weight < 0.0 ? 1.0
                            : filteredShadow(l.shadowArray, l.shadowLayer + c, uv,
                                             ndc.z - l.depthBias, l.shadowTexel);
  return weight;
}

// The sun at P: the finest cascade that holds P, faded into the next one near its border;
// lit where none holds it (outside the scene's bounds).
float sunVisibility(GpuLight l, vec3 P, vec3 N) {
  for (int c = 0; c < PC_SUN_CASCADES; ++c) {
    float v;
    float w = sunCascade(l, P, N, c, v);
    if (w < 0.0) continue;
    if (w >= 1.0 || c + 1 == PC_SUN_CASCADES) return v;
    float next;
    if (sunCascade(l, P, N, c + 1, next) < 0.0) return v;
    return mix(next, v, w);
  }
  return 1.0;
}

// Share of a spot, point or area light that reaches P, from its perspective shadow map (a
// cube face for point and area lights). The receiver moves along its normal by a texel's
// footprint at its distance so surfaces do not shadow themselves.
float shadowVisibility(GpuLight l, vec3 P, vec3 N, float dist) {
  if (l.shadowLayer < 0) return 1.0;
  vec3 offsetP = P + N * (l.normalOffset * dist);
  int matrixIndex = l.shadowMatrix;
  int layer = l.shadowLayer;
  if (l.type == PC_LIGHT_POINT || l.type == PC_LIGHT_AREA) {
    int face = cubeFace(offsetP - l.position);
    matrixIndex += face;
    layer += face;
  }
  vec4 clip = shadowMatrices[matrixIndex] * vec4(offsetP - l.position, 1.0);  // from the light
  if (clip.w <= 0.0) return 1.0;
  vec3 ndc = clip.xyz / clip.w;
  vec2 uv = ndc.xy * 0.5 + 0.5;
  if (any(lessThan(uv, vec2(0.0))) || any(greaterThan(uv, vec2(1.0))) || ndc.z >= 1.0) return 1.0;
  return filteredShadow(l.shadowArray, layer, uv, ndc.z - l.depthBias, l.shadowTexel);
}

// Irradiance at P from light `l`, shadowed by its map (0 where it does not reach P), and in
// `wi` the direction toward it. The light itself is the shared light model
// (shaders/interop/light_model.h), as the tracers evaluate it. N: the shading normal (the
// light's cosine); Nbias: the vertex normal, along which the receiver moves off its surface
// for the shadow lookup (a normal-mapped normal would move it off the real surface).
vec3 lightIrradiance(GpuLight l, vec3 P, vec3 N, vec3 Nbias, out vec3 wi) {
  float d;
  float scale = pcLightScale(l, P, N, wi, d);
  if (!(scale > 0.0)) return vec3(0.0);  // behind P, outside its cone or range
  if (l.type == PC_LIGHT_DIRECTIONAL)
    return l.power * (scale * (l.shadowLayer < 0 ? 1.0 : sunVisibility(l, P, Nbias)));
  return l.power * (scale * shadowVisibility(l, P, Nbias, d));
}

// Every light at P, each shadowed by its map (see lightIrradiance).
vec3 directIrradiance(vec3 P, vec3 N, vec3 Nbias) {
  vec3 E = vec3(0.0);
  vec3 wi;
  for (int i = 0; i < frame.lightCount; ++i) E += lightIrradiance(lights[i], P, N, Nbias, wi);
  return E;
}

// Radiance toward V (unit, toward the viewer) reflected from every light by the surface's
// BRDF (shaders/interop/brdf.h), as the CPU renders weigh each light sample
// (cpu/lighting.cpp, directReflected): Lambert alone where the surface has no specular lobe.
vec3 directReflected(vec3 P, vec3 N, vec3 Nbias, vec3 V, vec3 baseColor, float metallic,
                     float roughness) {
  if (!pcHasSpecularLobe(metallic, roughness))
    return baseColor * (1.0 / PC_PI) * directIrradiance(P, N, Nbias);
  vec3 L = vec3(0.0);
  for (int i = 0; i < frame.lightCount; ++i) {
    vec3 wi;
    vec3 E = lightIrradiance(lights[i], P, N, Nbias, wi);
    if (E != vec3(0.0)) L += E * pcMaterialBrdf(N, V, wi, baseColor, metallic, roughness);
  }
  return L;
}
