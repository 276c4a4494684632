// The sun's cascaded shadow maps, shared by client/sun_cascades.cpp (which fits them to the
// camera) and shaders/client/client_direct.glsl (which picks and blends them per pixel).
//
// One map over a whole scene spreads its texels over everything the sun sees, most of it far
// from the camera: a shadow edge near the eye is as blurred as one across the level. The
// camera's view is cut into PC_SUN_CASCADES slices by distance, and each slice gets its own
// orthographic map fitted to it, the nearest slice the finest. A point takes the finest map
// that holds it (with room for the filter's taps), and near that map's edge fades into the
// next coarser one so the change of resolution leaves no seam.
#ifndef PC_SUN_CASCADES_H
#define PC_SUN_CASCADES_H

#include "pc_interop.h"

PC_BEGIN

// Maps per sun (shadow layers and matrices, from GpuLight::shadowLayer / shadowMatrix on).
PC_CONST int PC_SUN_CASCADES = 4;
// Split distances: this share of a logarithmic split, the rest a uniform one (the "practical
// split scheme"). Logarithmic gives equal texels per pixel on screen; the uniform share keeps
// far slices from growing too coarse.
PC_CONST float PC_SUN_CASCADE_LOG_SHARE = 0.9f;
// The slices start no nearer than this share of the farthest distance: a near plane of a few
// centimetres would spend the logarithmic split's first slice on them.
PC_CONST float PC_SUN_CASCADE_NEAREST = 0.005f;
// Texels kept free at a map's border: the 3x3 filter's gathers read two texels past the centre.
PC_CONST float PC_SUN_CASCADE_MARGIN_TEXELS = 3.0f;
// The band along a map's border (share of its width) where it fades into the next map.
PC_CONST float PC_SUN_CASCADE_BLEND = 0.06f;
// Receivers move along their normal by this many texels of the map they are looked up in.
PC_CONST float PC_SUN_NORMAL_OFFSET_TEXELS = 1.5f;

// How far inside cascade map coordinates `uv` (0..1) and depth `ndcZ` lie, as a weight: below 0
// outside the map (or within the filter's margin of its border, `texel`: 1 / map size), 1 past
// the blend band, in between across the band. A point takes the first cascade where this is
// not negative, and mixes in the next one by 1 - weight.
PC_FN float pcSunCascadeWeight(vec2 uv, float ndcZ, float texel) {
  if (ndcZ < 0.0f || ndcZ >= 1.0f) return -1.0f;
  float margin = PC_SUN_CASCADE_MARGIN_TEXELS * texel;
  float edge = min(min(uv.x, uv.y), min(1.0f - uv.x, 1.0f - uv.y)) - margin;
  if (edge < 0.0f) return -1.0f;
  return min(edge / PC_SUN_CASCADE_BLEND, 1.0f);
}

PC_END

#endif
