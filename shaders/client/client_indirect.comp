#version 460
// Lighting pass: direct light from the lights (with shadow maps) and indirect light from the
// field's cascades for every pixel, added to the resolved emission. Shading is per sample of
// the multisampled G-buffer, but samples written by the same fragment hold bit-identical
// distances and normals, so each pixel is lit once per distinct surface it covers (once inside
// triangles, a few times on edges): the result equals shading every sample, at per-pixel cost.
#extension GL_GOOGLE_include_directive : require
#include "client_common.glsl"
#include "../interop/probe_math.h"
#include "client_direct.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
layout(constant_id = 0) const int SAMPLES = 4;

layout(set = 0, binding = PC_BIND_FIELD_DESC) uniform FieldBlock { FieldDesc field; };
layout(set = 0, binding = PC_BIND_PROBES, std430) readonly buffer ProbeBlock { vec4 probes[]; };
layout(set = 0, binding = PC_BIND_IRRADIANCE) uniform sampler2D irradianceAtlas;
layout(set = 0, binding = PC_BIND_DEPTH) uniform sampler2D depthAtlas;
layout(set = 0, binding = PC_BIND_OCCLUSION) uniform sampler2D occlusionAtlas;
layout(set = 0, binding = PC_BIND_G_POSITION) uniform sampler2DMSArray gPosition;
layout(set = 0, binding = PC_BIND_G_NORMAL) uniform sampler2DMSArray gNormal;
layout(set = 0, binding = PC_BIND_G_ALBEDO) uniform sampler2DMSArray gAlbedo;
layout(set = 0, binding = PC_BIND_DIRECT) uniform sampler2DArray directLight;  // emission
layout(set = 0, binding = PC_BIND_HDR_IMAGE, rgba32f) uniform writeonly image2DArray hdrImage;

// Fetch hooks of shaders/interop/probe_sampling.h: bilinear reads of a bordered tile, done by
// the texture unit exactly as the CPU's bilinear() does on its copy of the atlas.
#define PC_FIELD_PARAM
#define PC_FIELD_ARG
vec2 atlasCoord(int cascade, int slot, vec3 dir, int texels, vec2 atlasSize) {
  ivec2 origin = pcAtlasTileOrigin(field.cascades[cascade], slot, texels + 2);
  return (vec2(origin) + pcTileCoord(dir, texels)) / atlasSize;
}
vec3 pcFetchIrradiance(int cascade, int slot, vec3 dir) {
  vec2 size = vec2(textureSize(irradianceAtlas, 0));
  return textureLod(irradianceAtlas, atlasCoord(cascade, slot, dir, PC_IRRADIANCE_TEXELS, size), 0.0).rgb;
}
vec2 pcFetchDepth(int cascade, int slot, vec3 dir) {
  vec2 size = vec2(textureSize(depthAtlas, 0));
  return textureLod(depthAtlas, atlasCoord(cascade, slot, dir, PC_DEPTH_TEXELS, size), 0.0).rg;
}
float pcFetchOcclusion(int cascade, int slot, vec3 dir) {
  vec2 size = vec2(textureSize(occlusionAtlas, 0));
  return textureLod(occlusionAtlas, atlasCoord(cascade, slot, dir, PC_OCCLUSION_TEXELS, size), 0.0).r;
}
vec4 pcFetchProbe(int cascade, int slot) {
  return probes[field.cascades[cascade].firstProbe + slot];
}
#include "../interop/probe_sampling.h"

vec3 skyRadiance(vec3 dir) {
  float y = clamp(dir.y, -1.0, 1.0);
  if (y >= 0.0) return mix(frame.skyHorizon.rgb, frame.skyZenith.rgb, y);
  return mix(frame.skyHorizon.rgb, frame.skyGround.rgb, -y);
}

vec3 fieldIrradiance(vec3 P, vec3 N, vec3 V) {
  if (frame.fieldPresent == 0) return frame.ambient.rgb;
  float coverage = 0.0;
  vec4 s = pcSampleField(field, P, N, V, frame.sampleFlags, coverage);
  // Where no cascade holds data yet, the plain ambient term stands in.
  return mix(frame.ambient.rgb, s.rgb, coverage);
}

void main() {
  ivec3 id = ivec3(gl_GlobalInvocationID);
  ivec2 size = ivec2(frame.viewport);
  if (id.x >= size.x || id.y >= size.y) return;
  ClientView view = frame.views[id.z];
  vec3 eye = view.position.xyz;

  // The pixel-centre ray, on which every sample's surface point lies (see client_scene.frag).
  vec2 ndc = (vec2(id.xy) + 0.5) / vec2(size) * 2.0 - 1.0;
  vec4 far = view.invViewProj * vec4(ndc, 0.5, 1.0);
  vec3 ray = normalize(far.xyz / far.w - eye);

  float distances[SAMPLES];
  vec4 normals[SAMPLES];
  vec3 shaded[SAMPLES];
  vec3 sum = vec3(0.0);
  for (int s = 0; s < SAMPLES; ++s) {
    float t = texelFetch(gPosition, id, s).r;
    vec4 n = texelFetch(gNormal, id, s);
    distances[s] = t;
    normals[s] = n;
    shaded[s] = vec3(0.0);
    if (t == 0.0) {
      // No geometry: the sky through the pixel centre.
      shaded[s] = skyRadiance(ray);
      distances[s] = -1.0;  // matches no surface
      sum += shaded[s];
      continue;
    }
    int same = -1;
    for (int u = 0; u < s; ++u) {
      if (distances[u] == t && normals[u] == n) {
        same = u;
        break;
      }
    }
    if (same >= 0) {
      shaded[s] = shaded[same];
    } else {
      vec3 P = eye + ray * t;
      vec3 N = normalize(n.xyz * 2.0 - 1.0);
      vec3 albedo = texelFetch(gAlbedo, id, s).rgb;
      vec3 V = -ray;
      shaded[s] = albedo * (1.0 / PC_PI) * (directIrradiance(P, N) + fieldIrradiance(P, N, V));
    }
    sum += shaded[s];
  }
  vec3 direct = texelFetch(directLight, id, 0).rgb;
  imageStore(hdrImage, id, vec4(direct + sum / float(SAMPLES), 1.0));
}
