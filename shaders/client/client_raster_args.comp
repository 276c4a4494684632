#version 460
// Compute rasterizer: the tile pass's indirect workgroup counts from the jobs the triangle
// pass appended (two dimensions: one may hold at most PC_RASTER_MAX_GROUPS).
#extension GL_GOOGLE_include_directive : require
#include "client_common.glsl"

layout(local_size_x = 1) in;
layout(set = 0, binding = PC_CLIENT_BIND_RASTER_COUNTERS, std430) buffer CounterBlock {
  RasterCounters counters;
};

void main() {
  uint jobs = min(counters.jobs, frame.rasterJobCapacity);
  uint perRow = uint(PC_RASTER_MAX_GROUPS);
  counters.dispatch = uvec4(min(jobs, perRow), (jobs + perRow - 1u) / perRow, 1u, jobs);
}
