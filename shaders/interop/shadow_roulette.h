// Russian roulette on the shadow rays of probe updates, the same in both backends (the
// Embree tracer through cpu/lighting.cpp, the Vulkan tracer in probe_shade.comp).
//
// A punctual light that brings at least `share` of a hit's unshadowed direct light (by
// luminance, over the scene's punctual lights) always gets its shadow ray. A weaker one gets
// it with probability p = contribution / (share x total), and its light then counts 1/p
// times, so the expected light is unchanged: what is saved is the shadow rays toward lights
// far away or at grazing angles, most of which walls stop anyway. What it adds is noise: at
// most share x total per surviving weak light, on a hit whose total is dominated by the
// strong ones; the field's hysteresis averages it over updates.
//
// The random numbers come from a hash of the update's seed, the ray (request x rays + ray)
// and the light, so both backends make the same choices for the same ray.
#ifndef PC_SHADOW_ROULETTE_H
#define PC_SHADOW_ROULETTE_H

#include "probe_math.h"

PC_BEGIN

// The key of the ray `rayIndex` (request x rays per probe + ray) of the update with `seed`.
PC_FN uint pcShadowRouletteKey(uint seed, uint rayIndex) {
  return pcHash(seed * 0x85EBCA77u ^ pcHash(rayIndex));
}

// The weight of light `light`'s contribution at a hit: 1 for its shadow ray as always, 0 for
// no shadow ray (the light is left out), 1/p for a weak light that won the draw.
PC_FN float pcShadowRouletteWeight(float contribution, float total, float share, uint key,
                                   int light) {
  if (!(share > 0.0f) || contribution >= share * total) return 1.0f;
  float p = contribution / (share * total);
  float u = pcHashToFloat(pcHash(key + uint(light) * 0x9E3779B9u));
  return u < p ? 1.0f / p : 0.0f;
}

PC_END

#endif
