#version 460
// Lighting pass: rebuilds each sample's surface from the visibility buffer (client_surface.glsl)
// and lights it: emission, direct light from the lights (with shadow maps) and indirect light
// from the field's cascades. Shading is per sample of the multisampled visibility buffer, but
// samples covered by the same triangle share the pixel-centre surface point, so each pixel is
// lit once per distinct triangle it covers (once inside triangles, a few times on edges): the
// result equals shading every sample, at per-pixel cost. The indirect light is darkened by
// screen-space ambient occlusion (GTAO, shaders/interop/screen_ao.h) where the probes are too
// coarse to see a contact: once per pixel, from the surfaces client_ao_surfaces.comp wrote.
#extension GL_GOOGLE_include_directive : require
#include "client_common.glsl"
#include "../interop/probe_math.h"
#include "client_direct.glsl"
#include "client_ao_buffer.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
layout(constant_id = 0) const int SAMPLES = 4;
layout(constant_id = 1) const int TEXTURE_COUNT = 1;
// true: the visibility ids come from the compute rasterizer's buffer, not the raster image.
layout(constant_id = 2) const bool VIS_BUFFER = false;
#include "client_surface.glsl"

#include "client_field_fetch.glsl"
#include "client_visibility.glsl"
#include "client_samples.glsl"

// Hooks of shaders/interop/screen_ao_horizons.h: the surface buffer and the view's rays.
#define PC_AO_PARAM int view,
#define PC_AO_ARG view,
vec4 pcAoSurface(int view, ivec2 p) {
  ivec2 size = ivec2(frame.viewport);
  if (p.x < 0 || p.y < 0 || p.x >= size.x || p.y >= size.y) return vec4(0.0);
  return aoSurfaces[2u * aoPixelIndex(view, p)];
}
vec3 pcAoNormal(int view, ivec2 p) { return aoSurfaces[2u * aoPixelIndex(view, p) + 1u].xyz; }
vec3 pcAoRay(int view, vec2 pixel) { return normalize(rayUnderPixel(view, pixel)); }
#include "../interop/screen_ao_horizons.h"

// The pixel's occlusion of the indirect light (1: none), from the surface under its centre.
float pixelOcclusion(int view, ivec2 p) {
  if (frame.aoRadius <= 0.0 || frame.fieldPresent == 0) return 1.0;
  uint i = aoPixelIndex(view, p);
  vec4 surface = aoSurfaces[2u * i];
  if (surface.w <= 0.0) return 1.0;
  vec3 P = surface.xyz;
  float radius = pcAoRadius(field, frame.views[view].position.xyz + P, frame.aoRadius);
  return pcScreenAo(view, p, P, aoSurfaces[2u * i + 1u].xyz, radius);
}

// The split-sum table's (A, B) at (N.V, roughness), from the frame's uploaded copy.
#define PC_SPLIT_SUM_PAIR(p) frame.splitSum[p]
#include "../split_sum_lookup.glsl"

vec3 skyRadiance(vec3 dir) {
  float y = clamp(dir.y, -1.0, 1.0);
  if (y >= 0.0) return mix(frame.skyHorizon.rgb, frame.skyZenith.rgb, y);
  return mix(frame.skyHorizon.rgb, frame.skyGround.rgb, -y);
}

// Whether surface `f` takes the field's specular lobe besides its irradiance.
bool hasSpecular(Surface f) {
  return (frame.sampleFlags & PC_SAMPLE_SPECULAR) != 0 &&
         pcHasSpecularLobe(f.metallic, f.roughness);
}

// Indirect light reflected toward V by surface `f` (client_surface.glsl), in two steps
// (fieldLight, then reflectedFrom): the field's
// irradiance through the BRDF's diffuse part and, on glossy surfaces with
// PC_SAMPLE_SPECULAR, the field's GGX-filtered radiance toward the mirror direction through the
// split-sum table (shaders/interop/specular_probe.h), as the CPU probe-lit render shades it.
// The vertex normal places the sample and weighs the probes; the shading (normal-mapped)
// normal looks up the irradiance and reflects V. The sampler's normal bias and backface and
// visibility weights describe where the surface itself lies: moved along a perturbed normal,
// the biased point could sink into the surface or reach probes that do not see it, and light
// would leak (probe_sampling.h). Where no probe near P holds data, the plain ambient term
// stands in (the shared rule).
//
// fieldLight: the field's light at surface `f` seen along V: irradiance E and, on glossy surfaces, the
// filtered radiance S toward the mirror direction (zero elsewhere).
void fieldLight(Surface f, vec3 V, out vec3 E, out vec3 S) {
  E = frame.ambient.rgb;
  S = frame.ambient.rgb * (1.0 / PC_PI);
  bool specular = hasSpecular(f);
  if (frame.fieldPresent != 0) {
    int flags = specular ? frame.sampleFlags : frame.sampleFlags & ~PC_SAMPLE_SPECULAR;
    E = pcSampleFieldOrAmbientLit(field, f.position, f.vertexNormal, f.normal, V, flags,
                                  frame.ambient.rgb, pcSpecularDirection(f.normal, V, f.roughness),
                                  pcGgxSpecularZh(f.roughness), S).rgb;
  }
  if (!specular) S = vec3(0.0);
}

vec3 reflectedFrom(Surface f, vec3 V, vec3 E, vec3 S) {
  vec2 ab = hasSpecular(f) ? splitSumAt(max(dot(f.normal, V), 0.0), f.roughness) : vec2(0.0);
  return pcIndirectReflected(f.normal, V, f.albedo, f.metallic, f.roughness, E, S, ab);
}

// ---- foveated field sampling ----
// Outside the fovea a workgroup (8x8 pixels) samples the field once per 2x2 quad: its first 16
// invocations (one half of a 32-wide subgroup, so the other subgroup skips the sampling
// altogether) each light the surface under their quad's first pixel centre and leave it here.
// Every pixel then takes its quad's light where its own surface lies on the same plane, facing
// the same way, with the same lobes; elsewhere (edges, small objects) it samples the field
// itself. The field's light changes over a probe spacing, so a neighbour's is that of the
// pixel to within its small offset along the surface.
shared vec4 sQuadE[16];  // rgb: E; a: 1 where the quad's pixel holds a surface
shared vec4 sQuadS[16];  // rgb: S; a: 1 where it was sampled with the specular lobe
shared vec4 sQuadP[16];  // xyz: surface point (eye-relative)
shared vec4 sQuadN[16];  // xyz: shading normal

bool workgroupOutsideFovea() {
  if (frame.foveaRadius <= 0.0) return false;
  vec2 size = frame.viewport;
  // The workgroup's pixel nearest the view's centre decides, so that no pixel inside the
  // fovea is ever shared.
  vec2 lo = vec2(gl_WorkGroupID.xy * gl_WorkGroupSize.xy), hi = lo + vec2(gl_WorkGroupSize.xy);
  vec2 nearest = clamp(0.5 * size, lo, hi);
  vec2 d = (nearest - 0.5 * size) / (0.5 * size);
  return length(d) > frame.foveaRadius;
}

void sampleQuads(int view, vec3 eye) {
  uint t = gl_LocalInvocationIndex;
  if (t >= 16u) return;
  ivec2 pixel = ivec2(gl_WorkGroupID.xy * gl_WorkGroupSize.xy) + 2 * ivec2(t % 4u, t / 4u);
  sQuadE[t] = vec4(0.0);
  ivec2 size = ivec2(frame.viewport);
  if (pixel.x >= size.x || pixel.y >= size.y) return;
  uint visibility = visibilityAt(ivec3(pixel, view), 0);
  if (visibility == 0u) return;
  vec2 centre = vec2(pixel) + 0.5;
  vec3 ray = normalize(rayUnderPixel(view, centre));
  vec3 rayDx = rayUnderPixel(view, centre + vec2(1.0, 0.0));
  vec3 rayDy = rayUnderPixel(view, centre + vec2(0.0, 1.0));
  Surface f = surfaceOf(visibility, eye, ray, rayDx, rayDy, ray);
  vec3 E, S;
  fieldLight(f, -ray, E, S);
  sQuadE[t] = vec4(E, 1.0);
  sQuadS[t] = vec4(S, hasSpecular(f) ? 1.0 : 0.0);
  sQuadP[t] = vec4(f.position, 0.0);
  sQuadN[t] = vec4(f.normal, 0.0);
}

// The quad's light where surface `f` matches the quad's, else the field sampled at `f`.
void quadOrOwnLight(Surface f, vec3 V, uint quad, out vec3 E, out vec3 S) {
  vec4 q = sQuadE[quad];
  if (q.a > 0.0) {
    vec3 P = sQuadP[quad].xyz, N = sQuadN[quad].xyz;
    // Same plane to within a hundredth of the distance (a pixel's footprint is far smaller),
    // same facing, and the lobe the pixel needs.
    bool samePlane = abs(dot(f.position - P, N)) < 0.01 * length(P) + 1e-4;
    bool sameFacing = dot(f.normal, N) > 0.95;
    bool lobe = !hasSpecular(f) || sQuadS[quad].a > 0.0;
    if (samePlane && sameFacing && lobe) {
      E = q.rgb;
      S = hasSpecular(f) ? sQuadS[quad].rgb : vec3(0.0);
      return;
    }
  }
  fieldLight(f, V, E, S);
}

void main() {
  ivec3 id = ivec3(gl_GlobalInvocationID);
  ivec2 size = ivec2(frame.viewport);
  ClientView view = frame.views[id.z];
  vec3 eye = view.position.xyz;
  // Uniform over the workgroup (it depends on the workgroup alone), so the barrier is too.
  bool quadShared = frame.fieldPresent != 0 && workgroupOutsideFovea();
  if (quadShared) {
    sampleQuads(id.z, eye);
    barrier();
  }
  if (id.x >= size.x || id.y >= size.y) return;
  uint quad = uint(gl_LocalInvocationID.x / 2u) + 4u * uint(gl_LocalInvocationID.y / 2u);

  // The pixel-centre ray, on which every sample's surface point lies (client_surface.glsl).
  vec2 centre = vec2(id.xy) + 0.5;
  vec3 ray = normalize(rayUnderPixel(id.z, centre));
  // The next pixels' centre rays, for the texture footprint.
  vec3 rayDx = rayUnderPixel(id.z, centre + vec2(1.0, 0.0));
  vec3 rayDy = rayUnderPixel(id.z, centre + vec2(0.0, 1.0));

  float occlusion = pixelOcclusion(id.z, id.xy);
  uint ids[SAMPLES];
  vec3 shaded[SAMPLES];
  vec3 sum = vec3(0.0);
  // Where the pixel holds more than one triangle, each is lit where a sample of its own shows
  // it, not on the centre ray (client_surface.glsl).
  bool onePrimitive = true;
  for (int s = 0; s < SAMPLES; ++s) {
    ids[s] = visibilityAt(id, s);
    onePrimitive = onePrimitive && ids[s] == ids[0];
  }
  for (int s = 0; s < SAMPLES; ++s) {
    uint visibility = ids[s];
    int same = -1;
    for (int u = 0; u < s; ++u) {
      if (ids[u] == visibility) {
        same = u;
        break;
      }
    }
    if (same >= 0) {
      shaded[s] = shaded[same];
    } else if (visibility == 0u) {
      shaded[s] = skyRadiance(ray);  // no geometry: the sky through the pixel centre
    } else {
      vec3 sampleRay =
          onePrimitive ? ray : normalize(rayUnderPixel(id.z, vec2(id.xy) + samplePosition(s)));
      Surface f = surfaceOf(visibility, eye, ray, rayDx, rayDy, sampleRay);
      vec3 V = -ray;
      vec3 E, S;
      if (quadShared) quadOrOwnLight(f, V, quad, E, S);
      else fieldLight(f, V, E, S);
      vec3 indirect = reflectedFrom(f, V, E, S);
      if (occlusion < 1.0) indirect *= pcAoMultiBounce(occlusion, f.albedo);
      shaded[s] = f.emission + indirect +
                  directReflected(f.position, f.normal, f.vertexNormal, V, f.albedo, f.metallic,
                                  f.roughness);
    }
    sum += shaded[s];
  }
  imageStore(hdrImage, id, vec4(sum / float(SAMPLES), 1.0));
}
