#version 460
// LDM build, pass 2 (interop/ldm.h): sorts each pixel's list by depth, nearest (lowest along
// the direction) first, so that the trace stops walking once it is past d_max. The depths are
// rewritten along the list's own links (the nodes stay where the rasterizer put them). Lists up
// to PC_LDM_SORT_LOCAL long are sorted in registers; longer ones in place in the node buffer.
#extension GL_GOOGLE_include_directive : require
#include "interop/ldm.h"

layout(local_size_x = PC_LDM_SORT_THREADS) in;

layout(push_constant) uniform Push { LdmParams params; };
layout(std430, set = 0, binding = PC_LDM_BIND_HEADS) buffer Heads { uint heads[]; };
layout(std430, set = 0, binding = PC_LDM_BIND_NODES) buffer Nodes { LdmNode nodes[]; };
layout(std430, set = 0, binding = PC_LDM_BIND_COUNTERS) buffer Counters { LdmCounters counters; };

void main() {
  uint pixels = uint(params.resolution) * uint(params.resolution);
  if (gl_GlobalInvocationID.x >= pixels || int(gl_GlobalInvocationID.y) >= params.directions) return;
  uint pixel = gl_GlobalInvocationID.y * pixels + gl_GlobalInvocationID.x;
  // A layer is its depth and its facing bits: they move together.
  const uint facingBits = ~PC_LDM_NONE;
  float local[PC_LDM_SORT_LOCAL];
  uint facing[PC_LDM_SORT_LOCAL];
  uint count = 0u;
  uint node = heads[pixel];
  while (node != PC_LDM_NONE && count < uint(PC_LDM_SORT_LOCAL)) {
    local[count] = nodes[node].depth;
    facing[count++] = nodes[node].next & facingBits;
    node = nodes[node].next & PC_LDM_NONE;
  }
  if (node == PC_LDM_NONE) {
    for (uint i = 1u; i < count; ++i) {  // insertion sort: lists are short
      float v = local[i];
      uint f = facing[i];
      uint j = i;
      while (j > 0u && local[j - 1u] > v) {
        local[j] = local[j - 1u];
        facing[j] = facing[j - 1u];
        --j;
      }
      local[j] = v;
      facing[j] = f;
    }
    node = heads[pixel];
    for (uint i = 0u; i < count; ++i) {
      nodes[node].depth = local[i];
      nodes[node].next = (nodes[node].next & PC_LDM_NONE) | facing[i];
      node = nodes[node].next & PC_LDM_NONE;
    }
  } else {
    // A long list: selection sort along the links.
    atomicAdd(counters.longLists, 1u);
    count = 0u;
    for (uint a = heads[pixel]; a != PC_LDM_NONE; a = nodes[a].next & PC_LDM_NONE) {
      ++count;
      uint best = a;
      for (uint c = nodes[a].next & PC_LDM_NONE; c != PC_LDM_NONE; c = nodes[c].next & PC_LDM_NONE)
        if (nodes[c].depth < nodes[best].depth) best = c;
      float v = nodes[a].depth;
      uint fa = nodes[a].next & facingBits, fb = nodes[best].next & facingBits;
      nodes[a].depth = nodes[best].depth;
      nodes[best].depth = v;
      nodes[a].next = (nodes[a].next & PC_LDM_NONE) | fb;
      nodes[best].next = (nodes[best].next & PC_LDM_NONE) | fa;
    }
  }
  if (count > 0u) atomicMax(counters.maxLayers, count);
}
