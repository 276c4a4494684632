#version 460
// Exposure and the shared tone curve (shaders/interop/tonemap.h) onto an 8-bit UNORM target
// (sRGB encoded here, so headless images and window screenshots hold the same bytes), and
// the overlay text on top.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_multiview : require
#include "client_common.glsl"
#include "../interop/tonemap.h"

layout(set = 0, binding = PC_CLIENT_BIND_HDR_TEXTURE) uniform sampler2DArray hdrTexture;
layout(set = 0, binding = PC_CLIENT_BIND_OVERLAY, std430) readonly buffer OverlayBlock { OverlayText overlay; };

layout(location = 0) out vec4 outColor;
// Stereo into one image twice the render width: the left eye in the left half.
layout(constant_id = 0) const bool SIDE_BY_SIDE = false;

const int kScale = 2;    // screen pixels per font pixel
const int kMargin = 6;   // pixels from the top-left corner

// 1 where the overlay text covers pixel p, 0 on its dark backdrop, -1 outside the overlay.
float overlayText(ivec2 p) {
  if (frame.overlayLines <= 0) return -1.0;
  ivec2 cell = ivec2(PC_FONT_COLUMNS + 1, PC_FONT_ROWS + 3) * kScale;
  ivec2 q = p - ivec2(kMargin);
  if (q.x < 0 || q.y < 0) return -1.0;
  ivec2 c = q / cell;
  if (c.x >= PC_OVERLAY_COLUMNS || c.y >= frame.overlayLines) return -1.0;
  uint code = overlay.text[c.y * PC_OVERLAY_COLUMNS + c.x];
  if (code == 0u) return -1.0;
  ivec2 f = (q - c * cell) / kScale - ivec2(0, 1);
  if (f.x >= PC_FONT_COLUMNS || f.y < 0 || f.y >= PC_FONT_ROWS || code < uint(PC_FONT_FIRST) ||
      code >= uint(PC_FONT_FIRST + PC_FONT_GLYPHS)) {
    return 0.0;
  }
  uint row = overlay.glyphs[(code - uint(PC_FONT_FIRST)) * uint(PC_FONT_ROWS) + uint(f.y)];
  return ((row >> uint(PC_FONT_COLUMNS - 1 - f.x)) & 1u) != 0u ? 1.0 : 0.0;
}

void main() {
  ivec2 p = ivec2(gl_FragCoord.xy);
  int eye = gl_ViewIndex;
  if (SIDE_BY_SIDE) {
    int width = int(frame.viewport.x);
    eye = min(p.x / width, 1);
    p.x -= eye * width;
  }
  vec3 hdr = texelFetch(hdrTexture, ivec3(p, eye), 0).rgb;
  vec3 color = pcTonemap(hdr, frame.exposure);
  float text = overlayText(p);
  if (text >= 0.0) color = mix(color * 0.35, vec3(1.0), text);
  outColor = vec4(color, 1.0);
}
