#version 460
// The probe debug view, after the lighting pass: probes drawn as spheres (shaded by the
// irradiance their tile holds toward the sphere's normal, or coloured by state) and their
// relocations as thin lines from the grid point, over the lit frame and hidden behind the
// scene's surfaces. Each pixel's ray walks each shown cascade's cells (3D DDA) and tests the
// probes at the corners of the cells it crosses: a probe's sphere and line stay within the
// eight cells around its grid point (relocation is at most 0.45 spacing), so the first hit
// found in a cell before the ray leaves it is the nearest. Bricks that just changed flash.
// Layouts and colours: shaders/interop/probe_view.h.
#extension GL_GOOGLE_include_directive : require
#include "client_common.glsl"
#include "../interop/probe_math.h"

layout(local_size_x = 8, local_size_y = 8) in;
layout(constant_id = 0) const int SAMPLES = 4;
layout(constant_id = 1) const int TEXTURE_COUNT = 1;
layout(constant_id = 2) const bool VIS_BUFFER = false;
#include "client_surface.glsl"
#include "client_field_fetch.glsl"
#include "client_visibility.glsl"

layout(set = 0, binding = PC_CLIENT_BIND_BRICK_FLASH, std430) readonly buffer FlashBlock { float brickFlash[]; };

// Distance along the pixel-centre ray to the nearest surface any sample of the pixel shows.
float sceneDistance(ivec3 id, vec3 eye, vec3 ray) {
  float nearest = 1e30;
  for (int s = 0; s < SAMPLES; ++s) {
    uint visibility = visibilityAt(id, s);
    if (visibility == 0u) continue;
    uint triangle = visibility - 1u;
    WorldTriangle w = worldTriangle(draws[drawOfTriangle(triangle)], triangle);
    vec3 tv = eye - w.p0;
    nearest = min(nearest, max(planeHit(ray, w.e1, w.e2, tv, cross(tv, w.e1)).z, 0.0));
  }
  return nearest;
}

struct Hit {
  float t;      // along the ray; 1e30: none
  int cascade;
  int slot;     // in the cascade
  int brick;    // in the flash buffer
  bool line;    // the relocation line, not the sphere
  vec3 centre;  // the relocated probe
};

// Tests the probe at logical grid point g of cascade k against the ray.
void testProbe(int k, ivec3 g, vec3 eye, vec3 ray, inout Hit hit) {
  CascadeDesc c = field.cascades[k];
  ivec3 physical = pcPhysicalCoord(c, g);
  int slot = pcProbeSlot(c, physical);
  vec4 record = probes[c.firstProbe + slot];
  vec3 grid = pcProbeGridPosition(c, g);
  vec3 centre = grid + record.xyz;
  float t = pcRaySphere(eye, ray, centre, PC_PROBE_VIEW_RADIUS * c.spacing);
  bool line = false;
  if (frame.probeView.offsets != 0 && length(record.xyz) > PC_PROBE_VIEW_MIN_OFFSET * c.spacing) {
    float tl = pcRayCapsule(eye, ray, grid, centre, PC_PROBE_VIEW_LINE_RADIUS * c.spacing);
    if (tl >= 0.0 && (t < 0.0 || tl < t)) {
      t = tl;
      line = true;
    }
  }
  if (t < 0.0 || t >= hit.t) return;
  hit.t = t;
  hit.cascade = k;
  hit.slot = slot;
  hit.brick = frame.probeView.brickBase[k] + pcBrickIndex(c, physical);
  hit.line = line;
  hit.centre = centre;
}

// Walks cascade k's cells along the ray up to distance `limit`.
void walkCascade(int k, vec3 eye, vec3 ray, float limit, inout Hit hit) {
  CascadeDesc c = field.cascades[k];
  // Grid units: probe g at integer point g; cells [i, i + 1); cells -1 .. counts - 1 hold
  // every sphere and line.
  vec3 u0 = (eye - c.origin) / c.spacing;
  vec3 d = ray;
  vec3 inv = vec3(abs(d.x) > 1e-12 ? 1.0 / d.x : 1e30, abs(d.y) > 1e-12 ? 1.0 / d.y : 1e30,
                  abs(d.z) > 1e-12 ? 1.0 / d.z : 1e30);
  vec3 lo = (vec3(-1.0) - u0) * inv, hi = (vec3(c.counts) - u0) * inv;
  vec3 tmin3 = min(lo, hi), tmax3 = max(lo, hi);
  float tEnter = max(max(tmin3.x, tmin3.y), max(tmin3.z, 0.0));
  float tExit = min(min(tmax3.x, tmax3.y), tmax3.z);
  float tLimit = min(limit, hit.t) / c.spacing;
  if (tEnter > tExit || tEnter > tLimit) return;
  vec3 p = u0 + d * tEnter;
  ivec3 cell = clamp(ivec3(floor(p)), ivec3(-1), c.counts - 1);
  ivec3 stepDir = ivec3(d.x >= 0.0 ? 1 : -1, d.y >= 0.0 ? 1 : -1, d.z >= 0.0 ? 1 : -1);
  vec3 tNext = (vec3(cell) + vec3(greaterThanEqual(d, vec3(0.0))) - u0) * inv;
  vec3 tDelta = abs(inv);
  int steps = c.counts.x + c.counts.y + c.counts.z + 6;
  for (int i = 0; i < steps; ++i) {
    for (int corner = 0; corner < 8; ++corner) {
      ivec3 g = cell + ivec3(corner & 1, (corner >> 1) & 1, corner >> 2);
      if (any(lessThan(g, ivec3(0))) || any(greaterThanEqual(g, c.counts))) continue;
      testProbe(k, g, eye, ray, hit);
    }
    float cellExit = min(min(tNext.x, tNext.y), tNext.z);
    // A hit inside this cell is nearer than anything a later cell holds.
    if (hit.t / c.spacing <= cellExit || cellExit > tLimit || cellExit > tExit) return;
    if (tNext.x <= tNext.y && tNext.x <= tNext.z) {
      cell.x += stepDir.x;
      tNext.x += tDelta.x;
    } else if (tNext.y <= tNext.z) {
      cell.y += stepDir.y;
      tNext.y += tDelta.y;
    } else {
      cell.z += stepDir.z;
      tNext.z += tDelta.z;
    }
  }
}

vec3 shade(Hit hit, vec3 eye, vec3 ray) {
  // Colours meant as colours (states, lines) are divided by the exposure tone mapping applies.
  float unexposed = 1.0 / max(frame.exposure, 1e-6);
  if (hit.line) return pcProbeLineColor() * unexposed;
  vec3 n = normalize(eye + ray * hit.t - hit.centre);
  int state = int(probes[field.cascades[hit.cascade].firstProbe + hit.slot].w);
  vec3 color;
  if (frame.probeView.mode == PC_PROBE_VIEW_STATE || !pcProbeHasData(state)) {
    // Lit from the viewer, so the spheres read as round.
    color = pcProbeStateColor(state) * (0.35 + 0.65 * max(dot(n, -ray), 0.0)) * unexposed;
    if (frame.probeView.mode != PC_PROBE_VIEW_STATE) color *= 0.3;  // no data: dim grey
  } else {
    // What a white diffuse sphere lit by the probe's irradiance would send back.
    vec3 e = max(pcFetchIrradiance(hit.cascade, hit.slot, n), vec3(0.0));
    color = e * e * e * e * e * (1.0 / PC_PI);
  }
  if (frame.probeView.flash != 0) color = pcApplyFlash(color, brickFlash[hit.brick]);
  return color;
}

void main() {
  ivec3 id = ivec3(gl_GlobalInvocationID);
  ivec2 size = ivec2(frame.viewport);
  if (id.x >= size.x || id.y >= size.y || frame.fieldPresent == 0) return;
  vec3 eye = frame.views[id.z].position.xyz;
  vec3 ray = normalize(rayUnderPixel(id.z, vec2(id.xy) + 0.5));
  float limit = sceneDistance(id, eye, ray);
  Hit hit;
  hit.t = 1e30;
  for (int k = 0; k < field.cascadeCount; ++k) {
    if (frame.probeView.cascade < 0 || frame.probeView.cascade == k)
      walkCascade(k, eye, ray, limit, hit);
  }
  if (hit.t < limit) imageStore(hdrImage, id, vec4(shade(hit, eye, ray), 1.0));
}
