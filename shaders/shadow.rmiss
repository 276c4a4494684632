#version 460
// Shadow rays skip closest-hit shaders and stop at the first hit; reaching this shader means
// nothing was in the way.
#extension GL_EXT_ray_tracing : require

layout(location = 0) rayPayloadInEXT uint visible;

void main() { visible = 1u; }
