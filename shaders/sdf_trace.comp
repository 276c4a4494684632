#version 460
// The SDF backend's probe rays, in place of probe_trace.rgen (interop/gpu_trace.h): each ray
// sphere-traced through the distance field (sdf_trace.glsl) to its closest hit, stored as the
// same GpuHit for probe_shade.comp. One invocation per ray, in launch order.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_nonuniform_qualifier : require
#include "field_sampling.glsl"
#include "interop/sdf_grid.h"

layout(local_size_x = PC_SDF_TRACE_THREADS) in;
// Scenes with cut-outs test their hits' coverage (cutout_coverage.glsl).
layout(constant_id = 0) const bool kCutOuts = false;

layout(std430, set = 0, binding = PC_BIND_PARAMS) readonly buffer Params { UpdateParams params; };
layout(std430, set = 0, binding = PC_BIND_REQUESTS) readonly buffer Requests { ivec2 requests[]; };
layout(std430, set = 0, binding = PC_BIND_RAY_DIRS) readonly buffer RayDirs { vec4 rayDirs[]; };
layout(std430, set = 0, binding = PC_BIND_HITS) writeonly buffer Hits { GpuHit hits[]; };
layout(std430, set = 0, binding = PC_BIND_VERTICES) readonly buffer Vertices { GpuVertex vertices[]; };
layout(std430, set = 0, binding = PC_BIND_INDICES) readonly buffer Indices { uint indices[]; };
layout(std430, set = 0, binding = PC_BIND_MESHES) readonly buffer Meshes { GpuMesh meshes[]; };
layout(std430, set = 0, binding = PC_BIND_INSTANCES) readonly buffer Instances { GpuInstance instances[]; };
layout(std430, set = 0, binding = PC_BIND_MATERIALS) readonly buffer Materials { GpuMaterial materials[]; };
layout(set = 0, binding = PC_BIND_TEXTURES) uniform sampler2D textures[];

#include "sdf_trace.glsl"

void main() {
  uint launchIndex = (gl_WorkGroupID.y * uint(PC_DISPATCH_ROWS) + gl_WorkGroupID.x) * uint(PC_SDF_TRACE_THREADS) +
                     gl_LocalInvocationID.x;
  if (launchIndex >= uint(params.probeCount) * uint(params.rayCount)) return;
  ivec2 pr = pcLaunchProbeRay(launchIndex, params.probeCount, params.rayCount);
  ivec2 ref = requests[pr.x];
  CascadeDesc c = field.cascades[ref.x];
  GpuProbeRecord record = probes[c.firstProbe + ref.y];
  vec3 origin = pcProbeGridPosition(c, pcLogicalCoord(c, pcSlotCoord(c, ref.y))) + record.offset;
  vec3 dir = rayDirs[pr.y].xyz;
  SdfHit s = sdfTrace(origin, dir, pcProbeRayNear(c), PC_MISS_DISTANCE);
  GpuHit h;
  h.barycentric = s.barycentric;
  h.t = s.t;
  h.instance = -1;
  h.primitive = 0;
  h.pad0 = 0;
  if (s.t >= 0.0f) {
    SdfTriangle tr = triangles[s.triangle];
    h.instance = tr.record;
    h.primitive = tr.primitive;
  }
  hits[launchIndex] = h;
}
