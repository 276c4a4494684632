// What a probe ray's closest-hit shader hands back to the ray generation shader, which stores
// it for the shade pass (interop/gpu_trace.h: GpuHit).
#ifndef PC_PROBE_TRACE_PAYLOAD_GLSL
#define PC_PROBE_TRACE_PAYLOAD_GLSL

#include "interop/gpu_trace.h"

struct HitPayload {
  vec2 barycentric;
  float t;
  int instance;  // shading record (GpuInstance); -1: miss
  int primitive;
};

#endif
