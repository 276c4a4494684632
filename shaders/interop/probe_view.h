// The client's probe debug view (client_probe_view.comp, client/probe_view.h): its per-frame
// parameters, the colour of each probe state and the ray tests that draw the probes as
// spheres and their relocations as thin capsules from the grid point. Shared so that the C++
// side fills the same layout and tests check the same geometry the shader draws.
#ifndef PC_PROBE_VIEW_H
#define PC_PROBE_VIEW_H

#include "field_desc.h"
#include "pc_interop.h"

PC_BEGIN

PC_CONST int PC_PROBE_VIEW_OFF = 0;
PC_CONST int PC_PROBE_VIEW_IRRADIANCE = 1;  // each sphere shows its probe's irradiance by normal
PC_CONST int PC_PROBE_VIEW_STATE = 2;       // each sphere coloured by its probe's state

// Sizes as fractions of the cascade's spacing: spheres small enough that neighbours never
// touch, relocation lines thin enough not to hide the sphere they lead to.
PC_CONST float PC_PROBE_VIEW_RADIUS = 0.12f;
PC_CONST float PC_PROBE_VIEW_LINE_RADIUS = 0.02f;
// Seconds a brick's probes stay brightened after its version changed.
PC_CONST float PC_PROBE_VIEW_FLASH_SECONDS = 0.3f;
// Offsets shorter than this share of the spacing draw no line (a probe that never moved).
PC_CONST float PC_PROBE_VIEW_MIN_OFFSET = 0.005f;

// FrameUniforms::probeView (client_frame.h).
struct ProbeViewParams {
  int mode;     // PC_PROBE_VIEW_*
  int cascade;  // the only cascade drawn; -1: all
  int offsets;  // 1: relocation lines
  int flash;    // 1: the brick flash buffer holds this frame's values
  // -- 16
  ivec4 brickBase;  // per cascade: index of its first brick in the flash buffer
  // -- 32
};

// Linear colour of a probe state in the state view: active green, sleeping blue, inside
// geometry red, no data yet grey.
PC_FN vec3 pcProbeStateColor(int state) {
  if (state == PC_PROBE_ACTIVE) return vec3(0.1f, 0.8f, 0.15f);
  if (state == PC_PROBE_SLEEPING) return vec3(0.15f, 0.3f, 0.9f);
  if (state == PC_PROBE_INSIDE) return vec3(0.9f, 0.1f, 0.1f);
  return vec3(0.35f, 0.35f, 0.35f);
}
// Relocation lines: yellow.
PC_FN vec3 pcProbeLineColor() { return vec3(0.95f, 0.8f, 0.1f); }

// Brightening of a brick that changed `age` seconds ago: 1 at once, fading to 0.
PC_FN float pcProbeFlash(float age) {
  if (age < 0.0f || age >= PC_PROBE_VIEW_FLASH_SECONDS) return 0.0f;
  return 1.0f - age / PC_PROBE_VIEW_FLASH_SECONDS;
}
PC_FN vec3 pcApplyFlash(vec3 color, float flash) {
  return color * (1.0f + 3.0f * flash) + vec3(0.5f * flash, 0.5f * flash, 0.5f * flash);
}

// Distance along unit `dir` from `origin` to the sphere (centre, radius), or -1 on a miss or
// where the sphere lies behind.
PC_FN float pcRaySphere(vec3 origin, vec3 dir, vec3 centre, float radius) {
  vec3 oc = origin - centre;
  float b = dot(oc, dir);
  float c = dot(oc, oc) - radius * radius;
  float h = b * b - c;
  if (h < 0.0f) return -1.0f;
  float t = -b - sqrt(h);
  return t >= 0.0f ? t : -1.0f;
}

// Distance along unit `dir` to the capsule from a to b of radius r, or -1.
PC_FN float pcRayCapsule(vec3 origin, vec3 dir, vec3 a, vec3 b, float r) {
  vec3 ba = b - a;
  vec3 oa = origin - a;
  float baba = dot(ba, ba);
  float bard = dot(ba, dir);
  float baoa = dot(ba, oa);
  float rdoa = dot(dir, oa);
  float oaoa = dot(oa, oa);
  float qa = baba - bard * bard;
  float qb = baba * rdoa - baoa * bard;
  float qc = baba * oaoa - baoa * baoa - r * r * baba;
  float h = qb * qb - qa * qc;
  if (qa > 0.0f && h >= 0.0f) {
    float t = (-qb - sqrt(h)) / qa;
    float y = baoa + t * bard;
    if (t >= 0.0f && y > 0.0f && y < baba) return t;
  }
  // The caps: spheres at both ends.
  float ta = pcRaySphere(origin, dir, a, r);
  float tb = pcRaySphere(origin, dir, b, r);
  if (ta < 0.0f) return tb;
  if (tb < 0.0f) return ta;
  return min(ta, tb);
}

PC_END

#ifdef __cplusplus
static_assert(sizeof(pc::gpu::ProbeViewParams) == 32);
#endif

#endif
