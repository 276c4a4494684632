// Shading from a probe field: the 8-probe cage of each cascade, weighted by trilinear
// position, wrap-shaded backface term and Chebyshev visibility on the depth moments, with
// normal and view bias, blended from the finest cascade to coarser ones near cascade edges.
// Two normals: N, the surface's own (vertex) normal, places the sample (normal bias) and weighs
// the probes (backface term, visibility), as those are about where the surface lies and which
// probes see it; Ns, the shading normal (N perturbed by a normal map, else N itself), is the
// direction whose irradiance and occlusion are looked up. A perturbed normal would move the
// biased point off the real surface, into walls or toward probes that do not see it.
//
// A point whose cages hold no probe with data falls back, in this order, to a coarser cascade,
// to the nearest probes with data that see it, then to the renderer's ambient term: the rule
// every renderer follows, so no surface goes black for want of probes.
//
// The includer provides the texel fetches (textures on the GPU, arrays on the CPU) before
// including this file:
//   PC_FIELD_PARAM / PC_FIELD_ARG  an extra leading parameter/argument (empty in GLSL)
//   vec3  pcFetchIrradiance(PC_FIELD_PARAM int cascade, int slot, vec3 dir)  gamma-encoded,
//   bilinear vec2  pcFetchDepth(PC_FIELD_PARAM int cascade, int slot, vec3 dir)       mean, mean
//   square float pcFetchOcclusion(PC_FIELD_PARAM int cascade, int slot, vec3 dir) vec4
//   pcFetchProbe(PC_FIELD_PARAM int cascade, int slot)                 offset xyz, state w
#ifndef PC_PROBE_SAMPLING_H
#define PC_PROBE_SAMPLING_H

#include "probe_math.h"
#include "specular_probe.h"

PC_BEGIN

// Chebyshev upper bound on the chance that a point at `dist` from the probe is visible,
// given the mean and mean square of the probe's hit distances in that direction.
PC_FN float pcChebyshevVisibility(vec2 moments, float dist) {
  float mean = moments.x;
  if (dist <= mean) return 1.0f;
  float variance = abs(moments.y - mean * mean);
  float d = dist - mean;
  float p = variance / (variance + d * d);
  return max(p * p * p, 0.0f);  // cubed: sharpens the soft bound toward the real occluder
}

// Whether a point may sample a probe in this state: probes inside geometry describe the inside
// of a wall, and untraced ones hold nothing.
PC_FN bool pcProbeHasData(int state) {
  return state != PC_PROBE_INSIDE && state != PC_PROBE_UNINITIALIZED;
}

// How much a probe at probeP may light surface point P (biasedP: P moved by the normal and view
// biases), before its position weight: a smooth backface term (probes behind the surface count
// less, never zero, so a point with every probe behind it still gets light) times Chebyshev
// visibility on its depth moments, with tiny weights crushed: they come from occluded probes
// whose light would leak.
PC_FN float pcProbeVisibilityWeight(PC_FIELD_PARAM int cascade, int slot, vec3 probeP, vec3 P,
                                    vec3 biasedP, vec3 N) {
  vec3 toProbe = normalize(probeP - P);
  float wrap = (dot(toProbe, N) + 1.0f) * 0.5f;
  float weight = wrap * wrap + 0.2f;

  vec3 probeToPoint = biasedP - probeP;
  float dist = length(probeToPoint);
  vec3 dir = dist > 0.0f ? probeToPoint / dist : N;
  vec2 moments = pcFetchDepth(PC_FIELD_ARG cascade, slot, dir);
  weight *= max(0.05f, pcChebyshevVisibility(moments, dist));
  weight = max(0.000001f, weight);
  const float crush = 0.2f;
  if (weight < crush) weight *= weight * weight / (crush * crush);
  return weight;
}

// Adds one probe's gamma-encoded irradiance `encoded` (and its occlusion toward Ns) with
// `weight`. Interpolation happens in a perceptual space (square root of irradiance) like RTXGI:
// the atlas holds irradiance^(1/gamma), so raise to gamma/2 here; pcResolveProbeSum squares the
// weighted mean. e^(gamma/2) with gamma = 5 as two multiplies and a square root (pow is slow on
// CPUs).
PC_FN void pcAccumulateProbe(PC_FIELD_PARAM int cascade, int slot, vec3 encoded, vec3 Ns,
                             float weight, int flags, PC_INOUT(vec4) sum,
                             PC_INOUT(float) weightSum) {
  vec3 e = max(encoded, vec3(0.0f));
  vec3 perceptual = e * e * sqrt(e);
  float occlusion = 0.0f;
  if ((flags & PC_SAMPLE_NO_OCCLUSION) == 0) {
    occlusion = pcFetchOcclusion(PC_FIELD_ARG cascade, slot, Ns);
  }
  sum += weight * vec4(perceptual.x, perceptual.y, perceptual.z, occlusion);
  weightSum += weight;
}

// One probe's GGX-filtered radiance toward R (specular_probe.h): its irradiance tile at the
// six octahedron directions about R, decoded (e^gamma, gamma = 5, as two multiplies).
PC_FN vec3 pcProbeSpecular(PC_FIELD_PARAM int cascade, int slot, vec3 R, vec2 zh) {
  vec3 T = pcFrameTangent(R), B = pcFrameBitangent(R);
  vec3 g[6];
  g[0] = pcFetchIrradiance(PC_FIELD_ARG cascade, slot, R);
  g[1] = pcFetchIrradiance(PC_FIELD_ARG cascade, slot, -R);
  g[2] = pcFetchIrradiance(PC_FIELD_ARG cascade, slot, T);
  g[3] = pcFetchIrradiance(PC_FIELD_ARG cascade, slot, -T);
  g[4] = pcFetchIrradiance(PC_FIELD_ARG cascade, slot, B);
  g[5] = pcFetchIrradiance(PC_FIELD_ARG cascade, slot, -B);
  vec3 e[6];
  for (int i = 0; i < 6; ++i) {
    vec3 c = max(g[i], vec3(0.0f));
    vec3 c2 = c * c;
    e[i] = c2 * c2 * c;
  }
  return pcSpecularFromIrradiance(e[0], e[1], e[2] + e[3] + e[4] + e[5], zh);
}

PC_FN vec4 pcResolveProbeSum(vec4 sum, float weightSum) {
  if (weightSum <= 0.0f) return vec4(0.0f);
  vec4 m = sum / weightSum;  // rgb squared: back from the sqrt-irradiance space
  return vec4(m.x * m.x, m.y * m.y, m.z * m.z, m.w);
}

// Irradiance (rgb, W/m^2) and sky occlusion (a) from one cascade; `weightSum` returns the sum
// of cage weights (0 when no probe of the cage holds data).
// With PC_SAMPLE_SPECULAR, `specular` returns the cage's GGX-filtered radiance toward R
// (lobe coefficients zh), its probes weighted as for the irradiance, linearly.
PC_FN vec4 pcSampleCascade(PC_FIELD_PARAM PC_IN(CascadeDesc) c, int cascade, vec3 P, vec3 N,
                           vec3 Ns, vec3 V, int flags, vec3 R, vec2 zh, PC_INOUT(float) weightSum,
                           PC_INOUT(vec3) specular) {
  vec3 biasedP = P + N * c.normalBias + V * c.viewBias;
  vec3 grid = (biasedP - c.origin) / c.spacing;
  ivec3 base = clamp(ivec3(floor(grid)), ivec3(0), max(c.counts - ivec3(2), ivec3(0)));
  vec3 alpha = clamp(grid - vec3(base), vec3(0.0f), vec3(1.0f));

  vec4 sum = vec4(0.0f);
  weightSum = 0.0f;
  specular = vec3(0.0f);
  for (int i = 0; i < 8; ++i) {
    ivec3 offset = ivec3(i & 1, (i >> 1) & 1, (i >> 2) & 1);
    ivec3 logical = min(base + offset, c.counts - ivec3(1));
    int slot = pcProbeSlot(c, pcPhysicalCoord(c, logical));
    vec4 probe = pcFetchProbe(PC_FIELD_ARG cascade, slot);
    // Fetched before the probe's state is known: it depends on the slot alone, so on a GPU its
    // loads go out with the probe record's instead of a round trip after it.
    vec3 encoded = pcFetchIrradiance(PC_FIELD_ARG cascade, slot, Ns);
    if (!pcProbeHasData(int(probe.w))) continue;
    vec3 probeP = pcProbeGridPosition(c, logical) + vec3(probe.x, probe.y, probe.z);

    vec3 tri = mix(vec3(1.0f) - alpha, alpha, vec3(offset));
    float weight = max(0.001f, tri.x * tri.y * tri.z);
    if ((flags & PC_SAMPLE_NO_VISIBILITY) == 0) {
      weight *= pcProbeVisibilityWeight(PC_FIELD_ARG cascade, slot, probeP, P, biasedP, N);
    }
    pcAccumulateProbe(PC_FIELD_ARG cascade, slot, encoded, Ns, weight, flags, sum, weightSum);
    if ((flags & PC_SAMPLE_SPECULAR) != 0)
      specular += weight * pcProbeSpecular(PC_FIELD_ARG cascade, slot, R, zh);
  }
  if (weightSum > 0.0f) specular /= weightSum;
  return pcResolveProbeSum(sum, weightSum);
}

// The fallback of a point whose cage holds no probe with data (all eight inside geometry or
// untraced, as among one-sided walls or in a crevice): the probes with data in the 4x4x4 block
// around the cage, each weighted by a tent two cells wide around the biased point and by the
// same visibility as the cage's, so that the nearest probes that see the point light it.
PC_FN vec4 pcSampleCascadeWide(PC_FIELD_PARAM PC_IN(CascadeDesc) c, int cascade, vec3 P, vec3 N,
                               vec3 Ns, vec3 V, int flags, vec3 R, vec2 zh,
                               PC_INOUT(float) weightSum, PC_INOUT(vec3) specular) {
  vec3 biasedP = P + N * c.normalBias + V * c.viewBias;
  vec3 grid = (biasedP - c.origin) / c.spacing;
  ivec3 base = clamp(ivec3(floor(grid)), ivec3(0), max(c.counts - ivec3(2), ivec3(0)));

  vec4 sum = vec4(0.0f);
  weightSum = 0.0f;
  specular = vec3(0.0f);
  for (int i = 0; i < 64; ++i) {
    ivec3 logical = base + ivec3(i & 3, (i >> 2) & 3, (i >> 4) & 3) - ivec3(1);
    if (logical.x < 0 || logical.y < 0 || logical.z < 0 || logical.x >= c.counts.x ||
        logical.y >= c.counts.y || logical.z >= c.counts.z)
      continue;
    int slot = pcProbeSlot(c, pcPhysicalCoord(c, logical));
    vec4 probe = pcFetchProbe(PC_FIELD_ARG cascade, slot);
    if (!pcProbeHasData(int(probe.w))) continue;
    vec3 probeP = pcProbeGridPosition(c, logical) + vec3(probe.x, probe.y, probe.z);

    vec3 tent = max(vec3(0.0f), vec3(1.0f) - abs(grid - vec3(logical)) * 0.5f);
    float weight = max(0.001f, tent.x * tent.y * tent.z);
    if ((flags & PC_SAMPLE_NO_VISIBILITY) == 0) {
      weight *= pcProbeVisibilityWeight(PC_FIELD_ARG cascade, slot, probeP, P, biasedP, N);
    }
    vec3 encoded = pcFetchIrradiance(PC_FIELD_ARG cascade, slot, Ns);
    pcAccumulateProbe(PC_FIELD_ARG cascade, slot, encoded, Ns, weight, flags, sum, weightSum);
    if ((flags & PC_SAMPLE_SPECULAR) != 0)
      specular += weight * pcProbeSpecular(PC_FIELD_ARG cascade, slot, R, zh);
  }
  if (weightSum > 0.0f) specular /= weightSum;
  return pcResolveProbeSum(sum, weightSum);
}

// How much cascade `c` owns point P: 1 inside the box its probes span, fading to 0 over
// blendMargin beyond it. Points up to blendMargin outside still get a (clamped) cage: volumes
// are usually inset from the walls they light, and those walls must use their finest cascade.
PC_FN float pcCascadeCoverage(PC_IN(CascadeDesc) c, vec3 P) {
  vec3 lo = c.origin;
  vec3 hi = c.origin + vec3(c.counts - ivec3(1)) * c.spacing;
  vec3 inside = min(P - lo, hi - P);
  float d = min(inside.x, min(inside.y, inside.z));  // < 0 outside the box
  if (c.blendMargin <= 0.0f) return d >= 0.0f ? 1.0f : 0.0f;
  return clamp(1.0f + d / c.blendMargin, 0.0f, 1.0f);
}

// Irradiance and occlusion at a surface point from all cascades (finest first). The coarsest
// cascade takes whatever the finer ones leave, even outside its extent (clamped cage). Where no
// cage holds data, the wider block of the finest cascade that has any (pcSampleCascadeWide)
// fills the rest, unless PC_SAMPLE_NO_FALLBACK. `coverage` returns how much of the result came
// from probes that hold data (0..1). N places and weighs, Ns looks up (see the top).
// With PC_SAMPLE_SPECULAR, `specular` returns the GGX-filtered radiance toward R (lobe
// coefficients zh, pcGgxSpecularZh) blended over cascades as the irradiance is.
PC_FN vec4 pcSampleFieldLit(PC_FIELD_PARAM PC_IN(FieldDesc) f, vec3 P, vec3 N, vec3 Ns, vec3 V,
                            int flags, vec3 R, vec2 zh, PC_INOUT(float) coverage,
                            PC_INOUT(vec3) specular) {
  vec4 result = vec4(0.0f);
  specular = vec3(0.0f);
  vec3 cascadeSpecular = vec3(0.0f);
  float remaining = 1.0f;
  for (int k = 0; k < f.cascadeCount; ++k) {
    float w = k == f.cascadeCount - 1 ? 1.0f : pcCascadeCoverage(f.cascades[k], P);
    if (w <= 0.0f) continue;
    float weightSum = 0.0f;
    vec4 s = pcSampleCascade(PC_FIELD_ARG f.cascades[k], k, P, N, Ns, V, flags, R, zh, weightSum,
                             cascadeSpecular);
    if (weightSum <= 0.0f) continue;
    result += remaining * w * s;
    specular += remaining * w * cascadeSpecular;
    remaining *= 1.0f - w;
    if (remaining <= 0.0f) break;
  }
  if (remaining > 0.0f && (flags & PC_SAMPLE_NO_FALLBACK) == 0) {
    for (int k = 0; k < f.cascadeCount; ++k) {
      if (k < f.cascadeCount - 1 && pcCascadeCoverage(f.cascades[k], P) <= 0.0f) continue;
      float weightSum = 0.0f;
      vec4 s = pcSampleCascadeWide(PC_FIELD_ARG f.cascades[k], k, P, N, Ns, V, flags, R, zh,
                                   weightSum, cascadeSpecular);
      if (weightSum <= 0.0f) continue;
      result += remaining * s;
      specular += remaining * cascadeSpecular;
      remaining = 0.0f;
      break;
    }
  }
  coverage = 1.0f - remaining;
  if (coverage > 0.0f) specular /= coverage;
  return coverage > 0.0f ? result / coverage : vec4(0.0f);
}

// Irradiance and occlusion alone (no specular).
PC_FN vec4 pcSampleFieldShaded(PC_FIELD_PARAM PC_IN(FieldDesc) f, vec3 P, vec3 N, vec3 Ns, vec3 V,
                               int flags, PC_INOUT(float) coverage) {
  vec3 unused = vec3(0.0f);
  return pcSampleFieldLit(PC_FIELD_ARG f, P, N, Ns, V, flags & ~PC_SAMPLE_SPECULAR, N, vec2(1.0f),
                          coverage, unused);
}

// The same where the shading normal is the surface's own (probe rays, unmapped surfaces).
PC_FN vec4 pcSampleField(PC_FIELD_PARAM PC_IN(FieldDesc) f, vec3 P, vec3 N, vec3 V, int flags,
                         PC_INOUT(float) coverage) {
  return pcSampleFieldShaded(PC_FIELD_ARG f, P, N, N, V, flags, coverage);
}

// What a renderer shades with: the field, and where no probe near P holds data (an empty or
// partial field, a point walled in by probes inside geometry), the renderer's ambient term for
// the rest (occlusion 1), so that no surface goes without indirect light. PC_SAMPLE_NO_FALLBACK
// leaves the rest black. N places and weighs, Ns looks up (see the top).
// With PC_SAMPLE_SPECULAR, `specular` returns the GGX-filtered radiance toward R, the ambient
// term's radiance (ambient / pi) standing in where the irradiance's does.
PC_FN vec4 pcSampleFieldOrAmbientLit(PC_FIELD_PARAM PC_IN(FieldDesc) f, vec3 P, vec3 N, vec3 Ns,
                                     vec3 V, int flags, vec3 ambient, vec3 R, vec2 zh,
                                     PC_INOUT(vec3) specular) {
  float coverage = 0.0f;
  vec4 s = pcSampleFieldLit(PC_FIELD_ARG f, P, N, Ns, V, flags, R, zh, coverage, specular);
  if ((flags & PC_SAMPLE_NO_FALLBACK) != 0) return s;
  specular = mix(ambient * (1.0f / PC_PI), specular, coverage);
  vec3 irradiance = mix(ambient, vec3(s.x, s.y, s.z), coverage);
  return vec4(irradiance.x, irradiance.y, irradiance.z, mix(1.0f, s.w, coverage));
}

PC_FN vec4 pcSampleFieldOrAmbient(PC_FIELD_PARAM PC_IN(FieldDesc) f, vec3 P, vec3 N, vec3 Ns,
                                  vec3 V, int flags, vec3 ambient) {
  vec3 unused = vec3(0.0f);
  return pcSampleFieldOrAmbientLit(PC_FIELD_ARG f, P, N, Ns, V, flags & ~PC_SAMPLE_SPECULAR,
                                   ambient, N, vec2(1.0f), unused);
}

PC_END

#endif
