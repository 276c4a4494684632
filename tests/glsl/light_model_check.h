// One case of the light model's GLSL/C++ agreement test (tests/test_light_model.cpp and
// light_model_check.comp): a light, a surface point, its normal, the view and the material
// (shaders/interop/brdf.h). The emitter-geometry and
// ray-offset checks reuse the light's position and direction as the emitter point and normal.
#ifndef PC_LIGHT_MODEL_CHECK_H
#define PC_LIGHT_MODEL_CHECK_H

#include "../../shaders/interop/brdf.h"
#include "../../shaders/interop/light_model.h"
#include "../../shaders/interop/specular_probe.h"

PC_BEGIN

struct LightCheckCase {
  GpuLight light;
  // -- 80
  vec4 position;  // xyz: P
  vec4 normal;    // xyz: N (unit)
  // -- 112
  vec4 view;      // xyz: V (unit, toward the viewer), w: roughness
  vec4 material;  // xyz: base colour, w: metallic
  // -- 144
};

// Per case, three vec4 results:
//   [0] pcLightIrradiance (xyz) and its distance (w)
//   [1] its wi (xyz) and pcEmitterGeometry(light.position, light.direction, P, N) (w)
//   [2] pcOffsetRayOrigin(P, N) (xyz), pcRangeWindow(distance to the light, range) (w)
//   [3] pcMaterialBrdf(N, V, wi, material) x the irradiance (xyz: the reflected radiance),
//       pcGgxVndfPdf of wi (w)
//   [4] the split-sum indirect term (specular_probe.h): pcIndirectReflected (xyz) with the
//       irradiance as E and a specular radiance made by pcSpecularFromIrradiance toward the
//       mirror direction; the lobe's k_1 + k_2 (w)
PC_CONST int PC_LIGHT_CHECK_RESULTS = 5;

// The light reflected toward V, and the density of drawing wi by GGX's visible normals (the
// half-vector of V and wi): what a renderer evaluates with brdf.h for one light sample.
PC_FN vec4 pcBrdfCheck(LightCheckCase c, vec3 wi, vec3 E) {
  vec3 N = vec3(c.normal.x, c.normal.y, c.normal.z);
  vec3 V = vec3(c.view.x, c.view.y, c.view.z);
  vec3 base = vec3(c.material.x, c.material.y, c.material.z);
  vec3 f = pcMaterialBrdf(N, V, wi, base, c.material.w, c.view.w);
  vec3 h = V + wi;
  float hLength = length(h);
  float NdotH = hLength > 0.0f ? max(dot(N, h) / hLength, 0.0f) : 0.0f;
  return vec4(f * E, pcGgxVndfPdf(dot(N, V), NdotH, pcGgxAlpha(c.view.w)));
}

// The indirect light a renderer gets from the field for this case's surface, with the light's
// irradiance E standing in for the probes': E toward the mirror direction, and E scaled
// differently toward the opposite and the four side directions, so every band takes part. The
// table's (A, B) is a smooth made-up function here (the table itself is a C++ upload).
PC_FN vec4 pcSpecularCheck(LightCheckCase c, vec3 E) {
  vec3 N = vec3(c.normal.x, c.normal.y, c.normal.z);
  vec3 V = vec3(c.view.x, c.view.y, c.view.z);
  vec3 base = vec3(c.material.x, c.material.y, c.material.z);
  float roughness = c.view.w;
  vec2 zh = pcGgxSpecularZh(roughness);
  vec3 R = pcReflect(V, N);
  vec3 S = pcSpecularFromIrradiance(E, E * abs(R.x), E * (1.0f + R.y * R.y), zh);
  vec2 ab = vec2(0.5f + 0.4f * max(dot(N, V), 0.0f), 0.05f * roughness);
  vec3 L = pcIndirectReflected(N, V, base, c.material.w, roughness, E, S, ab);
  return vec4(L, zh.x + zh.y);
}

PC_END

#ifdef __cplusplus
static_assert(sizeof(pc::gpu::LightCheckCase) == 144);
#endif

#endif
