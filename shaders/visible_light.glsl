// The light of a probe ray's visible shadow slots (interop/gpu_trace.h): what the shade pass
// requested for each slot, where the shadow pass set the slot's bit. Read by the blend (one
// round of slots) and by the resolve pass (several rounds). The includer declares `params`,
// `shadowMask` and `shadowLight`.
#ifndef PC_VISIBLE_LIGHT_GLSL
#define PC_VISIBLE_LIGHT_GLSL

// `base` with the light of the visible slots of this round added in slot order (lights, then
// emissive samples, as the CPU sums them), for the ray at launch index i. Only the set bits'
// records are read. `mask0` is the ray's first mask word, loaded by the caller with the ray.
vec3 pcAddVisibleLight(uint i, vec3 base, uint mask0) {
  uint stride = uint(params.probeCount) * uint(params.rayCount);
  vec3 radiance = base;
  int words = pcShadowMaskWords(params.roundSlots);
  for (int w = 0; w < words; ++w) {
    for (uint m = w == 0 ? mask0 : shadowMask[uint(w) * stride + i]; m != 0u; m &= m - 1u) {
      uint slot = uint(w) * 32u + uint(findLSB(m));
      radiance += shadowLight[slot * stride + i].radiance;
    }
  }
  return radiance;
}

#endif
