// Screen-space ambient occlusion of the field's indirect light: GTAO, the horizon-based
// estimator of Jimenez et al. 2016, "Practical Realtime Strategies for Accurate Indirect
// Occlusion" (the slice integration as in Intel's XeGTAO), with the paper's multi-bounce fit.
// It darkens what probes cannot resolve: contacts and concave edges closer than the probe
// spacing. The radius is a fraction of the spacing of the cascade that lights the point, so
// occluders farther away, which the probes' visibility already sees, are left to the field.
//
// This file: the settings, the radius and the multi-bounce fit, for every includer. The
// estimator itself, which reads a surface buffer through hooks, is screen_ao_horizons.h.
#ifndef PC_SCREEN_AO_H
#define PC_SCREEN_AO_H

#include "field_desc.h"
#include "pc_interop.h"

PC_BEGIN

PC_CONST int PC_AO_SLICES = 8;  // slice directions over a half turn, each marched both ways
PC_CONST int PC_AO_STEPS = 6;   // samples per side of a slice, denser near the centre
// A slice's samples fade out over this last fraction of the radius (XeGTAO's 0.615), so an
// occluder entering the radius darkens gradually.
PC_CONST float PC_AO_FALLOFF = 0.615f;
// The screen radius is capped (a surface right in front of the eye would spread it over the
// whole image and read far-away pixels).
PC_CONST float PC_AO_MAX_PIXELS = 64.0f;
// Default radius as a fraction of the probe spacing (the tools' --ao-radius). Measured
// (docs/BENCHMARKS.md, "Contact occlusion"): 0.35 takes the bias out of the band along a
// block's contact (+2.9 levels to +0.1) and costs no shared scene PSNR; 0.5 over-darkens the
// contact and costs the living room 0.07 dB, 1.0 0.33 dB (what the probes already see,
// darkened twice).
PC_CONST float PC_AO_DEFAULT_RADIUS = 0.35f;

// World radius of the occlusion at world point P: `scale` x the spacing of the finest cascade
// whose probe box holds P (the one that mostly lights it), the coarsest one's elsewhere.
PC_FN float pcAoRadius(PC_IN(FieldDesc) f, vec3 P, float scale) {
  float spacing = f.cascades[f.cascadeCount - 1].spacing;
  for (int k = f.cascadeCount - 2; k >= 0; --k) {
    vec3 lo = f.cascades[k].origin;
    vec3 hi = lo + vec3(f.cascades[k].counts - ivec3(1)) * f.cascades[k].spacing;
    if (all(greaterThanEqual(P, lo)) && all(lessThanEqual(P, hi))) spacing = f.cascades[k].spacing;
  }
  return scale * spacing;
}

// The paper's multi-bounce fit: light that the occluders themselves reflect gives some of the
// lost irradiance back, more on bright surfaces. Per colour channel of the albedo.
PC_FN vec3 pcAoMultiBounce(float visibility, vec3 albedo) {
  vec3 a = 2.0404f * albedo - vec3(0.3324f);
  vec3 b = -4.7951f * albedo + vec3(0.6417f);
  vec3 c = 2.7552f * albedo + vec3(0.6903f);
  vec3 v = vec3(visibility);
  return max(v, ((v * a + b) * v + c) * v);
}

PC_END

#endif
