// Deterministically directed layered depth maps (LDMs, after Aalund, Frisvad and Baerentzen):
// the occlusion-field tracer of GPUs without ray tracing (server/ldm_occlusion.cpp,
// shaders/ldm_*.comp, docs/LDM.md).
//
// An LDM is an orthographic view of the scene along one fixed direction d over a square of
// `resolution`^2 pixels that covers the field's bounds; each pixel keeps EVERY surface its
// centre line crosses (a per-pixel linked list of depths along d, filled by a compute
// rasterizer with atomics), sorted by depth afterwards. A probe's visibility along +d and -d
// within d_max is then one walk of the pixel it projects into: a surface lies within d_max
// ahead or behind it, or not. `directions` LDMs along an equal-area (Fibonacci) set of the +z
// hemisphere, each traced both ways, give 2 x directions fixed directions over the sphere: the
// same set for every probe and every update, so the occlusion they give has no noise to
// filter (it is exact for those directions, up to the pixel's offset from the probe).
#ifndef PC_LDM_H
#define PC_LDM_H

#include "pc_interop.h"

PC_BEGIN

// A node's `next` holds the next node's index in its low 30 bits (PC_LDM_NONE at the list's
// end) and the layer's facing in the top two: the tracers count a backface hit as blocked at
// any distance (its distance is stored negative, and "open" is distance > d_max), so a layer
// records which way along the LDM's direction a line meets its back.
PC_CONST uint PC_LDM_NONE = 0x3fffffffu;         // end of a pixel's list (and the index mask)
PC_CONST uint PC_LDM_BACK_AHEAD = 0x80000000u;   // a line along +d meets this layer's back
PC_CONST uint PC_LDM_BACK_BEHIND = 0x40000000u;  // a line along -d meets this layer's back
PC_CONST int PC_LDM_RASTER_THREADS = 64;         // ldm_raster.comp: a (triangle, direction) each
PC_CONST int PC_LDM_SORT_THREADS = 64;           // ldm_sort.comp: a pixel each
// ldm_sort.comp sorts lists up to this long in registers; longer ones (rare: that many surfaces
// on one line across the field) are sorted in place in the node buffer, slower but complete.
PC_CONST int PC_LDM_SORT_LOCAL = 48;
PC_CONST int PC_LDM_MAX_DIRECTIONS = 1024;
// ldm_occlusion.comp: a workgroup per probe, a thread per occlusion texel (PC_OCCLUSION_TEXELS^2).
PC_CONST int PC_LDM_TRACE_THREADS = 64;
PC_CONST int PC_LDM_MAX_PROBES_PER_DISPATCH = 65535;

// Descriptor bindings of the three passes (one set layout for all).
PC_CONST int PC_LDM_BIND_TRIANGLES = 0;
PC_CONST int PC_LDM_BIND_HEADS = 1;
PC_CONST int PC_LDM_BIND_NODES = 2;
PC_CONST int PC_LDM_BIND_COUNTERS = 3;
PC_CONST int PC_LDM_BIND_PROBES = 4;
PC_CONST int PC_LDM_BIND_TILES = 5;
PC_CONST int PC_LDM_BINDINGS = 6;

// Push constants of every pass.
struct LdmParams {
  vec3 center;       // the square's centre (and depth 0) in every LDM
  float halfExtent;  // half the square's side, metres: the bounds' bounding sphere radius
  // -- 16
  int resolution;     // pixels a side (a multiple of 8)
  int directions;     // LDMs
  uint nodeCapacity;  // nodes the node buffer holds
  int triangleCount;
  // -- 32
  int probeBase;  // ldm_occlusion.comp: the first probe of this dispatch
  int probeCount;
  float dmax;  // occlusion distance, metres
  int pad0;
};

struct LdmTriangle {
  vec4 p0, p1, p2;  // world space; p0.w 1: both sides are surface (cut-outs), else 0
};

struct LdmNode {
  float depth;  // along the LDM's direction, from its centre
  uint next;    // the next node of the pixel's list and the layer's facing (see above)
};

// The counters: nodes appended (may pass the capacity: then the build grows it and runs
// again), the most layers a pixel holds, pixels sorted in place (over PC_LDM_SORT_LOCAL).
struct LdmCounters {
  uint nodeCount;
  uint maxLayers;
  uint longLists;
  uint pad0;
};

// Direction i of n: an equal-area Fibonacci set of the +z hemisphere (z = (i + 0.5) / n is
// uniform in z, hence in area; the azimuth steps by the golden angle). With each LDM traced
// along +d and -d, the 2n directions cover the sphere evenly and symmetrically.
PC_FN vec3 pcLdmDirection(int i, int n) {
  float z = (float(i) + 0.5f) / float(n);
  float r = sqrt(max(0.0f, 1.0f - z * z));
  float phi = 2.39996323f * float(i);  // pi (3 - sqrt 5)
  return vec3(r * cos(phi), r * sin(phi), z);
}

// An orthonormal basis (t, b) around unit d, d.z > -1 (Frisvad's, as revised by Duff et al.).
PC_FN void pcLdmBasis(vec3 d, PC_INOUT(vec3) t, PC_INOUT(vec3) b) {
  float s = d.z >= 0.0f ? 1.0f : -1.0f;
  float a = -1.0f / (s + d.z);
  float c = d.x * d.y * a;
  t = vec3(1.0f + s * d.x * d.x * a, s * c, -s * d.x);
  b = vec3(c, s + d.y * d.y * a, -d.y);
}

// World point p in LDM `i` of `p`: continuous pixel coordinates (pixel centres at k + 0.5) and
// the depth along the LDM's direction.
PC_FN vec3 pcLdmProject(PC_IN(LdmParams) params, vec3 d, vec3 t, vec3 b, vec3 p) {
  vec3 q = p - params.center;
  float scale = float(params.resolution) / (2.0f * params.halfExtent);
  return vec3((dot(q, t) + params.halfExtent) * scale, (dot(q, b) + params.halfExtent) * scale,
              dot(q, d));
}

PC_END

#endif
