// Where a pixel's samples lie: Vulkan's standard sample locations, which the fixed-function
// rasterizer uses and the compute rasterizer copies (client_raster.glsl); the lighting pass
// finds an edge sample's own point on its triangle with them (client_surface.glsl). Needs
// client_common.glsl first, and SAMPLES declared.
#ifndef PC_CLIENT_SAMPLES_GLSL
#define PC_CLIENT_SAMPLES_GLSL

// Vulkan's standard sample locations, in 1/PC_RASTER_SUBPIXEL of a pixel from its corner.
ivec2 sampleOffset(int s) {
  if (SAMPLES == 2) return s == 0 ? ivec2(192, 192) : ivec2(64, 64);
  if (SAMPLES == 4) {
    const ivec2 p4[4] = ivec2[](ivec2(96, 32), ivec2(224, 96), ivec2(32, 160), ivec2(160, 224));
    return p4[s];
  }
  if (SAMPLES == 8) {
    const ivec2 p8[8] = ivec2[](ivec2(144, 80), ivec2(112, 176), ivec2(208, 144), ivec2(80, 48),
                                ivec2(48, 208), ivec2(16, 112), ivec2(176, 240), ivec2(240, 16));
    return p8[s];
  }
  return ivec2(128, 128);
}

// The same, in pixels from the pixel's corner.
vec2 samplePosition(int s) { return vec2(sampleOffset(s)) / float(PC_RASTER_SUBPIXEL); }

#endif
