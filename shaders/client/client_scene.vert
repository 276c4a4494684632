#version 460
// Main pass vertices: object -> world -> the view of this multiview slot. The fragment
// shader only names the triangle (and tests cut-outs), so the draw's first triangle id and
// its index are all that is passed on.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_multiview : require
#include "client_common.glsl"

layout(location = 0) in vec3 inPosition;

layout(location = 0) flat out uint outTriangleBase;
layout(location = 1) flat out uint outDraw;  // for cut-outs (client_scene.frag)
// The optional depth pre-pass and the visibility pass run this shader in two pipelines; their
// depths must match bit for bit for the second pass's EQUAL test.
invariant gl_Position;

void main() {
  DrawData d = draws[gl_InstanceIndex];
  outTriangleBase = uint(d.geometry.z);
  outDraw = uint(gl_InstanceIndex);
  gl_Position = frame.views[gl_ViewIndex].viewProj * (d.model * vec4(inPosition, 1.0));
}
