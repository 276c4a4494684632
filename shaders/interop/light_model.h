// The light model, once for every renderer and tracer: the GPU light record and how a light
// or an emitter sample lights a surface point. The Embree field update and the CPU renders
// (cpu/lighting.cpp), the Vulkan field update (probe_shade.comp) and the client's lighting
// pass (shaders/client/client_direct.glsl) all evaluate lights with these functions, so they
// cannot disagree on fall-off, cone or emitter geometry. Visibility is each side's own: shadow
// rays in the tracers, shadow maps in the client.
#ifndef PC_LIGHT_MODEL_H
#define PC_LIGHT_MODEL_H

#include "pc_interop.h"

PC_BEGIN

// Light kinds (GpuLight.type). Area lights are the client's virtual point lights standing for
// a patch of an emissive surface: they emit only to their front (cosine fall-off), like the
// emitter. The tracers sample emitters as triangles instead (pcEmitterGeometry).
PC_CONST int PC_LIGHT_POINT = 0;
PC_CONST int PC_LIGHT_SPOT = 1;
PC_CONST int PC_LIGHT_DIRECTIONAL = 2;
PC_CONST int PC_LIGHT_AREA = 3;

// Shadow rays start a hair past their (already offset) origin and stop a hair short of the
// light, so neither the receiver nor the emitter itself counts as an occluder.
PC_CONST float PC_SHADOW_NEAR = 1e-4f;
PC_CONST float PC_SHADOW_FAR_SCALE = 1.0f - 1e-4f;
// The distance of a directional light: past anything a scene holds in float.
PC_CONST float PC_LIGHT_UNBOUNDED = 1e30f;

// One light as the GPU reads it (std430; the tracers leave the shadow-map fields unused).
// common/light_pack.h fills it from a scene Light.
struct GpuLight {
  vec3 position;  // client: also the origin of its shadow matrices (directional: the map's eye)
  int type;       // PC_LIGHT_*
  // -- 16
  vec3 direction;  // unit: where the light travels (spot, directional); area: emitter normal
  float range;     // 0: unlimited; area: the patch's area (see pcLightIrradiance)
  // -- 32
  vec3 power;  // colour x intensity: W/sr (point, spot), W/m^2 (directional);
               // area: radiance x patch area (W/sr at normal incidence)
  float cosOuter;
  // -- 48
  float cosInner;
  int shadowLayer;     // client: first layer in its shadow array (6 for cubes), -1: no shadow
  int shadowArray;     // client: 0 large maps (sun, spots), 1 small (area), 2 point-light cubes
  float normalOffset;  // client: world units per unit of distance (perspective);
                       // directional: texels of the cascade looked up
  // -- 64
  int shadowMatrix;   // client: index of its first matrix in the shadow matrix buffer
  float shadowTexel;  // client: 1 / shadow map resolution
  float depthBias;    // client: subtracted from the receiver's shadow-map depth
  int pad0;
  // -- 80
};

// Smooth fall-off to zero at `range` (the window glTF's KHR_lights_punctual suggests), so
// limited-range lights do not end in a visible edge.
PC_FN float pcRangeWindow(float distance, float range) {
  if (range <= 0.0f) return 1.0f;
  float r = distance / range;
  float w = clamp(1.0f - r * r * r * r, 0.0f, 1.0f);
  return w * w;
}

// A spot light's cone at the direction `towardLight` (unit, from the surface to the light):
// smoothstep from the outer to the inner cone; a hard edge where the two coincide.
PC_FN float pcSpotFactor(PC_IN(GpuLight) l, vec3 towardLight) {
  float cosAngle = -dot(towardLight, l.direction);
  if (l.cosInner - l.cosOuter <= 1e-6f) return cosAngle >= l.cosOuter ? 1.0f : 0.0f;
  float t = clamp((cosAngle - l.cosOuter) / (l.cosInner - l.cosOuter), 0.0f, 1.0f);
  return t * t * (3.0f - 2.0f * t);
}

// The factor that turns light `l`'s power into the unshadowed irradiance (W/m^2) it brings to
// P (unit normal N): cosines, fall-off, cone, range. `wi` is set to the unit direction toward
// the light and `distance` to the light's distance (PC_LIGHT_UNBOUNDED for a directional
// light); all three are 0 where the light does not reach P (behind the surface, outside the
// cone or the range). A scalar, so that a caller can fold its shadow term in before the
// colour: l.power * (scale * visibility).
PC_FN float pcLightScale(PC_IN(GpuLight) l, vec3 P, vec3 N, PC_INOUT(vec3) wi,
                         PC_INOUT(float) distance) {
  wi = vec3(0.0f);
  distance = 0.0f;
  if (l.type == PC_LIGHT_DIRECTIONAL) {
    vec3 toward = -l.direction;
    float cosTheta = dot(N, toward);
    if (!(cosTheta > 0.0f)) return 0.0f;
    wi = toward;
    distance = PC_LIGHT_UNBOUNDED;
    return cosTheta;
  }
  vec3 toLight = l.position - P;
  float d2 = dot(toLight, toLight);
  if (!(d2 > 0.0f)) return 0.0f;
  float d = sqrt(d2);
  vec3 toward = toLight / d;
  float cosTheta = dot(N, toward);
  if (!(cosTheta > 0.0f)) return 0.0f;
  float scale;
  if (l.type == PC_LIGHT_AREA) {
    // One-sided cosine emission. `range` holds the squared distance below which a patch stops
    // brightening (its own size): the point-light form of a patch diverges where the area
    // integral does not.
    float cosLight = -dot(l.direction, toward);
    if (!(cosLight > 0.0f)) return 0.0f;
    scale = cosTheta * cosLight / max(d2, l.range);
  } else {
    scale = cosTheta / d2 * pcRangeWindow(d, l.range);
    if (l.type == PC_LIGHT_SPOT) scale *= pcSpotFactor(l, toward);
  }
  if (!(scale > 0.0f)) return 0.0f;
  wi = toward;
  distance = d;
  return scale;
}

// Unshadowed irradiance (W/m^2) that light `l` brings to P: its power x pcLightScale, with `wi`
// and `distance` as that sets them.
PC_FN vec3 pcLightIrradiance(PC_IN(GpuLight) l, vec3 P, vec3 N, PC_INOUT(vec3) wi,
                             PC_INOUT(float) distance) {
  return l.power * pcLightScale(l, P, N, wi, distance);
}

// A uniform point on the triangle p0 + u e1 + v e2 from two uniform numbers in [0, 1)
// (square-root warp of the unit square).
PC_FN vec3 pcTrianglePoint(vec3 p0, vec3 e1, vec3 e2, float u1, float u2) {
  float r = sqrt(u1);
  return p0 + r * (1.0f - u2) * e1 + r * u2 * e2;
}

// The geometry term of an emitter sample: cos at the surface x cos at the emitter / d^2, for
// the point Q on an emitter with unit front normal Ne seen from P (unit normal N); 0 where
// either faces away (emitters are one-sided). The sample's irradiance estimate is
// radiance x pcEmitterGeometry / pdf (the pdf by area of choosing Q).
PC_FN float pcEmitterGeometry(vec3 Q, vec3 Ne, vec3 P, vec3 N) {
  vec3 toLight = Q - P;
  float d2 = dot(toLight, toLight);
  if (!(d2 > 0.0f)) return 0.0f;
  vec3 wi = toLight / sqrt(d2);
  float cosSurface = dot(N, wi);
  float cosLight = -dot(Ne, wi);
  if (!(cosSurface > 0.0f) || !(cosLight > 0.0f)) return 0.0f;
  return cosSurface * cosLight / d2;
}

// P moved a fixed number of float steps (ulps) along the unit normal n, so the offset scales
// with the rounding error of the coordinates themselves: large scenes get larger offsets,
// small ones smaller. Near zero, ulps become tiny and a small absolute offset takes over.
// Shadow rays toward an emitter sample aim at its point lifted off the emitter this way, so
// the emitter never shadows its own sample. (After Waechter and Binder, "A Fast and Robust
// Method for Avoiding Self-Intersection", Ray Tracing Gems, 2019.)
PC_FN vec3 pcOffsetRayOrigin(vec3 P, vec3 n) {
  const float kNearZero = 1.0f / 32.0f;
  const float kAbsoluteStep = 1.0f / 65536.0f;
  const float kUlpsPerUnitNormal = 256.0f;
  vec3 o = P;
  for (int c = 0; c < 3; ++c) {
    float p = P[c];
    if (abs(p) < kNearZero) {
      o[c] = p + kAbsoluteStep * n[c];
    } else {
      // Moving away from zero means adding to the bit pattern's magnitude; the sign of the
      // coordinate decides which way that is.
      int ulps = int(kUlpsPerUnitNormal * n[c]);
      o[c] = intBitsToFloat(floatBitsToInt(p) + (p < 0.0f ? -ulps : ulps));
    }
  }
  return o;
}

PC_END

#ifdef __cplusplus
static_assert(sizeof(pc::gpu::GpuLight) == 80);
#endif

#endif
