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

// Indirect light reflected toward V by surface `f` (client_surface.glsl): the field's
// irradiance through the BRDF's diffuse part and, on glossy surfaces with
// PC_SAMPLE_SPECULAR, the field's GGX-filtered radiance toward the mirror direction through the
// split-sum table (shaders/interop/specular_probe.h), as the CPU probe-lit render shades it.
// The vertex normal places the sample and weighs the probes; the shading (normal-mapped)
// normal looks up the irradiance and reflects V. The sampler's normal bias and backface and
// visibility weights describe where the surface itself lies: moved along a perturbed normal,
// the biased point could sink into the surface or reach probes that do not see it, and light
// would leak (probe_sampling.h). Where no probe near P holds data, the plain ambient term
// stands in (the shared rule).
vec3 fieldReflected(Surface f, vec3 V) {
  vec3 E = frame.ambient.rgb;
  vec3 S = frame.ambient.rgb * (1.0 / PC_PI);
  vec2 ab = vec2(0.0);
  bool specular = (frame.sampleFlags & PC_SAMPLE_SPECULAR) != 0 &&
                  pcHasSpecularLobe(f.metallic, f.roughness);
  if (frame.fieldPresent != 0) {
    int flags = specular ? frame.sampleFlags : frame.sampleFlags & ~PC_SAMPLE_SPECULAR;
    E = pcSampleFieldOrAmbientLit(field, f.position, f.vertexNormal, f.normal, V, flags,
                                  frame.ambient.rgb, pcSpecularDirection(f.normal, V, f.roughness),
                                  pcGgxSpecularZh(f.roughness), S).rgb;
  }
  if (specular) ab = splitSumAt(max(dot(f.normal, V), 0.0), f.roughness);
  else S = vec3(0.0);
  return pcIndirectReflected(f.normal, V, f.albedo, f.metallic, f.roughness, E, S, ab);
}

void main() {
  ivec3 id = ivec3(gl_GlobalInvocationID);
  ivec2 size = ivec2(frame.viewport);
  if (id.x >= size.x || id.y >= size.y) return;
  ClientView view = frame.views[id.z];
  vec3 eye = view.position.xyz;

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
      vec3 indirect = fieldReflected(f, V);
      if (occlusion < 1.0) indirect *= pcAoMultiBounce(occlusion, f.albedo);
      shaded[s] = f.emission + indirect +
                  directReflected(f.position, f.normal, f.vertexNormal, V, f.albedo, f.metallic,
                                  f.roughness);
    }
    sum += shaded[s];
  }
  imageStore(hdrImage, id, vec4(sum / float(SAMPLES), 1.0));
}
