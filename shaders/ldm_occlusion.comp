#version 460
// LDM occlusion trace (interop/ldm.h): a workgroup per probe. First every LDM tells whether
// the probe's line through it meets a surface within d_max ahead (+d) or behind (-d): one
// walk of the sorted list of the pixel the probe projects into. Then each thread, one per
// occlusion texel, weighs those 2 x directions answers by the texel's cosine lobe, as the
// tracers' blend weighs its rays (server/probe_blend.cpp): the cos-weighted share of
// directions that travel past d_max. A surface exactly at d_max still blocks, as a ray hit at
// d_max does ("open" is distance > d_max), and so does a first surface met from its back at any
// distance (the tracers store a backface hit's distance negative).
#extension GL_GOOGLE_include_directive : require
#include "interop/ldm.h"
#include "interop/probe_math.h"

layout(local_size_x = PC_LDM_TRACE_THREADS) in;

layout(push_constant) uniform Push { LdmParams params; };
layout(std430, set = 0, binding = PC_LDM_BIND_HEADS) readonly buffer Heads { uint heads[]; };
layout(std430, set = 0, binding = PC_LDM_BIND_NODES) readonly buffer Nodes { LdmNode nodes[]; };
layout(std430, set = 0, binding = PC_LDM_BIND_PROBES) readonly buffer Probes { vec4 probes[]; };
layout(std430, set = 0, binding = PC_LDM_BIND_TILES) writeonly buffer Tiles { float tiles[]; };

// Bit 2j: direction j is open along +d; bit 2j + 1: along -d.
shared uint openBits[PC_LDM_MAX_DIRECTIONS * 2 / 32];

void main() {
  int probe = params.probeBase + int(gl_WorkGroupID.x);
  uint tid = gl_LocalInvocationID.x;
  for (uint i = tid; i < uint(PC_LDM_MAX_DIRECTIONS * 2 / 32); i += uint(PC_LDM_TRACE_THREADS))
    openBits[i] = 0u;
  barrier();
  vec3 p = probes[probe].xyz;
  int n = params.resolution;
  for (int j = int(tid); j < params.directions; j += PC_LDM_TRACE_THREADS) {
    vec3 d = pcLdmDirection(j, params.directions), t, b;
    pcLdmBasis(d, t, b);
    vec3 q = pcLdmProject(params, d, t, b, p);
    int x = int(floor(q.x)), y = int(floor(q.y));
    // The first layer at or past the probe each way decides: open where there is none, or
    // where it lies beyond d_max and faces the probe.
    bool ahead = true, behind = true;
    if (x >= 0 && y >= 0 && x < n && y < n) {
      uint node = heads[uint(j) * uint(n) * uint(n) + uint(y * n + x)];
      while (node != PC_LDM_NONE) {
        float s = nodes[node].depth - q.z;  // signed distance along d
        uint link = nodes[node].next;
        if (s <= 0.0f)  // sorted: the last of these is the first behind the probe
          behind = -s > params.dmax && (link & PC_LDM_BACK_BEHIND) == 0u;
        if (s >= 0.0f) {  // the first ahead: nothing after it matters
          ahead = s > params.dmax && (link & PC_LDM_BACK_AHEAD) == 0u;
          break;
        }
        node = link & PC_LDM_NONE;
      }
    }
    uint bits = (ahead ? 1u : 0u) | (behind ? 2u : 0u);
    if (bits != 0u) atomicOr(openBits[(2 * j) / 32], bits << uint((2 * j) % 32));
  }
  barrier();
  vec3 w = pcTexelDirection(int(tid) % PC_OCCLUSION_TEXELS, int(tid) / PC_OCCLUSION_TEXELS,
                            PC_OCCLUSION_TEXELS);
  float open = 0.0f, total = 0.0f;
  for (int j = 0; j < params.directions; ++j) {
    float c = dot(w, pcLdmDirection(j, params.directions));
    uint bit = c >= 0.0f ? uint(2 * j) : uint(2 * j + 1);  // the half of the line in w's lobe
    float weight = abs(c);
    total += weight;
    if ((openBits[bit / 32u] & (1u << (bit % 32u))) != 0u) open += weight;
  }
  tiles[probe * PC_LDM_TRACE_THREADS + int(tid)] = total > 0.0f ? open / total : 1.0f;
}
