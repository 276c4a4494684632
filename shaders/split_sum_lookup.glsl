// The split-sum table's (A, B) at (N.V, roughness), bilinear, as common/split_sum_table.cpp
// lookupSplitSum reads it, from the copy a shader was given packed two entries to a vec4
// (entry e in pair e / 2, .xy when e is even, .zw when odd). The includer defines
// PC_SPLIT_SUM_PAIR(p), the vec4 of pair p, before including this file.
#ifndef PC_SPLIT_SUM_LOOKUP_GLSL
#define PC_SPLIT_SUM_LOOKUP_GLSL

#include "interop/specular_probe.h"

vec2 splitSumEntry(int i, int j) {
  int e = i + PC_SPLIT_SUM_SIZE * j;
  vec4 pair = PC_SPLIT_SUM_PAIR(e >> 1);
  return (e & 1) == 0 ? pair.xy : pair.zw;
}

vec2 splitSumAt(float NdotV, float roughness) {
  vec2 c = pcSplitSumCoord(NdotV, roughness);
  ivec2 c0 = min(ivec2(c), ivec2(PC_SPLIT_SUM_SIZE - 2));
  vec2 t = c - vec2(c0);
  return mix(mix(splitSumEntry(c0.x, c0.y), splitSumEntry(c0.x + 1, c0.y), t.x),
             mix(splitSumEntry(c0.x, c0.y + 1), splitSumEntry(c0.x + 1, c0.y + 1), t.x), t.y);
}

#endif
