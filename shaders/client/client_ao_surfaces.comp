#version 460
// Before the lighting pass, when the ambient occlusion of the indirect light is on: the
// surface under every pixel centre (the triangle of sample 0, rebuilt on the pixel-centre ray
// as client_surface.glsl does), for the occlusion estimator (shaders/interop/screen_ao.h),
// which reads each pixel's neighbours. The CPU probe-lit render traces the same buffer.
#extension GL_GOOGLE_include_directive : require
#include "client_common.glsl"
#include "client_ao_buffer.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
layout(constant_id = 0) const int SAMPLES = 4;
layout(constant_id = 1) const int TEXTURE_COUNT = 1;
// true: the visibility ids come from the compute rasterizer's buffer, not the raster image.
layout(constant_id = 2) const bool VIS_BUFFER = false;
#include "client_surface.glsl"

layout(set = 0, binding = PC_CLIENT_BIND_G_VISIBILITY) uniform usampler2DMSArray gVisibility;
layout(set = 0, binding = PC_CLIENT_BIND_VIS_SAMPLES, std430) readonly buffer VisBlock { uvec2 visSamples[]; };

void main() {
  ivec3 id = ivec3(gl_GlobalInvocationID);
  ivec2 size = ivec2(frame.viewport);
  if (id.x >= size.x || id.y >= size.y) return;
  uint pixel = aoPixelIndex(id.z, id.xy);
  uint visibility;
  if (VIS_BUFFER) {
    visibility = visSamples[pixel * uint(SAMPLES)].x;
  } else {
    visibility = texelFetch(gVisibility, id, 0).r;
  }
  if (visibility == 0u) {
    aoSurfaces[2u * pixel] = vec4(0.0);
    aoSurfaces[2u * pixel + 1u] = vec4(0.0);
    return;
  }
  vec2 centre = vec2(id.xy) + 0.5;
  vec3 ray = normalize(rayUnderPixel(id.z, centre));
  Surface f = surfaceOf(visibility, frame.views[id.z].position.xyz, ray, ray, ray, ray);
  // From the ray and its length, not the position minus the eye: nothing cancels far from
  // the world's origin (the CPU stores the same).
  aoSurfaces[2u * pixel] = vec4(ray * f.distance, 1.0);
  // The surface's own shape, not its normal map (the CPU's AO reads the same).
  aoSurfaces[2u * pixel + 1u] = vec4(f.vertexNormal, 0.0);
}
