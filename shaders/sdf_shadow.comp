#version 460
// The SDF backend's shadow rays, in place of probe_shadow.rgen (interop/gpu_trace.h): one
// invocation per entry a round's shadow lists can hold, those past their slot's list length
// (the counters) return at once; a ray that reaches its far end through the distance field
// (sdf_trace.glsl) unblocked sets its slot's bit in its probe ray's mask.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_nonuniform_qualifier : require
#include "interop/gpu_trace.h"
#include "interop/sdf_grid.h"

layout(local_size_x = PC_SDF_TRACE_THREADS) in;
layout(constant_id = 0) const bool kCutOuts = false;

layout(std430, set = 0, binding = PC_BIND_SHADOW_RAYS) readonly buffer ShadowRays { GpuShadowRay shadowRays[]; };
layout(std430, set = 0, binding = PC_BIND_PARAMS) readonly buffer Params { UpdateParams params; };
layout(std430, set = 0, binding = PC_BIND_SHADOW_MASK) buffer ShadowMask { uint shadowMask[]; };
layout(std430, set = 0, binding = PC_BIND_COUNTERS) readonly buffer Counters { uint counters[]; };
layout(std430, set = 0, binding = PC_BIND_VERTICES) readonly buffer Vertices { GpuVertex vertices[]; };
layout(std430, set = 0, binding = PC_BIND_INDICES) readonly buffer Indices { uint indices[]; };
layout(std430, set = 0, binding = PC_BIND_MESHES) readonly buffer Meshes { GpuMesh meshes[]; };
layout(std430, set = 0, binding = PC_BIND_INSTANCES) readonly buffer Instances { GpuInstance instances[]; };
layout(std430, set = 0, binding = PC_BIND_MATERIALS) readonly buffer Materials { GpuMaterial materials[]; };
layout(set = 0, binding = PC_BIND_TEXTURES) uniform sampler2D textures[];
// push.count: the round's slots; push.slotBase: its first slot (pcShadowRounds).
layout(push_constant) uniform Push { TracePush push; };

#include "sdf_trace.glsl"

void main() {
  uint i = (gl_WorkGroupID.y * uint(PC_DISPATCH_ROWS) + gl_WorkGroupID.x) * uint(PC_SDF_TRACE_THREADS) +
           gl_LocalInvocationID.x;
  uint rays = uint(params.probeCount) * uint(params.rayCount);
  uint slot = i / rays;  // the slot's place in its round
  if (slot >= uint(push.count)) return;
  uint listLength = counters[(uint(push.slotBase) + slot) * uint(PC_COUNTER_WORDS)];
  if (i - slot * rays >= listLength) return;  // past the list
  GpuShadowRay r = shadowRays[i];
  if (sdfTrace(r.origin, r.direction, PC_SHADOW_NEAR, r.tmax).t >= 0.0f) return;
  // r.light = slot * rays + launch index of its probe ray.
  uint ray = r.light - slot * rays;
  atomicOr(shadowMask[(slot >> 5u) * rays + ray], 1u << (slot & 31u));
}
