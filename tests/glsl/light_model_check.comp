#version 460
// Evaluates the shared light model (shaders/interop/light_model.h) and BRDF (brdf.h) as GLSL on the device, for
// tests/test_light_model.cpp to compare with the same header compiled as C++.
#extension GL_GOOGLE_include_directive : require
layout(local_size_x = 64) in;

#include "light_model_check.h"

layout(std430, binding = 0) readonly buffer Cases { LightCheckCase cases[]; };
layout(std430, binding = 1) writeonly buffer Results { vec4 results[]; };
layout(push_constant) uniform Push { int caseCount; };

void main() {
  int i = int(gl_GlobalInvocationID.x);
  if (i >= caseCount) return;
  LightCheckCase c = cases[i];
  vec3 P = c.position.xyz, N = c.normal.xyz;
  vec3 wi;
  float distance;
  vec3 E = pcLightIrradiance(c.light, P, N, wi, distance);
  float geometry = pcEmitterGeometry(c.light.position, c.light.direction, P, N);
  vec3 offset = pcOffsetRayOrigin(P, N);
  float window = pcRangeWindow(length(c.light.position - P), c.light.range);
  int base = i * PC_LIGHT_CHECK_RESULTS;
  results[base] = vec4(E, distance);
  results[base + 1] = vec4(wi, geometry);
  results[base + 2] = vec4(offset, window);
  results[base + 3] = pcBrdfCheck(c, wi, E);
  results[base + 4] = pcSpecularCheck(c, E);
}
