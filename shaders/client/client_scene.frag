#version 460
// Main pass: the visibility buffer. Each sample keeps only which triangle covers it (the
// draw's first triangle id + the primitive index, + 1 so that 0 means sky); the lighting pass
// (client_indirect.comp) rebuilds the surface from the triangle and the pixel-centre ray.
// Four bytes per sample instead of a G-buffer's twenty: on GPUs with few graphics units (an
// H100) the main pass is bound by the bytes its samples write. In scenes with cut-outs, a
// cut-out's fragment is discarded where its material is open under the fragment's centre
// (client_surface.glsl; the compute rasterizer tests each sample).
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_multiview : require
#include "client_common.glsl"

layout(constant_id = 1) const int TEXTURE_COUNT = 1;
layout(constant_id = 3) const bool CUT_OUTS = false;  // any cut-out material in the scene
#include "client_surface.glsl"

layout(location = 0) flat in uint inTriangleBase;
layout(location = 1) flat in uint inDraw;
layout(location = 0) out uint outVisibility;

void main() {
  uint triangle = inTriangleBase + uint(gl_PrimitiveID);
  if (CUT_OUTS && drawIsCutOut(draws[inDraw])) {
    int view = int(gl_ViewIndex);
    vec3 eye = frame.views[view].position.xyz;
    if (!coveredOnRay(draws[inDraw], triangle, eye, rayUnderPixel(view, gl_FragCoord.xy)))
      discard;
  }
  outVisibility = triangle + 1u;
}
