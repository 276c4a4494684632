#version 460
// Shadow map depth: object -> world -> the light's view of this shadow layer. Texture
// coordinates and the draw go on for cut-outs (client_shadow.frag, only in scenes with them).
#extension GL_GOOGLE_include_directive : require
#include "client_common.glsl"
#include "client_geometry.glsl"

layout(constant_id = 3) const bool CUT_OUTS = false;  // any cut-out material in the scene

layout(location = 0) in vec3 inPosition;
layout(push_constant) uniform Push { ShadowPush push; };

layout(location = 0) out vec2 outUv;
layout(location = 1) flat out uint outDraw;

void main() {
  // gl_VertexIndex includes the draw's vertex offset: an index into the packed vertices.
  outUv = CUT_OUTS ? vertexAt(uint(gl_VertexIndex)).uv : vec2(0.0);
  outDraw = uint(gl_InstanceIndex);
  // From the shadow origin: no large translation cancels against large positions here.
  const vec3 world = (draws[gl_InstanceIndex].model * vec4(inPosition, 1.0)).xyz;
  gl_Position = push.fromOrigin * vec4(world - push.origin.xyz, 1.0);
}
