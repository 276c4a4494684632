#version 460
// Shadow map depth: object -> world -> the light's view of this shadow layer.
#extension GL_GOOGLE_include_directive : require
#include "client_common.glsl"

layout(location = 0) in vec3 inPosition;
layout(push_constant) uniform Push { mat4 lightViewProj; } push;

void main() {
  gl_Position = push.lightViewProj * (draws[gl_InstanceIndex].model * vec4(inPosition, 1.0));
}
