#version 460
// Compute rasterizer, tile pass: one workgroup per tile job covers the pixels of a
// PC_RASTER_TILE^2 tile that lie in its triangle's bounds (client_raster.comp made the jobs).
#extension GL_GOOGLE_include_directive : require
#include "client_common.glsl"

layout(local_size_x = PC_RASTER_TILE_GROUP) in;
layout(constant_id = 0) const int SAMPLES = 4;
layout(constant_id = 1) const int TEXTURE_COUNT = 1;
layout(constant_id = 3) const bool CUT_OUTS = false;  // any cut-out material in the scene
#include "client_surface.glsl"
#include "client_raster.glsl"

layout(set = 0, binding = PC_CLIENT_BIND_RASTER_TRIANGLES, std430) readonly buffer TriangleBlock {
  RasterTriangle rasterTriangles[];
};
layout(set = 0, binding = PC_CLIENT_BIND_RASTER_JOBS, std430) readonly buffer JobBlock { uvec2 jobs[]; };
layout(set = 0, binding = PC_CLIENT_BIND_RASTER_COUNTERS, std430) readonly buffer CounterBlock {
  RasterCounters counters;
};

void main() {
  uint job = gl_WorkGroupID.y * uint(PC_RASTER_MAX_GROUPS) + gl_WorkGroupID.x;
  if (job >= counters.dispatch.w) return;
  uvec2 entry = jobs[job];
  if (entry.x == ~0u) return;  // a dropped triangle's job (client_raster.comp)
  RasterTriangle r = rasterTriangles[entry.x];
  ScreenTriangle t;
  t.a = r.ab.xy;
  t.b = r.ab.zw;
  t.c = r.cIdView.xy;
  t.id = uint(r.cIdView.z);
  t.view = r.cIdView.w;
  t.depth = r.depth.xyz;
  t.invArea = r.depth.w;
  t.cutOutDraw = cutOutDrawOf(t.id);
  ivec2 lo, hi;
  pixelBounds(t, lo, hi);
  ivec2 tile = ivec2(int(entry.y & 0xFFFFu), int(entry.y >> 16)) * PC_RASTER_TILE;
  lo = max(lo, tile);
  hi = min(hi, tile + PC_RASTER_TILE - 1);
  const int kPixels = PC_RASTER_TILE * PC_RASTER_TILE;
  for (int i = int(gl_LocalInvocationID.x); i < kPixels; i += PC_RASTER_TILE_GROUP) {
    ivec2 pixel = tile + ivec2(i % PC_RASTER_TILE, i / PC_RASTER_TILE);
    if (all(greaterThanEqual(pixel, lo)) && all(lessThanEqual(pixel, hi))) coverPixel(t, pixel);
  }
}
