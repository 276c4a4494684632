// The buffer of surfaces under the pixel centres (PC_CLIENT_BIND_AO_SURFACES), written by
// client_ao_surfaces.comp and read by the occlusion estimator in the lighting pass. Needs
// client_common.glsl first.
#ifndef PC_CLIENT_AO_BUFFER_GLSL
#define PC_CLIENT_AO_BUFFER_GLSL

// Per pixel and view: (position - eye, 1; 0 where the sky shows), (shading normal, 0).
layout(set = 0, binding = PC_CLIENT_BIND_AO_SURFACES, std430) buffer AoBlock { vec4 aoSurfaces[]; };

uint aoPixelIndex(int view, ivec2 p) {
  ivec2 size = ivec2(frame.viewport);
  return (uint(view) * uint(size.y) + uint(p.y)) * uint(size.x) + uint(p.x);
}

#endif
