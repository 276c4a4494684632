// Per-update probe math shared by the Embree path and the compute shaders: texel weights for
// blending ray results into the tiles, hysteresis, and probe classification and relocation.
#ifndef PC_PROBE_UPDATE_H
#define PC_PROBE_UPDATE_H

#include "probe_math.h"

PC_BEGIN

// Irradiance texels integrate cos-weighted radiance; depth texels use a sharper lobe so the
// moments describe the distance close to the texel's direction.
PC_FN float pcIrradianceWeight(vec3 texelDir, vec3 rayDir) {
  return max(0.0f, dot(texelDir, rayDir));
}
PC_FN float pcDepthWeight(vec3 texelDir, vec3 rayDir, float exponent) {
  return pow(max(0.0f, dot(texelDir, rayDir)), exponent);
}

// Hysteresis blend: alpha near 1 changes slowly. A tile without history takes the sample.
PC_FN float pcBlendFactor(float hysteresis, bool hasHistory) {
  return hasHistory ? hysteresis : 0.0f;
}

// Encoding of irradiance in the atlas (see PC_IRRADIANCE_GAMMA).
PC_FN vec3 pcEncodeIrradiance(vec3 e) {
  return pow(max(e, vec3(0.0f)), vec3(1.0f / PC_IRRADIANCE_GAMMA));
}
PC_FN vec3 pcDecodeIrradiance(vec3 g) { return pow(max(g, vec3(0.0f)), vec3(PC_IRRADIANCE_GAMMA)); }

// Backface hits report a shortened distance so the depth moments mark the probe as seeing a
// wall close by; the sign carries the backface flag through the ray buffer.
PC_CONST float PC_BACKFACE_DEPTH_SCALE = 0.2f;

// Cut-outs (foliage cards, grilles, fences: materials with an alpha cutoff) are thin sheets
// seen from both sides: a probe ray that meets a card's back meets a lit surface, not the
// inside of a solid. Both tracers shade such a hit as a front face (normal toward the ray, no
// emission) with a positive distance, so a probe among one-sided cards is neither classed
// inside geometry nor fed black rays; only backfaces of other geometry count below.
PC_FN bool pcBackfaceIsSurface(float alphaCutoff) { return alphaCutoff > 0.0f; }

// Share of backface hits above which a probe counts as inside geometry, and below which a
// probe inside counts as outside again. The gap is hysteresis: a probe whose share hovers
// near one threshold (a probe in a corner that relocation cannot free) would otherwise flip
// with ray noise, losing its history at every flip and making every flip a brick change that
// goes to every client.
PC_CONST float PC_INSIDE_BACKFACE_FRACTION = 0.25f;
PC_CONST float PC_OUTSIDE_BACKFACE_FRACTION = 0.1f;

PC_FN bool pcProbeInside(float backfaceFraction, int oldState) {
  float limit =
      oldState == PC_PROBE_INSIDE ? PC_OUTSIDE_BACKFACE_FRACTION : PC_INSIDE_BACKFACE_FRACTION;
  return backfaceFraction > limit;
}

// Relocation distances, fractions of the cascade's spacing: a probe nearer a front face than
// PC_RELOCATE_MIN_FRONTFACE backs away from it, and no probe moves farther than
// PC_RELOCATE_MAX_OFFSET from its grid point. 0.35 instead of 0.2 kept more probes off thin
// walls (+0.3 dB on the tunnel) but cost sauer-pandora 1 dB (docs/BENCHMARKS.md, "Never black,
// cut-outs, view bias"), so 0.2 stays.
PC_CONST float PC_RELOCATE_MIN_FRONTFACE = 0.2f;
PC_CONST float PC_RELOCATE_MAX_OFFSET = 0.45f;

// Relocation: push the probe out of geometry or away from a too-close wall. Offsets are kept
// within maxOffset (a fraction of spacing) of the grid point.
PC_FN vec3 pcRelocate(vec3 offset, bool inside, float closestBackface, vec3 closestBackfaceDir,
                      float closestFrontface, vec3 closestFrontfaceDir, float minFrontface,
                      float maxOffset) {
  vec3 moved = offset;
  if (inside && closestBackface < 1e30f) {
    // Inside: step through the nearest backface, a little past the surface, if that stays
    // within reach. A step that would be clamped could leave the probe inside again, and a
    // probe that alternates between two clamped positions flips between inside and active
    // at every update; this update's rays may find a reachable way out next time.
    vec3 stepped = offset + closestBackfaceDir * (closestBackface + minFrontface * 0.5f);
    if (length(stepped) <= maxOffset) moved = stepped;
  } else if (closestFrontface < minFrontface) {
    // Too close to a wall: back away from it.
    moved -= closestFrontfaceDir * (minFrontface - closestFrontface);
  }
  float len = length(moved);
  if (len > maxOffset) moved *= maxOffset / len;
  return moved;
}

PC_END

#endif
