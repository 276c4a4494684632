#version 460
// LDM build, pass 1 (interop/ldm.h): rasterizes every triangle into every LDM in compute, an
// invocation per (triangle, direction), appending a node to the list of each pixel whose centre
// the triangle covers. Compute, not the graphics pipeline: fragment-shader atomics, render
// passes and attachments are not needed, and the coverage rule is ours, so that a pixel centre
// on an edge two triangles share is counted exactly once (layer counts are exact). Edge
// functions are evaluated with the edge's end points in a canonical order (then negated),
// `precise`, so two triangles sharing an edge compute the very same value; a zero goes to one
// side only by a top-left rule.
#extension GL_GOOGLE_include_directive : require
#include "interop/ldm.h"

layout(local_size_x = PC_LDM_RASTER_THREADS) in;

layout(push_constant) uniform Push { LdmParams params; };
layout(std430, set = 0, binding = PC_LDM_BIND_TRIANGLES) readonly buffer Triangles { LdmTriangle triangles[]; };
layout(std430, set = 0, binding = PC_LDM_BIND_HEADS) buffer Heads { uint heads[]; };
layout(std430, set = 0, binding = PC_LDM_BIND_NODES) buffer Nodes { LdmNode nodes[]; };
layout(std430, set = 0, binding = PC_LDM_BIND_COUNTERS) buffer Counters { LdmCounters counters; };

float edgeFunction(vec2 a, vec2 b, vec2 q) {
  bool swapped = a.x > b.x || (a.x == b.x && a.y > b.y);
  vec2 lo = swapped ? b : a;
  vec2 hi = swapped ? a : b;
  precise float e = (hi.x - lo.x) * (q.y - lo.y) - (hi.y - lo.y) * (q.x - lo.x);
  return swapped ? -e : e;
}

// Whether q, with edge value e for edge a->b of a counter-clockwise triangle, is inside that
// edge: on the edge only for one of the two directions an edge can be walked in.
bool insideEdge(float e, vec2 a, vec2 b) {
  if (e != 0.0f) return e > 0.0f;
  vec2 d = b - a;
  return d.y > 0.0f || (d.y == 0.0f && d.x < 0.0f);
}

void main() {
  int tri = int(gl_GlobalInvocationID.x);
  int dir = int(gl_GlobalInvocationID.y);
  if (tri >= params.triangleCount || dir >= params.directions) return;
  vec3 d = pcLdmDirection(dir, params.directions), t, b;
  pcLdmBasis(d, t, b);
  LdmTriangle tr = triangles[tri];
  vec3 a3 = pcLdmProject(params, d, t, b, tr.p0.xyz);
  vec3 b3 = pcLdmProject(params, d, t, b, tr.p1.xyz);
  vec3 c3 = pcLdmProject(params, d, t, b, tr.p2.xyz);
  vec2 pa = a3.xy, pb = b3.xy, pc = c3.xy;
  // Which way along d a line meets the triangle's back (its winding's normal, as the tracers
  // take it); neither for a two-sided one.
  float facing = dot(cross(tr.p1.xyz - tr.p0.xyz, tr.p2.xyz - tr.p0.xyz), d);
  uint back = tr.p0.w != 0.0f ? 0u : (facing > 0.0f ? PC_LDM_BACK_AHEAD : PC_LDM_BACK_BEHIND);
  float area = edgeFunction(pa, pb, pc);
  if (area == 0.0f) return;  // edge-on along d: it covers no pixel centre
  if (area < 0.0f) {         // counter-clockwise, whichever side faces d
    vec3 s3 = b3;
    b3 = c3;
    c3 = s3;
    pb = b3.xy;
    pc = c3.xy;
    area = -area;
  }
  int n = params.resolution;
  vec2 lo = min(pa, min(pb, pc)), hi = max(pa, max(pb, pc));
  int x0 = max(0, int(ceil(lo.x - 0.5f))), x1 = min(n - 1, int(floor(hi.x - 0.5f)));
  int y0 = max(0, int(ceil(lo.y - 0.5f))), y1 = min(n - 1, int(floor(hi.y - 0.5f)));
  uint base = uint(dir) * uint(n) * uint(n);
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      vec2 q = vec2(float(x) + 0.5f, float(y) + 0.5f);
      float ea = edgeFunction(pb, pc, q);  // opposite a: a's barycentric weight
      float eb = edgeFunction(pc, pa, q);
      float ec = edgeFunction(pa, pb, q);
      if (!insideEdge(ea, pb, pc) || !insideEdge(eb, pc, pa) || !insideEdge(ec, pa, pb)) continue;
      float depth = (ea * a3.z + eb * b3.z + ec * c3.z) / area;
      uint node = atomicAdd(counters.nodeCount, 1u);
      if (node >= params.nodeCapacity) continue;  // counted: the build grows the buffer, runs again
      nodes[node].depth = depth;
      nodes[node].next = atomicExchange(heads[base + uint(y * n + x)], node) | back;
    }
  }
}
