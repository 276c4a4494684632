#version 460
// Compiles the shared C++/GLSL headers as GLSL with stub fetches, so a header edit that only
// C++ accepts fails the tests.
#extension GL_GOOGLE_include_directive : require
layout(local_size_x = 8, local_size_y = 8) in;

#include "../../shaders/interop/field_desc.h"
#include "../../shaders/interop/normal_map.h"
#include "../../shaders/interop/brdf.h"
layout(std430, binding = 0) buffer Out { vec4 result[]; };
layout(std140, binding = 1) uniform Desc { FieldDesc field; };
layout(binding = 2) uniform sampler2D irradianceAtlas;
layout(binding = 3) uniform sampler2D depthAtlas;

#define PC_FIELD_PARAM
#define PC_FIELD_ARG
vec3 pcFetchIrradiance(int cascade, int slot, vec3 dir) { return textureLod(irradianceAtlas, vec2(float(slot), dir.x), 0.0f).rgb; }
vec2 pcFetchDepth(int cascade, int slot, vec3 dir) { return textureLod(depthAtlas, vec2(float(slot), dir.y), 0.0f).rg; }
float pcFetchOcclusion(int cascade, int slot, vec3 dir) { return 1.0f; }
vec4 pcFetchProbe(int cascade, int slot) { return vec4(0.0f); }
#include "../../shaders/interop/probe_sampling.h"
#include "../../shaders/interop/probe_update.h"
#include "../../shaders/interop/probe_hit_shading.h"
#include "../../shaders/interop/sdf_grid.h"
#include "../../shaders/interop/ldm.h"
#include "../../shaders/interop/sh_probe.h"
#include "../../shaders/interop/tonemap.h"
#include "../../shaders/interop/sun_cascades.h"
#include "../../shaders/interop/probe_view.h"
#define PC_AO_PARAM
#define PC_AO_ARG
vec4 pcAoSurface(ivec2 p) { return textureLod(depthAtlas, vec2(p) * 0.01f, 0.0f); }
vec3 pcAoNormal(ivec2 p) { return vec3(0.0f, 0.0f, 1.0f); }
vec3 pcAoRay(vec2 p) { return normalize(vec3(p * 0.01f, -1.0f)); }
#include "../../shaders/interop/screen_ao_horizons.h"

void main() {
  uint i = gl_GlobalInvocationID.x;
  vec3 d = pcFibonacciDirection(int(i), 256);
  d = pcRandomRotation(7u) * d;
  vec2 uv = pcOctEncode(d);
  float coverage = 0.0f;
  vec4 s = pcSampleField(field, vec3(1.0f), pcOctDecode(uv), vec3(0.0f, 1.0f, 0.0f), PC_SAMPLE_DEFAULT, coverage);
  ivec2 b = pcBorderSource(0, 3, 8);
  float ao = pcScreenAo(ivec2(i, 0), d, d, pcAoRadius(field, d, PC_AO_DEFAULT_RADIUS));
  vec3 n = pcPerturbNormal(d, vec3(1.0f, 0.0f, 0.0f), 1.0f, pcNormalMapDirection(vec3(s), 1.0f));
  vec3 h = pcSampleGgxVndf(d, 0.3f, 0.5f, 0.25f);
  vec3 f = pcMaterialBrdf(n, d, pcFrameTangent(h) + pcFrameBitangent(h), vec3(s), 0.5f, 0.4f) *
           pcGgxVndfPdf(d.z, h.z, pcGgxAlpha(0.4f));
  result[i] = vec4(pcTonemap(vec3(s), 1.0f) * pcAoMultiBounce(ao, n) + f,
                   coverage + float(b.x) + pcIrradianceWeight(d, d));
}
