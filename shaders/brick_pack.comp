#version 460
// Packs the tiles of each changed brick for the host: one workgroup per listed brick (an
// indirect dispatch sized by brick_changes.comp). A brick's 64 probes are consecutive slots of
// one atlas tile row, so its tiles cover whole runs of atlas rows: the brick packs as those
// runs (gpu_trace.h), PC_PROBES_PER_BRICK * PC_PACKED_PROBE_FLOATS floats, and the host copies
// each run back with one memcpy. Only these bytes cross to the host.
#extension GL_GOOGLE_include_directive : require
#define PC_FIELD_READONLY
#include "field_buffers.glsl"

layout(local_size_x = 256) in;

layout(std430, set = 0, binding = PC_BIND_PARAMS) readonly buffer Params { UpdateParams params; };
layout(std430, set = 0, binding = PC_BIND_BRICK_LIST) readonly buffer BrickList { uint brickList[]; };
layout(std430, set = 0, binding = PC_BIND_PACKED) writeonly buffer Packed { float packed[]; };

void main() {
  uint entry = gl_WorkGroupID.x;
  int brick = int(brickList[PC_BRICK_LIST_HEADER + entry]);
  int k = 0;
  while (k + 1 < field.cascadeCount && brick >= params.cascadeBrickOffset[k + 1]) ++k;
  CascadeDesc c = field.cascades[k];
  int firstSlot = (brick - params.cascadeBrickOffset[k]) * PC_PROBES_PER_BRICK;
  const int si = PC_IRRADIANCE_TEXELS + 2, sd = PC_DEPTH_TEXELS + 2, so = PC_OCCLUSION_TEXELS + 2;
  // Floats of one packed row run, and where each channel's runs end.
  const int ri = PC_PROBES_PER_BRICK * si * 3, rd = PC_PROBES_PER_BRICK * sd * 2, ro = PC_PROBES_PER_BRICK * so;
  const int endI = si * ri, endD = endI + sd * rd;
  const int total = PC_PROBES_PER_BRICK * PC_PACKED_PROBE_FLOATS;
  ivec2 oi = pcAtlasTileOrigin(c, firstSlot, si);
  ivec2 od = pcAtlasTileOrigin(c, firstSlot, sd);
  ivec2 oo = pcAtlasTileOrigin(c, firstSlot, so);
  uint outBase = entry * uint(total);
  for (int e = int(gl_LocalInvocationIndex); e < total; e += 256) {
    float value;
    if (e < endI) {
      int y = e / ri, x = e - y * ri;  // x: float in the row run, three per texel
      value = irradianceTexels[pcIrradianceIndex(oi + ivec2(x / 3, y))][x % 3];
    } else if (e < endD) {
      int f = e - endI, y = f / rd, x = f - y * rd;
      value = depthTexels[pcDepthIndex(od + ivec2(x / 2, y))][x % 2];
    } else {
      int f = e - endD, y = f / ro;
      value = occlusionTexels[pcOcclusionIndex(oo + ivec2(0, y)) + (f - y * ro)];
    }
    packed[outBase + uint(e)] = value;
  }
}
