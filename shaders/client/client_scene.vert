#version 460
// Main pass vertices: object -> world -> the view of this multiview slot.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_multiview : require
#include "client_common.glsl"

layout(location = 0) in vec3 inPosition;
layout(location = 1) in vec3 inNormal;
layout(location = 2) in vec2 inUv;

layout(location = 0) out vec3 outWorld;
layout(location = 1) out vec3 outNormal;
layout(location = 2) out vec2 outUv;
layout(location = 3) flat out int outDraw;
// The depth pre-pass and the shading pass run this shader in two pipelines; their depths must
// match bit for bit for the shading pass's EQUAL test.
invariant gl_Position;

void main() {
  DrawData d = draws[gl_InstanceIndex];
  vec4 world = d.model * vec4(inPosition, 1.0);
  outWorld = world.xyz;
  outNormal = mat3(d.normalMatrix) * inNormal;
  outUv = inUv;
  outDraw = gl_InstanceIndex;
  gl_Position = frame.views[gl_ViewIndex].viewProj * world;
}
