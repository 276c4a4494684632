#version 460
// The SDF build's first pass (interop/sdf_grid.h): one workgroup per coarse cell finds the
// distance from the cell's centre to the nearest triangle, every thread a share of the
// triangles. A cell within the band (plus its half diagonal) of a triangle is near: it takes a
// brick, which sdf_bricks.comp fills; any other keeps a lower bound of the distance from each
// of its points to the surface (the centre's distance less the half diagonal), which the
// tracer steps across in one go. Brute force over the triangles: every cell costs one pass over
// them, cheap beside the bricks' samples, and it needs no structure of its own. An update
// (SdfHeader::update) runs it over every cell too: a moved instance changes the bounds of
// empty cells anywhere.
#extension GL_GOOGLE_include_directive : require
#include "interop/gpu_trace.h"
#include "interop/sdf_grid.h"

layout(local_size_x = PC_SDF_CELL_THREADS) in;

layout(std430, set = 0, binding = PC_BIND_SDF_GRID) buffer Grid { SdfHeader sdf; SdfCell cells[]; };
layout(std430, set = 0, binding = PC_BIND_SDF_TRIANGLES) readonly buffer Triangles { SdfTriangle triangles[]; };

shared float nearest[PC_SDF_CELL_THREADS];

void main() {
  int cell = int(gl_WorkGroupID.y * uint(PC_DISPATCH_ROWS) + gl_WorkGroupID.x);
  int cellCount = sdf.cells.x * sdf.cells.y * sdf.cells.z;
  if (cell >= cellCount) return;  // uniform over the workgroup
  vec3 centre = pcSdfCellCentre(sdf, pcSdfCellCoord(sdf, cell));
  float best = 3.0e38f;
  for (int i = int(gl_LocalInvocationID.x); i < sdf.triangleCount; i += PC_SDF_CELL_THREADS) {
    SdfTriangle t = triangles[i];
    // The triangle's bounding sphere first: most triangles are far from most cells.
    vec3 mid = (t.p0 + t.p1 + t.p2) * (1.0f / 3.0f);
    float radius = sqrt(max(max(dot(t.p0 - mid, t.p0 - mid), dot(t.p1 - mid, t.p1 - mid)),
                            dot(t.p2 - mid, t.p2 - mid)));
    if (length(centre - mid) - radius >= best) continue;
    best = min(best, pcPointTriangleDistance(centre, t.p0, t.p1, t.p2));
  }
  nearest[gl_LocalInvocationID.x] = best;
  barrier();
  for (uint s = uint(PC_SDF_CELL_THREADS) / 2u; s > 0u; s >>= 1u) {
    if (gl_LocalInvocationID.x < s)
      nearest[gl_LocalInvocationID.x] = min(nearest[gl_LocalInvocationID.x], nearest[gl_LocalInvocationID.x + s]);
    barrier();
  }
  if (gl_LocalInvocationID.x != 0u) return;
  float d = nearest[0];
  float radius = pcSdfCellRadius(sdf);
  if (d <= radius + sdf.band) {
    // An update keeps a cell's brick (sdf_bricks.comp refills it where the change reaches).
    int kept = sdf.update != 0 ? cells[cell].brick : PC_SDF_NO_BRICK;
    cells[cell] = SdfCell(0.0f, kept >= 0 ? kept : int(atomicAdd(sdf.brickCount, 1u)));
  } else {
    cells[cell] = SdfCell(d - radius, PC_SDF_NO_BRICK);
  }
}
