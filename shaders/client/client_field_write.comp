#version 460
// Field-write pass: one workgroup per (listed brick, probe of the brick) writes the probe's
// three bordered tiles. Only interiors travel from the CPU; every border texel copies the
// interior texel pcBorderSource names, so borders come out exactly as Field::fixBorders makes
// them. A weight below 1 moves each texel that share of the way from the atlas's current value
// toward the new one (fading a changed brick in over several frames); since a border texel
// always holds a copy of its source, mixing keeps it a copy.
#extension GL_GOOGLE_include_directive : require
#include "../interop/client_frame.h"
#include "../interop/field_desc.h"
#include "../interop/probe_math.h"

layout(local_size_x = PC_FW_GROUP_SIZE) in;

layout(set = 0, binding = PC_FW_BIND_FIELD_DESC) uniform FieldBlock { FieldDesc field; };
layout(set = 0, binding = PC_FW_BIND_WRITES, std430) readonly buffer WriteBlock { FieldWrite writes[]; };
layout(set = 0, binding = PC_FW_BIND_IRRADIANCE_NEW, std430) readonly buffer IrrBlock { vec4 irradianceNew[]; };
layout(set = 0, binding = PC_FW_BIND_DEPTH_NEW, std430) readonly buffer DepthBlock { vec2 depthNew[]; };
layout(set = 0, binding = PC_FW_BIND_OCCLUSION_NEW, std430) readonly buffer OccBlock { float occlusionNew[]; };
layout(set = 0, binding = PC_FW_BIND_IRRADIANCE_HELD) uniform sampler2D irradianceHeld;
layout(set = 0, binding = PC_FW_BIND_DEPTH_HELD) uniform sampler2D depthHeld;
layout(set = 0, binding = PC_FW_BIND_OCCLUSION_HELD) uniform sampler2D occlusionHeld;
layout(set = 0, binding = PC_FW_BIND_IRRADIANCE_OUT) uniform writeonly image2D irradianceOut;
layout(set = 0, binding = PC_FW_BIND_DEPTH_OUT) uniform writeonly image2D depthOut;
layout(set = 0, binding = PC_FW_BIND_OCCLUSION_OUT) uniform writeonly image2D occlusionOut;

// Interior texel that tile texel t (row-major over the bordered n+2 square) takes its value from.
ivec2 sourceTexel(int t, int n, out ivec2 local) {
  int size = n + 2;
  local = ivec2(t % size, t / size);
  bool border = local.x == 0 || local.y == 0 || local.x == size - 1 || local.y == size - 1;
  return border ? pcBorderSource(local.x, local.y, n) : local - 1;
}

void main() {
  FieldWrite w = writes[gl_WorkGroupID.x];
  CascadeDesc c = field.cascades[w.cascade];
  int slot = w.brick * PC_PROBES_PER_BRICK + int(gl_WorkGroupID.y);
  int probe = c.firstProbe + slot;
  int first = int(gl_LocalInvocationIndex);
  bool exact = w.weight >= 1.0;

  int n = PC_IRRADIANCE_TEXELS;
  ivec2 origin = pcAtlasTileOrigin(c, slot, n + 2);
  for (int t = first; t < (n + 2) * (n + 2); t += PC_FW_GROUP_SIZE) {
    ivec2 local;
    ivec2 src = sourceTexel(t, n, local);
    vec4 v = vec4(irradianceNew[probe * n * n + src.y * n + src.x].rgb, 1.0);
    ivec2 p = origin + local;
    if (!exact) v = mix(texelFetch(irradianceHeld, p, 0), v, w.weight);
    imageStore(irradianceOut, p, v);
  }
  n = PC_DEPTH_TEXELS;
  origin = pcAtlasTileOrigin(c, slot, n + 2);
  for (int t = first; t < (n + 2) * (n + 2); t += PC_FW_GROUP_SIZE) {
    ivec2 local;
    ivec2 src = sourceTexel(t, n, local);
    vec2 v = depthNew[probe * n * n + src.y * n + src.x];
    ivec2 p = origin + local;
    if (!exact) v = mix(texelFetch(depthHeld, p, 0).rg, v, w.weight);
    imageStore(depthOut, p, vec4(v, 0.0, 0.0));
  }
  n = PC_OCCLUSION_TEXELS;
  origin = pcAtlasTileOrigin(c, slot, n + 2);
  for (int t = first; t < (n + 2) * (n + 2); t += PC_FW_GROUP_SIZE) {
    ivec2 local;
    ivec2 src = sourceTexel(t, n, local);
    float v = occlusionNew[probe * n * n + src.y * n + src.x];
    ivec2 p = origin + local;
    if (!exact) v = mix(texelFetch(occlusionHeld, p, 0).r, v, w.weight);
    imageStore(occlusionOut, p, vec4(v, 0.0, 0.0, 0.0));
  }
}
