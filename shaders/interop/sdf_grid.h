// The distance field of the SDF tracer (server/vulkan_tracer_sdf.cpp, shaders/sdf_*.comp):
// a sparse grid of unsigned distances to the scene's triangles, with the nearest triangle of
// each sample, built on the GPU and sphere-traced by the probe and shadow rays of a compute
// device without ray tracing.
//
// Layout: a coarse grid of cells (PC_SDF_BRICK_CELLS voxels of `voxel` metres a side) over the
// scene's bounds, within a probe spacing of its probe volumes where it has some. A cell within
// `band` + its half diagonal of a triangle (measured from its centre) is "near" and owns a brick:
// (PC_SDF_BRICK_CELLS + 1)^3 samples on its voxel corners (the faces shared with the neighbours are
// stored twice, so a brick interpolates alone). Each sample holds min(distance, band) to the
// nearest triangle and that triangle (PC_SDF_NO_TRIANGLE where none is within the band), and the
// nearest triangle that is no cut-out. Every other cell holds a lower bound of the distance from
// any of its points to any triangle (its centre's distance less its half diagonal, above the band)
// and no brick. Distances are unsigned: a hit's side comes from its triangle's winding, as for the
// ray-tracing backend, so probes inside walls see backfaces alike.
#ifndef PC_SDF_GRID_H
#define PC_SDF_GRID_H

#include "pc_interop.h"

PC_BEGIN

PC_CONST int PC_SDF_BRICK_CELLS = 8;                      // voxels a brick side
PC_CONST int PC_SDF_BRICK_SIDE = PC_SDF_BRICK_CELLS + 1;  // samples a brick side
PC_CONST int PC_SDF_BRICK_SAMPLES = PC_SDF_BRICK_SIDE * PC_SDF_BRICK_SIDE * PC_SDF_BRICK_SIDE;
PC_CONST uint PC_SDF_NO_TRIANGLE = 0xffffffffu;
PC_CONST int PC_SDF_NO_BRICK = -1;
PC_CONST int PC_SDF_CELL_THREADS = 64;    // sdf_cells.comp: a workgroup per cell
PC_CONST int PC_SDF_BRICK_THREADS = 128;  // sdf_bricks.comp: a workgroup per cell
PC_CONST int PC_SDF_TRACE_THREADS = 64;   // sdf_trace.comp, sdf_shadow.comp: a ray each

// The grid's header, at the start of the grid buffer (PC_BIND_SDF_GRID), cells after it.
struct SdfHeader {
  vec3 origin;  // the grid's lowest corner
  float voxel;  // a voxel's side (metres)
  // -- 16
  ivec3 cells;        // coarse cells per axis
  int brickCapacity;  // bricks the brick buffer holds
  // -- 32
  float band;         // samples hold min(distance, band)
  int triangleCount;  // SdfTriangle entries
  uint brickCount;    // bricks allocated so far (may pass the capacity: then grown)
  int update;         // 1: an update after instances moved (see below); 0: a whole build
  // -- 48
  // An update keeps the bricks of cells that stay near and refills only those of cells whose
  // centre lies within the band plus the half diagonal of [dirtyLo, dirtyHi] (the moved
  // triangles' old and new bounds): no other sample's distance can change. Cells that become near
  // take new bricks past brickCount; bricks of cells no longer near stay unused until the next
  // whole build.
  vec3 dirtyLo;
  uint bricksBuilt;  // bricks the brick pass filled (counted by it)
  // -- 64
  vec3 dirtyHi;
  // Triangles that reach outside the grid (a ground plane past the probe volumes, an
  // instance moved out): every ray tests them all (PC_BIND_SDF_OUTSIDE lists them).
  int outsideCount;
  // -- 80
  uint listCount;    // triangle references the brick pass wrote (may pass the capacity)
  int listCapacity;  // references the list buffer holds after its brick ranges
  int pad0;
  int pad1;
  // -- 96
};

// Each brick's cell's triangles (PC_BIND_SDF_LISTS): words 2b and 2b + 1 are brick b's first
// reference and count (PC_SDF_LIST_OVERFLOW: more than PC_SDF_MAX_CELL_TRIANGLES), then from
// word 2 x brickCapacity the references. A cell lists every triangle within its half diagonal
// of its centre: all that touch it. Near a surface the tracer tests the ray against the whole
// list once and, without a hit, leaves the cell: no triangle is missed for not being a
// sample's nearest.
PC_CONST int PC_SDF_MAX_CELL_TRIANGLES = 2048;
PC_CONST uint PC_SDF_LIST_OVERFLOW = 0xffffffffu;

struct SdfCell {
  float distance;  // no brick: lower bound of the distance from the cell to any triangle
  int brick;       // PC_SDF_NO_BRICK or the brick's index
};

struct SdfSample {
  float distance;  // min(distance to the nearest triangle, band)
  uint triangle;   // that triangle (SdfTriangle index) or PC_SDF_NO_TRIANGLE
  // The nearest triangle that is no cut-out, where it is not `triangle` and lies within the
  // band: a ray through a cut-out's open texel meets what lies just behind it, which need not
  // be the nearest triangle of any sample (a block's top 5 mm under a grille).
  uint opaque;
};

// A triangle in world space with its shading record, as a probe ray's hit reports it.
struct SdfTriangle {
  vec3 p0;
  int record;  // shading record (GpuInstance index)
  // -- 16
  vec3 p1;
  int primitive;  // triangle of the record's mesh
  // -- 32
  vec3 p2;
  int cutOut;  // 1: the material is a cut-out (alpha-tested at hits)
  // -- 48
};

PC_FN float pcSdfCellSize(PC_IN(SdfHeader) h) { return h.voxel * float(PC_SDF_BRICK_CELLS); }
PC_FN int pcSdfCellIndex(PC_IN(SdfHeader) h, ivec3 c) {
  return (c.z * h.cells.y + c.y) * h.cells.x + c.x;
}
PC_FN ivec3 pcSdfCellCoord(PC_IN(SdfHeader) h, int index) {
  return ivec3(index % h.cells.x, (index / h.cells.x) % h.cells.y, index / (h.cells.x * h.cells.y));
}
PC_FN vec3 pcSdfCellCentre(PC_IN(SdfHeader) h, ivec3 c) {
  return h.origin + (vec3(c) + vec3(0.5f)) * pcSdfCellSize(h);
}
// Half the diagonal of a cell: how far its centre is from its farthest point.
PC_FN float pcSdfCellRadius(PC_IN(SdfHeader) h) { return 0.8660254f * pcSdfCellSize(h); }
// Sample (x, y, z) of brick `brick`, each in [0, PC_SDF_BRICK_SIDE).
PC_FN int pcSdfSampleIndex(int brick, ivec3 s) {
  return brick * PC_SDF_BRICK_SAMPLES + (s.z * PC_SDF_BRICK_SIDE + s.y) * PC_SDF_BRICK_SIDE + s.x;
}
// Where sample s of cell c lies.
PC_FN vec3 pcSdfSamplePosition(PC_IN(SdfHeader) h, ivec3 c, ivec3 s) {
  return h.origin + vec3(c * PC_SDF_BRICK_CELLS + s) * h.voxel;
}

// The point of triangle (a, b, c) nearest to p (Ericson, Real-Time Collision Detection 5.1.5).
PC_FN vec3 pcClosestPointOnTriangle(vec3 p, vec3 a, vec3 b, vec3 c) {
  vec3 ab = b - a, ac = c - a, ap = p - a;
  float d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0.0f && d2 <= 0.0f) return a;
  vec3 bp = p - b;
  float d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0.0f && d4 <= d3) return b;
  float vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0f && d1 >= 0.0f && d3 <= 0.0f) return a + ab * (d1 / (d1 - d3));
  vec3 cp = p - c;
  float d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0.0f && d5 <= d6) return c;
  float vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0f && d2 >= 0.0f && d6 <= 0.0f) return a + ac * (d2 / (d2 - d6));
  float va = d3 * d6 - d5 * d4;
  if (va <= 0.0f && (d4 - d3) >= 0.0f && (d5 - d6) >= 0.0f)
    return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
  float denom = 1.0f / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

PC_FN float pcPointTriangleDistance(vec3 p, vec3 a, vec3 b, vec3 c) {
  return length(p - pcClosestPointOnTriangle(p, a, b, c));
}

// Ray (o, d) against triangle (a, b, c), both faces (Moller-Trumbore): x = t, y, z = the
// barycentrics of b and c (a probe ray's hit record); t < 0 where the ray's line misses.
PC_FN vec3 pcRayTriangle(vec3 o, vec3 d, vec3 a, vec3 b, vec3 c) {
  vec3 e1 = b - a, e2 = c - a;
  vec3 pv = cross(d, e2);
  float det = dot(e1, pv);
  if (abs(det) < 1e-20f) return vec3(-1.0f, 0.0f, 0.0f);
  float inv = 1.0f / det;
  vec3 tv = o - a;
  float u = dot(tv, pv) * inv;
  if (u < 0.0f || u > 1.0f) return vec3(-1.0f, 0.0f, 0.0f);
  vec3 qv = cross(tv, e1);
  float v = dot(d, qv) * inv;
  if (v < 0.0f || u + v > 1.0f) return vec3(-1.0f, 0.0f, 0.0f);
  return vec3(dot(e2, qv) * inv, u, v);
}

PC_END

#ifdef __cplusplus
static_assert(sizeof(pc::gpu::SdfHeader) == 96);
static_assert(sizeof(pc::gpu::SdfCell) == 8);
static_assert(sizeof(pc::gpu::SdfSample) == 12);
static_assert(sizeof(pc::gpu::SdfTriangle) == 48);
#endif

#endif
