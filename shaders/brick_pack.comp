#version 460
// Packs the tiles of each changed brick for the host: one workgroup per listed brick (an
// indirect dispatch sized by brick_changes.comp), its 64 probes' bordered irradiance, depth and
// occlusion tiles in slot order, PC_PACKED_PROBE_FLOATS floats per probe. Only these bytes
// cross to the host.
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
  const int total = PC_PROBES_PER_BRICK * PC_PACKED_PROBE_FLOATS;
  uint outBase = entry * uint(total);
  for (int e = int(gl_LocalInvocationIndex); e < total; e += 256) {
    int q = e / PC_PACKED_PROBE_FLOATS;
    int f = e - q * PC_PACKED_PROBE_FLOATS;
    int slot = firstSlot + q;
    float value;
    if (f < PC_PACKED_IRRADIANCE) {
      int t = f / 3;
      ivec2 o = pcAtlasTileOrigin(c, slot, si) + ivec2(t % si, t / si);
      value = irradianceTexels[pcIrradianceIndex(o) + f % 3];
    } else if (f < PC_PACKED_IRRADIANCE + PC_PACKED_DEPTH) {
      f -= PC_PACKED_IRRADIANCE;
      int t = f / 2;
      ivec2 o = pcAtlasTileOrigin(c, slot, sd) + ivec2(t % sd, t / sd);
      value = depthTexels[pcDepthIndex(o) + f % 2];
    } else {
      int t = f - PC_PACKED_IRRADIANCE - PC_PACKED_DEPTH;
      ivec2 o = pcAtlasTileOrigin(c, slot, so) + ivec2(t % so, t / so);
      value = occlusionTexels[pcOcclusionIndex(o)];
    }
    packed[outBase + uint(e)] = value;
  }
}
