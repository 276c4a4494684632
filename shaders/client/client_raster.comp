#version 460
// Compute rasterizer, triangle pass: one thread per triangle id and view (grid-stride over the
// ids). Clips the triangle in clip space against the near plane and a guard band, projects
// and snaps the pieces to fixed point, covers pieces with small bounds itself and turns the
// others into tile jobs for client_raster_tiles.comp. Why compute: on GPUs with few graphics
// units (an H100) the fixed-function raster rate, not the bytes, bounds a visibility pass.
#extension GL_GOOGLE_include_directive : require
#include "client_common.glsl"

layout(local_size_x = PC_RASTER_GROUP) in;
layout(constant_id = 0) const int SAMPLES = 4;
layout(constant_id = 1) const int TEXTURE_COUNT = 1;
layout(constant_id = 3) const bool CUT_OUTS = false;  // any cut-out material in the scene
#include "client_surface.glsl"
#include "client_raster.glsl"

layout(set = 0, binding = PC_CLIENT_BIND_RASTER_TRIANGLES, std430) writeonly buffer TriangleBlock {
  RasterTriangle rasterTriangles[];
};
layout(set = 0, binding = PC_CLIENT_BIND_RASTER_JOBS, std430) writeonly buffer JobBlock { uvec2 jobs[]; };
layout(set = 0, binding = PC_CLIENT_BIND_RASTER_COUNTERS, std430) buffer CounterBlock {
  RasterCounters counters;
};

// Signed distance of clip-space point v to clip plane k (inside: >= 0). Plane 0 is the near
// plane (depth z / w <= 1, with z = near: w >= z); 1-4 the guard band |x|, |y| <= G w.
float planeDistance(vec4 v, int k) {
  if (k == 0) return v.w - v.z;
  if (k == 1) return PC_RASTER_GUARD * v.w - v.x;
  if (k == 2) return PC_RASTER_GUARD * v.w + v.x;
  if (k == 3) return PC_RASTER_GUARD * v.w - v.y;
  return PC_RASTER_GUARD * v.w + v.y;
}

const int kMaxPolygon = 9;  // 3 corners + one per clip plane

void emitTriangle(vec4 c0, vec4 c1, vec4 c2, uint id, int view, int cutOutDraw) {
  vec2 size = frame.viewport;
  vec4 corners[3] = vec4[](c0, c1, c2);
  ivec2 p[3];
  vec3 depth;
  for (int i = 0; i < 3; ++i) {
    vec2 ndc = corners[i].xy / corners[i].w;
    p[i] = ivec2(round((ndc * 0.5 + 0.5) * size * float(PC_RASTER_SUBPIXEL)));
    depth[i] = corners[i].z / corners[i].w;
  }
  ScreenTriangle t;
  int64_t area = edgeFunction(p[0], p[1], p[2]);
  if (area == 0) return;  // no area after snapping: covers no sample
  t.a = p[0];
  t.depth.x = depth[0];
  if (area > 0) {
    t.b = p[1]; t.c = p[2]; t.depth.yz = depth.yz;
  } else {
    t.b = p[2]; t.c = p[1]; t.depth.yz = depth.zy;
    area = -area;
  }
  t.invArea = 1.0 / float(area);
  t.id = id;
  t.view = view;
  t.cutOutDraw = cutOutDraw;
  ivec2 lo, hi;
  pixelBounds(t, lo, hi);
  if (any(lessThan(hi, lo))) return;
  ivec2 extent = hi - lo + 1;
  if (extent.x * extent.y <= PC_RASTER_SMALL) {
    for (int y = lo.y; y <= hi.y; ++y)
      for (int x = lo.x; x <= hi.x; ++x) coverPixel(t, ivec2(x, y));
    return;
  }
  ivec2 tileLo = lo / PC_RASTER_TILE, tileHi = hi / PC_RASTER_TILE;
  ivec2 tiles = tileHi - tileLo + 1;
  uint jobCount = uint(tiles.x * tiles.y);
  uint record = atomicAdd(counters.triangles, 1u);
  if (record >= frame.rasterTriangleCapacity) {
    atomicAdd(counters.dropped, 1u);
    return;
  }
  uint firstJob = atomicAdd(counters.jobs, jobCount);
  // Past the capacity the triangle is dropped, but the slots of its jobs that fit are still
  // written (as no-ops): the tile pass runs every slot below the capacity.
  bool fits = firstJob + jobCount <= frame.rasterJobCapacity;
  if (fits) {
    RasterTriangle r;
    r.ab = ivec4(t.a, t.b);
    r.cIdView = ivec4(t.c, int(id), view);
    r.depth = vec4(t.depth, t.invArea);
    rasterTriangles[record] = r;
  } else {
    atomicAdd(counters.dropped, 1u);
  }
  for (uint j = 0u; j < jobCount && firstJob + j < frame.rasterJobCapacity; ++j) {
    ivec2 tile = tileLo + ivec2(int(j % uint(tiles.x)), int(j / uint(tiles.x)));
    jobs[firstJob + j] = fits ? uvec2(record, (uint(tile.y) << 16) | uint(tile.x)) : uvec2(~0u);
  }
}

void rasterize(uint triangle, int view) {
  int drawIndex = drawOfTriangle(triangle);
  DrawData d = draws[drawIndex];
  if ((d.textures.z & (1 << view)) == 0) return;  // the draw is outside this view
  int cutOutDraw = CUT_OUTS && drawIsCutOut(d) ? drawIndex : -1;
  uint i0, i1, i2;
  triangleVertices(d, triangle, i0, i1, i2);
  mat4 toClip = frame.views[view].viewProj * d.model;
  vec4 polygon[kMaxPolygon];
  polygon[0] = toClip * vec4(vertexAt(i0).position, 1.0);
  polygon[1] = toClip * vec4(vertexAt(i1).position, 1.0);
  polygon[2] = toClip * vec4(vertexAt(i2).position, 1.0);
  int count = 3;
  for (int k = 0; k < 5; ++k) {
    float d0 = planeDistance(polygon[0], k), d1 = planeDistance(polygon[1], k),
          d2 = planeDistance(polygon[2], k);
    if (count == 3 && d0 >= 0.0 && d1 >= 0.0 && d2 >= 0.0) continue;  // the common case
    // Sutherland-Hodgman against plane k.
    vec4 clipped[kMaxPolygon];
    int n = 0;
    for (int i = 0; i < count; ++i) {
      vec4 u = polygon[i], v = polygon[(i + 1) % count];
      float du = planeDistance(u, k), dv = planeDistance(v, k);
      if (du >= 0.0 && n < kMaxPolygon) clipped[n++] = u;
      if ((du >= 0.0) != (dv >= 0.0) && n < kMaxPolygon) clipped[n++] = mix(u, v, du / (du - dv));
    }
    count = n;
    if (count < 3) return;
    for (int i = 0; i < count; ++i) polygon[i] = clipped[i];
  }
  uint id = triangle + 1u;
  for (int i = 1; i + 1 < count; ++i)
    emitTriangle(polygon[0], polygon[i], polygon[i + 1], id, view, cutOutDraw);
}

void main() {
  int view = int(gl_GlobalInvocationID.y);
  uint stride = gl_NumWorkGroups.x * uint(PC_RASTER_GROUP);
  for (uint t = gl_GlobalInvocationID.x; t < frame.triangleCount; t += stride) rasterize(t, view);
}
