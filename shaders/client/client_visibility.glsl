// The visibility buffer's samples as the passes after the main pass read them (from the raster
// image or the compute rasterizer's buffer), and the linear frame they write. Needs
// client_common.glsl first, and SAMPLES and VIS_BUFFER declared.
#ifndef PC_CLIENT_VISIBILITY_GLSL
#define PC_CLIENT_VISIBILITY_GLSL

layout(set = 0, binding = PC_CLIENT_BIND_G_VISIBILITY) uniform usampler2DMSArray gVisibility;
// Per sample: depth bits in the high word, the id in the low word (client_raster.glsl).
layout(set = 0, binding = PC_CLIENT_BIND_VIS_SAMPLES, std430) readonly buffer VisBlock { uvec2 visSamples[]; };
layout(set = 0, binding = PC_CLIENT_BIND_HDR_IMAGE, rgba32f) uniform writeonly image2DArray hdrImage;

// The visibility id of sample `s` of pixel id.xy in view id.z (0: the sky).
uint visibilityAt(ivec3 id, int s) {
  if (VIS_BUFFER) {
    ivec2 size = ivec2(frame.viewport);
    uint pixel = (uint(id.z) * uint(size.y) + uint(id.y)) * uint(size.x) + uint(id.x);
    return visSamples[pixel * uint(SAMPLES) + uint(s)].x;
  }
  return texelFetch(gVisibility, id, s).r;
}

#endif
