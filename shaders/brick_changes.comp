#version 460
// Change detection: a brick changed when any of its requested probes changed by more than the
// threshold. Each changed brick is listed once; the list's length is the x of the dispatch
// arguments that size brick_pack.comp. Flags and count are cleared before each update.
#extension GL_GOOGLE_include_directive : require
#include "interop/gpu_trace.h"

layout(local_size_x = 64) in;

layout(std430, set = 0, binding = PC_BIND_PARAMS) readonly buffer Params { UpdateParams params; };
layout(std430, set = 0, binding = PC_BIND_REQUESTS) readonly buffer Requests { ivec2 requests[]; };
layout(std430, set = 0, binding = PC_BIND_CHANGES) readonly buffer Changes { float changes[]; };
layout(std430, set = 0, binding = PC_BIND_BRICK_FLAGS) buffer BrickFlags { uint brickFlags[]; };
layout(std430, set = 0, binding = PC_BIND_BRICK_LIST) buffer BrickList { uint brickList[]; };

void main() {
  int p = int(gl_GlobalInvocationID.x);
  if (p >= params.probeCount || !(changes[p] > params.changeThreshold)) return;
  ivec2 ref = requests[p];
  uint brick = uint(params.cascadeBrickOffset[ref.x] + ref.y / PC_PROBES_PER_BRICK);
  if (atomicExchange(brickFlags[brick], 1u) != 0u) return;
  uint index = atomicAdd(brickList[0], 1u);
  brickList[PC_BRICK_LIST_HEADER + index] = brick;
}
