// Tangent-space normal mapping (glTF 2.0 normalTexture), shared by the CPU renders
// (cpu/embree_scene.cpp: the reference path tracer and the probe-lit render) and the client's
// lighting pass (shaders/client/client_surface.glsl), so that both perturb a surface's
// shading normal alike.
#ifndef PC_NORMAL_MAP_H
#define PC_NORMAL_MAP_H

#include "pc_interop.h"

PC_BEGIN

// The tangent-space normal a texel of the map holds (linear RGB in [0, 1]), its x and y
// stretched by the material's scale: (rgb x 2 - 1) x (scale, scale, 1), not yet unit length.
PC_FN vec3 pcNormalMapDirection(vec3 texel, float scale) {
  return (texel * 2.0f - vec3(1.0f)) * vec3(scale, scale, 1.0f);
}

// The shading normal for tangent-space direction `m` at a surface with unit normal N and
// tangent T (any length; made perpendicular to N here) of handedness `w` (+1 or -1, already
// multiplied by the sign of the instance transform's determinant, which mirrors the frame):
// the bitangent is w x cross(N, T). N itself where the frame or the result is degenerate.
PC_FN vec3 pcPerturbNormal(vec3 N, vec3 T, float w, vec3 m) {
  vec3 t = T - N * dot(N, T);
  float tLength = length(t);
  if (!(tLength > 1e-12f)) return N;
  t = t / tLength;
  vec3 b = cross(N, t) * (w < 0.0f ? -1.0f : 1.0f);
  vec3 n = t * m.x + b * m.y + N * m.z;
  float nLength = length(n);
  return nLength > 0.0f ? n / nLength : N;
}

PC_END

#endif
