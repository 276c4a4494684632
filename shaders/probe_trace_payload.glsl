// What a probe ray's closest-hit shader hands back to the ray generation shader, which does
// the shading (one trace depth: shadow rays start from ray generation too).
#ifndef PC_PROBE_TRACE_PAYLOAD_GLSL
#define PC_PROBE_TRACE_PAYLOAD_GLSL

#include "interop/gpu_trace.h"

struct HitPayload {
  vec2 barycentric;
  float t;
  int instance;  // shading record (GpuInstance); -1: miss
  int primitive;
};

// Request and ray of launch index `id` (gpu_trace.h: PC_TRACE_TILE_PROBES), relative to a
// launch of `probeCount` requests of `rayCount` rays.
ivec2 pcLaunchProbeRay(uint id, int probeCount, int rayCount) {
  uint tileRays = uint(PC_TRACE_TILE_PROBES * rayCount);
  int tile = int(id / tileRays);
  int first = tile * PC_TRACE_TILE_PROBES;
  uint tileProbes = uint(min(PC_TRACE_TILE_PROBES, probeCount - first));
  uint within = id - uint(tile) * tileRays;
  return ivec2(first + int(within % tileProbes), int(within / tileProbes));
}

#endif
