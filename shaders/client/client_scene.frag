#version 460
// Main pass: emission per pixel, plus the G-buffer the lighting pass (client_indirect.comp:
// direct light with shadow maps, and the field) reads per sample: position, shading normal,
// albedo. Conventions follow the
// CPU renders (cpu/lighting.cpp, cpu/embree_scene.cpp): two-sided diffuse surfaces whose
// shading normal is turned to the viewer's side, one-sided emitters.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_multiview : require
#include "client_common.glsl"

layout(constant_id = 0) const int TEXTURE_COUNT = 1;

layout(set = 0, binding = PC_BIND_TEXTURES) uniform sampler2D textures[TEXTURE_COUNT];

layout(location = 0) in vec3 inWorld;
layout(location = 1) in vec3 inNormal;
layout(location = 2) in vec2 inUv;
layout(location = 3) flat in int inDraw;

layout(location = 0) out vec4 outDirect;
layout(location = 1) out float outDistance;  // from the eye along the pixel-centre ray
layout(location = 2) out vec4 outNormal;
layout(location = 3) out vec4 outAlbedo;

vec3 textureRgb(int index, vec2 uv) {
  if (index < 0 || index >= TEXTURE_COUNT) return vec3(1.0);
  return texture(textures[index], uv).rgb;
}

// Smooth fall-off to zero at `range` (as lighting.cpp).
void main() {
  DrawData d = draws[inDraw];
  vec3 P = inWorld;
  vec3 V = normalize(frame.views[gl_ViewIndex].position.xyz - P);
  // Geometric normal from the triangle's plane, turned toward the viewer.
  vec3 ng = normalize(cross(dFdx(P), dFdy(P)));
  if (dot(ng, V) < 0.0) ng = -ng;
  float len = length(inNormal);
  vec3 ns = len > 0.0 ? inNormal / len : ng;
  vec3 N = dot(ns, ng) < 0.0 ? -ns : ns;

  vec3 albedo = d.baseColor.rgb * textureRgb(d.textures.x, inUv);
  vec3 emission = gl_FrontFacing ? d.emissive.rgb * textureRgb(d.textures.y, inUv) : vec3(0.0);
  // Direct light from lights is added in the compute pass (client_direct.glsl); emission here.
  outDirect = vec4(emission, 1.0);
  // inWorld is interpolated at the pixel centre, so it lies on the pixel-centre ray: its
  // distance from the eye is all the lighting pass needs to rebuild it.
  outDistance = length(P - frame.views[gl_ViewIndex].position.xyz);
  outNormal = vec4(N * 0.5 + 0.5, 0.0);
  outAlbedo = vec4(albedo, 0.0);
}
