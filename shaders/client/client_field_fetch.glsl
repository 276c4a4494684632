// The field's bindings (client_frame.h) and the fetch hooks of shaders/interop/probe_sampling.h
// over them, then the sampling code itself: what the lighting pass and the probe view read.
// Needs client_common.glsl first.
#ifndef PC_CLIENT_FIELD_FETCH_GLSL
#define PC_CLIENT_FIELD_FETCH_GLSL

layout(set = 0, binding = PC_CLIENT_BIND_FIELD_DESC) uniform FieldBlock { FieldDesc field; };
layout(set = 0, binding = PC_CLIENT_BIND_PROBES, std430) readonly buffer ProbeBlock { vec4 probes[]; };
layout(set = 0, binding = PC_CLIENT_BIND_IRRADIANCE) uniform sampler2D irradianceAtlas;
layout(set = 0, binding = PC_CLIENT_BIND_DEPTH) uniform sampler2D depthAtlas;
layout(set = 0, binding = PC_CLIENT_BIND_OCCLUSION) uniform sampler2D occlusionAtlas;

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

#endif
