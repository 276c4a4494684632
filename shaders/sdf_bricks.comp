#version 460
// The SDF build's second pass (interop/sdf_grid.h): one workgroup per near cell fills its
// brick's samples with min(distance, band) to the nearest triangle and that triangle. The
// workgroup walks the triangles a chunk at a time; those within the band of some sample (the
// band plus the brick's half diagonal from its centre) go to a shared list, against which each
// thread measures its samples. A triangle nearer to a sample than the band is always listed,
// so samples within the band are exact; the others hold the band, a lower bound.
#extension GL_GOOGLE_include_directive : require
#include "interop/gpu_trace.h"
#include "interop/sdf_grid.h"

layout(local_size_x = PC_SDF_BRICK_THREADS) in;

layout(std430, set = 0, binding = PC_BIND_SDF_GRID) buffer Grid { SdfHeader sdf; SdfCell cells[]; };
layout(std430, set = 0, binding = PC_BIND_SDF_BRICKS) writeonly buffer Bricks { SdfSample samples[]; };
layout(std430, set = 0, binding = PC_BIND_SDF_TRIANGLES) readonly buffer Triangles { SdfTriangle triangles[]; };
layout(std430, set = 0, binding = PC_BIND_SDF_LISTS) writeonly buffer Lists { uint lists[]; };

const int kSamplesPerThread = (PC_SDF_BRICK_SAMPLES + PC_SDF_BRICK_THREADS - 1) / PC_SDF_BRICK_THREADS;

shared vec3 listed[3 * PC_SDF_BRICK_THREADS];
shared uint listedIndex[PC_SDF_BRICK_THREADS];
shared bool listedCutOut[PC_SDF_BRICK_THREADS];
shared uint listedCount;
// The triangles touching the cell (within its half diagonal of the centre), for its list.
shared uint cellTriangles[PC_SDF_MAX_CELL_TRIANGLES];
shared uint touching;
shared uint cellBase;

void main() {
  int cell = int(gl_WorkGroupID.y * uint(PC_DISPATCH_ROWS) + gl_WorkGroupID.x);
  int cellCount = sdf.cells.x * sdf.cells.y * sdf.cells.z;
  if (cell >= cellCount) return;
  int brick = cells[cell].brick;
  if (brick < 0 || brick >= sdf.brickCapacity) return;  // uniform over the workgroup
  ivec3 c = pcSdfCellCoord(sdf, cell);
  vec3 centre = pcSdfCellCentre(sdf, c);
  float reach = sdf.band + pcSdfCellRadius(sdf);
  uint lid = gl_LocalInvocationID.x;
  if (sdf.update != 0) {
    // Only cells whose centre lies within `reach` of the moved triangles' bounds: a sample
    // within the band of a moved triangle has its centre within `reach` of it, so elsewhere
    // no sample changed; and a cell turns near only with its centre within `reach` of a
    // triangle, so the new bricks are all here.
    if (any(lessThan(centre, sdf.dirtyLo - vec3(reach))) ||
        any(greaterThan(centre, sdf.dirtyHi + vec3(reach))))
      return;
  }
  if (lid == 0u) {
    atomicAdd(sdf.bricksBuilt, 1u);
    touching = 0u;
  }
  float radius = pcSdfCellRadius(sdf);

  vec3 position[kSamplesPerThread];
  float best[kSamplesPerThread], bestOpaque[kSamplesPerThread];
  uint bestTriangle[kSamplesPerThread], bestOpaqueTriangle[kSamplesPerThread];
  for (int k = 0; k < kSamplesPerThread; ++k) {
    int s = int(lid) + k * PC_SDF_BRICK_THREADS;
    ivec3 sc = ivec3(s % PC_SDF_BRICK_SIDE, (s / PC_SDF_BRICK_SIDE) % PC_SDF_BRICK_SIDE,
                     s / (PC_SDF_BRICK_SIDE * PC_SDF_BRICK_SIDE));
    position[k] = pcSdfSamplePosition(sdf, c, sc);
    best[k] = bestOpaque[k] = 3.0e38f;
    bestTriangle[k] = bestOpaqueTriangle[k] = PC_SDF_NO_TRIANGLE;
  }

  for (int first = 0; first < sdf.triangleCount; first += PC_SDF_BRICK_THREADS) {
    if (lid == 0u) listedCount = 0u;
    barrier();
    int i = first + int(lid);
    if (i < sdf.triangleCount) {
      SdfTriangle t = triangles[i];
      float d = pcPointTriangleDistance(centre, t.p0, t.p1, t.p2);
      if (d <= radius) {
        uint k = atomicAdd(touching, 1u);
        if (k < uint(PC_SDF_MAX_CELL_TRIANGLES)) cellTriangles[k] = uint(i);
      }
      if (d <= reach) {
        uint slot = atomicAdd(listedCount, 1u);
        listed[3u * slot] = t.p0;
        listed[3u * slot + 1u] = t.p1;
        listed[3u * slot + 2u] = t.p2;
        listedIndex[slot] = uint(i);
        listedCutOut[slot] = t.cutOut != 0;
      }
    }
    barrier();
    uint n = listedCount;
    for (uint j = 0u; j < n; ++j) {
      vec3 a = listed[3u * j], b = listed[3u * j + 1u], d = listed[3u * j + 2u];
      for (int k = 0; k < kSamplesPerThread; ++k) {
        float dist = pcPointTriangleDistance(position[k], a, b, d);
        // Ties go to the lower index, whatever order the list was filled in.
        if (dist < best[k] || (dist == best[k] && listedIndex[j] < bestTriangle[k])) {
          best[k] = dist;
          bestTriangle[k] = listedIndex[j];
        }
        if (!listedCutOut[j] &&
            (dist < bestOpaque[k] || (dist == bestOpaque[k] && listedIndex[j] < bestOpaqueTriangle[k]))) {
          bestOpaque[k] = dist;
          bestOpaqueTriangle[k] = listedIndex[j];
        }
      }
    }
    barrier();
  }
  // The cell's list: one allocation per brick; too many triangles, or a full buffer (the host
  // then grows it and builds again), leave the brick to the samples' nearest triangles.
  if (lid == 0u) {
    uint n = touching;
    uint base = PC_SDF_LIST_OVERFLOW;
    if (n <= uint(PC_SDF_MAX_CELL_TRIANGLES)) {
      base = atomicAdd(sdf.listCount, n);
      if (base + n > uint(sdf.listCapacity)) base = PC_SDF_LIST_OVERFLOW;
    }
    cellBase = base;
    lists[2 * brick] = base == PC_SDF_LIST_OVERFLOW ? 0u : base;
    lists[2 * brick + 1] = base == PC_SDF_LIST_OVERFLOW ? PC_SDF_LIST_OVERFLOW : n;
  }
  barrier();
  if (cellBase != PC_SDF_LIST_OVERFLOW)
    for (uint k = lid; k < touching; k += uint(PC_SDF_BRICK_THREADS))
      lists[2u * uint(sdf.brickCapacity) + cellBase + k] = cellTriangles[k];
  for (int k = 0; k < kSamplesPerThread; ++k) {
    int s = int(lid) + k * PC_SDF_BRICK_THREADS;
    if (s >= PC_SDF_BRICK_SAMPLES) continue;
    uint opaque = bestOpaque[k] <= sdf.band && bestOpaqueTriangle[k] != bestTriangle[k]
                      ? bestOpaqueTriangle[k] : PC_SDF_NO_TRIANGLE;
    samples[brick * PC_SDF_BRICK_SAMPLES + s] = SdfSample(min(best[k], sdf.band), bestTriangle[k], opaque);
  }
}
