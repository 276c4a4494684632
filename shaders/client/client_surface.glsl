// The surface a visibility-buffer sample names, rebuilt where the pixel-centre ray meets the
// triangle's plane: the point the rasterizer would have interpolated attributes at (outside
// the triangle on edge samples, as non-centroid interpolation does), so position, normal and
// texture coordinates equal what a G-buffer would have stored, without its bytes per sample.
// Conventions follow the CPU renders (cpu/lighting.cpp, cpu/embree_scene.cpp): two-sided
// diffuse surfaces whose shading normal is turned to the viewer's side, one-sided emitters
// whose front is the mesh's counter-clockwise side. Needs client_common.glsl first, and
// TEXTURE_COUNT declared.
#extension GL_EXT_nonuniform_qualifier : require
#include "client_geometry.glsl"

layout(set = 0, binding = PC_BIND_TEXTURES) uniform sampler2D textures[TEXTURE_COUNT];

struct Surface {
  vec3 position;
  vec3 normal;  // shading normal, on the viewer's side
  vec3 albedo;
  vec3 emission;
  float distance;  // along the ray from the eye
};

vec3 textureRgb(int index, vec2 uv) {
  if (index < 0 || index >= TEXTURE_COUNT) return vec3(1.0);
  // The scene's textures have one level (gpu_scene.h), so level 0 is what the fragment
  // shader's implicit-derivative lookup read.
  return textureLod(textures[nonuniformEXT(index)], uv, 0.0).rgb;
}

// `id`: a non-zero visibility value; `eye`, `ray` (unit): the pixel-centre ray of its view.
Surface surfaceOf(uint id, vec3 eye, vec3 ray) {
  uint triangle = id - 1u;
  DrawData d = draws[drawOfTriangle(triangle)];
  uint i0, i1, i2;
  triangleVertices(d, triangle, i0, i1, i2);
  VertexRecord v0 = vertexAt(i0), v1 = vertexAt(i1), v2 = vertexAt(i2);
  vec3 p0 = (d.model * vec4(v0.position, 1.0)).xyz;
  vec3 e1 = (d.model * vec4(v1.position, 1.0)).xyz - p0;
  vec3 e2 = (d.model * vec4(v2.position, 1.0)).xyz - p0;

  // Ray against the triangle's plane (Moller-Trumbore without the inside test): barycentrics
  // (b1, b2) and the distance. A triangle seen exactly edge-on covers no sample centre of
  // its own; the guard keeps the division finite for the rare sample that still names one.
  vec3 pv = cross(ray, e2);
  float det = dot(e1, pv);
  if (abs(det) < 1e-30) det = det < 0.0 ? -1e-30 : 1e-30;
  float inv = 1.0 / det;
  vec3 tv = eye - p0;
  vec3 qv = cross(tv, e1);
  float b1 = dot(tv, pv) * inv;
  float b2 = dot(ray, qv) * inv;
  float b0 = 1.0 - b1 - b2;

  Surface s;
  s.distance = max(dot(e2, qv) * inv, 0.0);
  s.position = eye + ray * s.distance;
  vec3 cross12 = cross(e1, e2);
  float area = length(cross12);
  vec3 toEye = -ray;
  vec3 ng = area > 0.0 ? cross12 / area : toEye;
  bool front = float(d.geometry.w) * dot(ng, toEye) > 0.0;
  if (dot(ng, toEye) < 0.0) ng = -ng;
  mat3 normalMatrix = mat3(d.normalMatrix);
  vec3 ns = normalMatrix * (b0 * v0.normal + b1 * v1.normal + b2 * v2.normal);
  float len = length(ns);
  ns = len > 0.0 ? ns / len : ng;
  s.normal = dot(ns, ng) < 0.0 ? -ns : ns;

  vec2 uv = b0 * v0.uv + b1 * v1.uv + b2 * v2.uv;
  s.albedo = d.baseColor.rgb * textureRgb(d.textures.x, uv);
  s.emission = front ? d.emissive.rgb * textureRgb(d.textures.y, uv) : vec3(0.0);
  return s;
}
