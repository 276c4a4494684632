// Sphere tracing through the SDF tracer's distance field (interop/sdf_grid.h), shared by its
// probe rays (sdf_trace.comp) and shadow rays (sdf_shadow.comp). Stack-free, one loop:
//   - in a cell without a brick, the ray jumps to the farther of the cell's exit and its
//     distance bound (the whole cell is free of surfaces: the coarse grid's skip);
//   - in a brick, it steps by the trilinear distance less the largest error trilinear
//     interpolation of a 1-Lipschitz field can make (sqrt(3)/2 voxel), at least half a voxel;
//   - within two voxels of a surface it tests the ray, once per cell, against every triangle
//     touching the cell (the brick's list) with exact ray-triangle tests: the first hit inside
//     the cell, else it leaves the cell;
//   - in a cell whose list overflowed, it tests the nearest triangles of the voxel's eight
//     corners (in scenes with cut-outs also their nearest triangles that are no cut-out: what
//     lies behind an open texel) and stops at the nearest hit among them no farther than the
//     distance plus a voxel ahead. A hit behind the current point counts too: where a step
//     passed a surface, the next voxel's corners name its triangle.
// So hits are exact points on triangles with the triangle's own barycentrics, the record the
// ray-tracing backend writes. Cut-outs (kCutOuts) refuse hits on their open texels as the
// any-hit shader does (cutout_coverage.glsl). The includer declares the scene bindings
// cutout_coverage.glsl reads and kCutOuts.
#ifndef PC_SDF_TRACE_GLSL
#define PC_SDF_TRACE_GLSL

#include "interop/sdf_grid.h"
#include "cutout_coverage.glsl"

layout(std430, set = 0, binding = PC_BIND_SDF_GRID) readonly buffer Grid { SdfHeader sdf; SdfCell cells[]; };
layout(std430, set = 0, binding = PC_BIND_SDF_BRICKS) readonly buffer Bricks { SdfSample samples[]; };
layout(std430, set = 0, binding = PC_BIND_SDF_TRIANGLES) readonly buffer Triangles { SdfTriangle triangles[]; };
layout(std430, set = 0, binding = PC_BIND_SDF_OUTSIDE) readonly buffer Outside { uint outside[]; };
layout(std430, set = 0, binding = PC_BIND_SDF_LISTS) readonly buffer Lists { uint lists[]; };

// Steps a ray may take before it counts as a miss (a ray grazing a wall steps half a voxel).
const int kSdfMaxSteps = 2048;
// Within this many voxels of a surface the candidates are tested.
const float kSdfNearVoxels = 2.0f;
// The most trilinear interpolation overestimates a 1-Lipschitz field, in voxels: sqrt(3)/2.
const float kSdfInterpolationError = 0.8660254f;

struct SdfHit {
  float t;  // < 0: none
  vec2 barycentric;
  uint triangle;
};

// Exit distance of the ray from the box [lo, hi] (inv: 1 / direction).
float sdfBoxExit(vec3 o, vec3 inv, vec3 lo, vec3 hi) {
  vec3 a = (lo - o) * inv, b = (hi - o) * inv;
  vec3 far = max(a, b);
  return min(min(far.x, far.y), far.z);
}

// The first hit of ray (o, dir) in [tmin, tmax) on a triangle of the field.
SdfHit sdfTraceGrid(vec3 o, vec3 dir, float tmin, float tmax) {
  SdfHit hit = SdfHit(-1.0f, vec2(0.0f), PC_SDF_NO_TRIANGLE);
  vec3 safe = mix(dir, vec3(1e-30f), equal(dir, vec3(0.0f)));
  vec3 inv = 1.0f / safe;
  float cellSize = pcSdfCellSize(sdf);
  float h = sdf.voxel;
  vec3 lo = sdf.origin, hi = sdf.origin + vec3(sdf.cells) * cellSize;
  vec3 a = (lo - o) * inv, b = (hi - o) * inv;
  vec3 near = min(a, b), far = max(a, b);
  float t = max(tmin, max(max(near.x, near.y), near.z));
  float tEnd = min(tmax, min(min(far.x, far.y), far.z));
  float best = tmax;
  int listed = -1;  // the cell whose list the ray was last tested against
  for (int step = 0; step < kSdfMaxSteps && t <= tEnd; ++step) {
    vec3 p = o + t * dir;
    ivec3 c = clamp(ivec3(floor((p - lo) / cellSize)), ivec3(0), sdf.cells - 1);
    int cellIndex = pcSdfCellIndex(sdf, c);
    SdfCell cell = cells[cellIndex];
    vec3 cellLo = lo + vec3(c) * cellSize;
    if (cell.brick < 0) {
      t = max(t + cell.distance, sdfBoxExit(o, inv, cellLo, cellLo + vec3(cellSize)) + 0.01f * h);
      continue;
    }
    vec3 local = (p - cellLo) / h;
    ivec3 i0 = clamp(ivec3(floor(local)), ivec3(0), ivec3(PC_SDF_BRICK_CELLS - 1));
    vec3 f = clamp(local - vec3(i0), vec3(0.0f), vec3(1.0f));
    float d[8];
    uint tri[16];  // the corners' nearest triangles, then (cut-outs only) their nearest opaque
    for (int k = 0; k < 8; ++k) {
      SdfSample s = samples[pcSdfSampleIndex(cell.brick, i0 + ivec3(k & 1, (k >> 1) & 1, k >> 2))];
      d[k] = s.distance;
      tri[k] = s.triangle;
      tri[k + 8] = s.opaque;
    }
    float dist = mix(mix(mix(d[0], d[1], f.x), mix(d[2], d[3], f.x), f.y),
                     mix(mix(d[4], d[5], f.x), mix(d[6], d[7], f.x), f.y), f.z);
    if (dist <= kSdfNearVoxels * h && cellIndex != listed &&
        lists[2 * cell.brick + 1] != PC_SDF_LIST_OVERFLOW) {
      // Every triangle touching the cell, once: the first hit within the cell, or none in it.
      listed = cellIndex;
      float exitT = sdfBoxExit(o, inv, cellLo, cellLo + vec3(cellSize)) + 0.01f * h;
      uint first = 2u * uint(sdf.brickCapacity) + lists[2 * cell.brick];
      uint count = lists[2 * cell.brick + 1];
      for (uint k = 0u; k < count; ++k) {
        uint i = lists[first + k];
        SdfTriangle tr = triangles[i];
        vec3 r = pcRayTriangle(o, dir, tr.p0, tr.p1, tr.p2);
        if (!(r.x >= tmin && r.x < best && r.x <= exitT)) continue;
        if (kCutOuts && tr.cutOut != 0 && !pcCutOutCovered(tr.record, tr.primitive, vec2(r.y, r.z))) continue;
        best = r.x;
        hit = SdfHit(r.x, vec2(r.y, r.z), i);
      }
      if (hit.t >= 0.0f) return hit;
      t = exitT;
      continue;
    }
    if (dist <= kSdfNearVoxels * h && cellIndex != listed) {
      // A cell whose list overflowed: the nearest triangles of the voxel's corners.
      float window = t + dist + h;
      for (int k = 0; k < (kCutOuts ? 16 : 8); ++k) {
        uint i = tri[k];
        bool seen = i == PC_SDF_NO_TRIANGLE;
        for (int j = 0; j < k; ++j) seen = seen || tri[j] == i;
        if (seen) continue;
        SdfTriangle tr = triangles[i];
        vec3 r = pcRayTriangle(o, dir, tr.p0, tr.p1, tr.p2);
        if (!(r.x >= tmin && r.x < best && r.x <= window)) continue;
        if (kCutOuts && tr.cutOut != 0 && !pcCutOutCovered(tr.record, tr.primitive, vec2(r.y, r.z))) continue;
        best = r.x;
        hit = SdfHit(r.x, vec2(r.y, r.z), i);
      }
      if (hit.t >= 0.0f) return hit;
    }
    t += max(dist - kSdfInterpolationError * h, 0.5f * h);
  }
  return hit;
}

// The first hit of ray (o, dir) in [tmin, tmax): through the grid, and against each triangle
// that reaches outside it.
SdfHit sdfTrace(vec3 o, vec3 dir, float tmin, float tmax) {
  SdfHit hit = sdfTraceGrid(o, dir, tmin, tmax);
  float best = hit.t >= 0.0f ? hit.t : tmax;
  for (int k = 0; k < sdf.outsideCount; ++k) {
    uint i = outside[k];
    SdfTriangle tr = triangles[i];
    vec3 r = pcRayTriangle(o, dir, tr.p0, tr.p1, tr.p2);
    if (!(r.x >= tmin && r.x < best)) continue;
    if (kCutOuts && tr.cutOut != 0 && !pcCutOutCovered(tr.record, tr.primitive, vec2(r.y, r.z))) continue;
    best = r.x;
    hit = SdfHit(r.x, vec2(r.y, r.z), i);
  }
  return hit;
}

#endif
