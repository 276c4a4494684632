#version 460
// Shadow rounds only (interop/gpu_trace.h, pcShadowRounds): after a round's shadow trace, adds
// the light of the round's visible slots to each probe ray's record, in slot order. Rounds run
// in slot order, so each ray sums its slots' light in the order the blend sums them when all
// slots fit one round, and the field is the same.
#extension GL_GOOGLE_include_directive : require
#include "interop/gpu_trace.h"

layout(local_size_x = PC_SHADE_THREADS) in;

layout(std430, set = 0, binding = PC_BIND_PARAMS) readonly buffer Params { UpdateParams params; };
layout(std430, set = 0, binding = PC_BIND_RAYS) buffer Rays { vec4 rays[]; };
layout(std430, set = 0, binding = PC_BIND_SHADOW_MASK) readonly buffer ShadowMask { uint shadowMask[]; };
layout(std430, set = 0, binding = PC_BIND_SHADOW_LIGHT) readonly buffer ShadowLight { GpuShadowLight shadowLight[]; };

#include "visible_light.glsl"

void main() {
  uint i = (gl_WorkGroupID.y * uint(PC_DISPATCH_ROWS) + gl_WorkGroupID.x) * uint(PC_SHADE_THREADS) +
           gl_LocalInvocationID.x;
  uint stride = uint(params.probeCount) * uint(params.rayCount);
  if (i >= stride) return;
  uint mask0 = shadowMask[i];
  bool visible = mask0 != 0u;
  int words = pcShadowMaskWords(params.roundSlots);
  for (int w = 1; w < words && !visible; ++w) visible = shadowMask[uint(w) * stride + i] != 0u;
  if (!visible) return;  // nothing of this round reached the ray's hit
  vec4 r = rays[i];
  rays[i] = vec4(pcAddVisibleLight(i, r.xyz, mask0), r.w);
}
