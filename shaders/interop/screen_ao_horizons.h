// The GTAO estimator of screen_ao.h: per slice, the highest horizon on either side of the
// pixel within the radius, then the cosine-weighted visible arc between the two horizons.
// One source for the client's lighting pass (shaders/client/client_indirect.comp) and the CPU
// probe-lit render (cpu/screen_ao.cpp). Both feed it the same kind of input, a buffer of the
// view's surfaces through the pixel centres, so their images agree. The includer provides,
// before including this file:
//   PC_AO_PARAM / PC_AO_ARG  an extra leading parameter/argument (the view in GLSL)
//   vec4 pcAoSurface(PC_AO_PARAM ivec2 pixel)  the surface under the pixel centre: xyz its
//        position relative to the eye, w 1 (0: sky or off the image)
//   vec3 pcAoNormal(PC_AO_PARAM ivec2 pixel)   its unit normal
//   vec3 pcAoRay(PC_AO_PARAM vec2 pixel)  the unit ray from the eye through a window position
//        (pixels from the top left corner, centres at + 0.5)
#ifndef PC_SCREEN_AO_HORIZONS_H
#define PC_SCREEN_AO_HORIZONS_H

#include "screen_ao.h"

PC_BEGIN

// Visibility (0 occluded .. 1 open, cosine-weighted over the hemisphere of N) of the surface
// at `P` (relative to the eye) with unit normal `N`, seen through `pixel`, from occluders
// within `radius` (world units) found in the surface buffer.
PC_FN float pcScreenAo(PC_AO_PARAM ivec2 pixel, vec3 P, vec3 N, float radius) {
  float dist = length(P);
  if (radius <= 0.0f || dist <= 0.0f) return 1.0f;
  vec3 V = -P / dist;  // toward the eye
  vec2 centre = vec2(pixel) + vec2(0.5f, 0.5f);
  vec3 ray0 = pcAoRay(PC_AO_ARG centre);
  // The angle one pixel spans here gives the radius in pixels.
  float pixelAngle = length(pcAoRay(PC_AO_ARG centre + vec2(1.0f, 0.0f)) - ray0);
  float radiusPx = min(radius / max(dist * pixelAngle, 1e-20f), PC_AO_MAX_PIXELS);
  if (radiusPx < 1.0f) return 1.0f;  // smaller than a pixel: nothing to find
  float falloffMul = -1.0f / (PC_AO_FALLOFF * radius);
  float falloffAdd = (1.0f - PC_AO_FALLOFF) / PC_AO_FALLOFF + 1.0f;

  // Sums over the slices of the visible arc and of the whole hemisphere's arc: their ratio is
  // exactly 1 on an open surface, which the slice sum alone is not with few slices at grazing
  // angles (8 slices give a floor seen edge-on 0.96).
  float visibility = 0.0f, open = 0.0f;
  for (int slice = 0; slice < PC_AO_SLICES; ++slice) {
    float phi = PC_PI * (float(slice) + 0.5f) / float(PC_AO_SLICES);
    vec2 omega = vec2(cos(phi), sin(phi));  // window space, y down
    // The slice plane holds V and the ray one pixel along omega; `dir` is its direction
    // across V toward omega's side, `axis` its normal.
    vec3 toward = pcAoRay(PC_AO_ARG centre + omega) - ray0;
    vec3 dir = toward - V * dot(toward, V);
    float dirLen = length(dir);
    if (dirLen <= 0.0f) continue;
    dir = dir / dirLen;
    vec3 axis = normalize(cross(dir, V));
    vec3 projN = N - axis * dot(N, axis);
    float projLen = length(projN);
    if (projLen <= 1e-6f) continue;
    float cosN = clamp(dot(projN, V) / projLen, 0.0f, 1.0f);
    float n = (dot(dir, projN) >= 0.0f ? 1.0f : -1.0f) * acos(cosN);
    // Horizons start at the tangent plane (nothing occludes) and rise to the highest sample.
    float low0 = cos(n + 0.5f * PC_PI), low1 = cos(n - 0.5f * PC_PI);
    float horizon0 = low0, horizon1 = low1;
    for (int step = 0; step < PC_AO_STEPS; ++step) {
      float s = (float(step) + 0.5f) / float(PC_AO_STEPS);
      float offset = 1.0f + s * s * (radiusPx - 1.0f);
      for (int side = 0; side < 2; ++side) {
        vec2 at = centre + (side == 0 ? omega : -omega) * offset;
        ivec2 texel = ivec2(floor(at.x), floor(at.y));
        vec4 q = pcAoSurface(PC_AO_ARG texel);
        if (q.w <= 0.0f) continue;  // sky or off the image: no occluder
        // The sample's surface where the ray through `at` itself meets it (its tangent plane
        // at the texel's centre): that point lies in the slice plane, so a plane does not
        // occlude itself, as the texel's centre (off the slice by up to half a pixel) would.
        vec3 Q = vec3(q.x, q.y, q.z);
        vec3 nq = pcAoNormal(PC_AO_ARG texel);
        vec3 rayAt = pcAoRay(PC_AO_ARG at);
        float denom = dot(rayAt, nq);
        if (abs(denom) > 0.01f) {  // not grazing: the plane hit is well defined
          float t = dot(Q, nq) / denom;
          if (t > 0.0f && t < 2.0f * length(Q)) Q = rayAt * t;
        }
        vec3 delta = Q - P;
        float len = length(delta);
        if (len <= 1e-6f * dist) continue;
        float weight = clamp(len * falloffMul + falloffAdd, 0.0f, 1.0f);
        float c = dot(delta / len, V);
        if (side == 0)
          horizon0 = max(horizon0, mix(low0, c, weight));
        else
          horizon1 = max(horizon1, mix(low1, c, weight));
      }
    }
    float h0 = -acos(clamp(horizon1, -1.0f, 1.0f));
    float h1 = acos(clamp(horizon0, -1.0f, 1.0f));
    h0 = n + clamp(h0 - n, -0.5f * PC_PI, 0.5f * PC_PI);
    h1 = n + clamp(h1 - n, -0.5f * PC_PI, 0.5f * PC_PI);
    float sinN = sin(n);
    float arc0 = (cosN + 2.0f * h0 * sinN - cos(2.0f * h0 - n)) * 0.25f;
    float arc1 = (cosN + 2.0f * h1 * sinN - cos(2.0f * h1 - n)) * 0.25f;
    visibility += projLen * (arc0 + arc1);
    open += projLen * (cosN + n * sinN);  // arc0 + arc1 with both horizons at the tangent
  }
  return open > 0.0f ? clamp(visibility / open, 0.0f, 1.0f) : 1.0f;
}

PC_END

#endif
