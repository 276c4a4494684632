#version 460
// Main pass: the visibility buffer. Each sample keeps only which triangle covers it (the
// draw's first triangle id + the primitive index, + 1 so that 0 means sky); the lighting pass
// (client_indirect.comp) rebuilds the surface from the triangle and the pixel-centre ray.
// Four bytes per sample instead of a G-buffer's twenty: on GPUs with few graphics units (an
// H100) the main pass is bound by the bytes its samples write.
#extension GL_GOOGLE_include_directive : require

layout(location = 0) flat in uint inTriangleBase;
layout(location = 0) out uint outVisibility;

void main() { outVisibility = inTriangleBase + uint(gl_PrimitiveID) + 1u; }
