// The compute rasterizer's coverage test (client_frame.h, PC_RASTER_*): watertight edge
// functions on fixed-point screen positions, evaluated at the standard multisample positions,
// depth interpolated linearly in screen space (reversed depth: near / w), and depth with the
// visibility id written by one 64-bit atomic max per covered sample; a cut-out's sample also
// needs its material covered where the sample's ray meets the triangle (client_surface.glsl).
// Needs client_common.glsl and client_surface.glsl first, and SAMPLES and CUT_OUTS declared.
#ifndef PC_CLIENT_RASTER_GLSL
#define PC_CLIENT_RASTER_GLSL

#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_EXT_shader_atomic_int64 : require

layout(set = 0, binding = PC_CLIENT_BIND_VIS_SAMPLES, std430) buffer VisBlock { uint64_t visSamples[]; };

#include "client_samples.glsl"

// Twice the signed area of (a, b, p): positive when p lies left of a -> b in screen space.
int64_t edgeFunction(ivec2 a, ivec2 b, ivec2 p) {
  return int64_t(b.x - a.x) * int64_t(p.y - a.y) - int64_t(b.y - a.y) * int64_t(p.x - a.x);
}

// Tie rule for samples exactly on an edge: two triangles sharing an edge run it in opposite
// directions, so owning one direction of each edge covers such a sample exactly once.
bool ownsEdge(ivec2 a, ivec2 b) {
  ivec2 d = b - a;
  return d.y > 0 || (d.y == 0 && d.x < 0);
}

struct ScreenTriangle {
  ivec2 a, b, c;  // fixed point, ordered so that edgeFunction(a, b, c) > 0
  vec3 depth;     // at a, b, c
  float invArea;  // 1 / edgeFunction(a, b, c)
  uint id;
  int view;
  int cutOutDraw;  // the draw when its material is a cut-out, else -1
};

// Draw index of triangle id `id` when its material is a cut-out, else -1 (and always -1 in
// scenes without cut-outs, at no cost).
int cutOutDrawOf(uint id) {
  if (!CUT_OUTS) return -1;
  int d = drawOfTriangle(id - 1u);
  return drawIsCutOut(draws[d]) ? d : -1;
}

// Covers the samples of `pixel` inside `t`.
void coverPixel(ScreenTriangle t, ivec2 pixel) {
  uint base = ((uint(t.view) * uint(frame.viewport.y) + uint(pixel.y)) * uint(frame.viewport.x) +
               uint(pixel.x)) * uint(SAMPLES);
  bool ownA = ownsEdge(t.b, t.c), ownB = ownsEdge(t.c, t.a), ownC = ownsEdge(t.a, t.b);
  for (int s = 0; s < SAMPLES; ++s) {
    ivec2 p = pixel * PC_RASTER_SUBPIXEL + sampleOffset(s);
    int64_t wa = edgeFunction(t.b, t.c, p);  // weight of a
    int64_t wb = edgeFunction(t.c, t.a, p);
    int64_t wc = edgeFunction(t.a, t.b, p);
    if (wa < 0 || wb < 0 || wc < 0) continue;
    if ((wa == 0 && !ownA) || (wb == 0 && !ownB) || (wc == 0 && !ownC)) continue;
    if (CUT_OUTS && t.cutOutDraw >= 0) {
      vec3 eye = frame.views[t.view].position.xyz;
      vec3 ray = rayUnderPixel(t.view, vec2(p) / float(PC_RASTER_SUBPIXEL));
      if (!coveredOnRay(draws[t.cutOutDraw], t.id - 1u, eye, ray)) continue;
    }
    float depth = (float(wa) * t.depth.x + float(wb) * t.depth.y + float(wc) * t.depth.z) * t.invArea;
    uint64_t value = (uint64_t(floatBitsToUint(depth)) << 32) | uint64_t(t.id);
    atomicMax(visSamples[base + uint(s)], value);
  }
}

// Pixel rectangle (inclusive) whose samples `t` may cover, clipped to the viewport; empty
// when hi < lo.
void pixelBounds(ScreenTriangle t, out ivec2 lo, out ivec2 hi) {
  ivec2 mn = min(t.a, min(t.b, t.c)), mx = max(t.a, max(t.b, t.c));
  // Samples lie strictly inside their pixel, so a pixel whose square misses the box is out.
  lo = max(mn / PC_RASTER_SUBPIXEL - 1, ivec2(0));
  hi = min(mx / PC_RASTER_SUBPIXEL, ivec2(frame.viewport) - 1);
}

#endif
