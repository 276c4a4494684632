// What a probe ray's closest-hit shader hands back to the ray generation shader, which does
// the shading (one trace depth: shadow rays start from ray generation too).
#ifndef PC_PROBE_TRACE_PAYLOAD_GLSL
#define PC_PROBE_TRACE_PAYLOAD_GLSL

struct HitPayload {
  vec2 barycentric;
  float t;
  int instance;  // index into Scene::instances; -1: miss
  int primitive;
};

#endif
