#version 460
// Shadow maps of scenes with cut-outs: a cut-out casts no shadow where its material is open
// (client_surface.glsl, the CPU's coveredAt at the fragment's interpolated coordinates).
// Scenes without cut-outs draw their shadow maps without a fragment shader.
#extension GL_GOOGLE_include_directive : require
#include "client_common.glsl"

layout(constant_id = 1) const int TEXTURE_COUNT = 1;
#include "client_surface.glsl"

layout(location = 0) in vec2 inUv;
layout(location = 1) flat in uint inDraw;

void main() {
  DrawData d = draws[inDraw];
  if (drawIsCutOut(d) && !coveredAtUv(d, inUv)) discard;
}
