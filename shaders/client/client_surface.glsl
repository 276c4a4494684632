// The surface a visibility-buffer sample names, rebuilt where the pixel-centre ray meets the
// triangle's plane: the point the rasterizer would have interpolated attributes at, so normal
// and texture coordinates equal what a G-buffer would have stored, without its bytes per
// sample. In a pixel that holds more than one triangle, the pixel centre may not show this
// one: its ray meets the triangle's plane beyond the triangle (as non-centroid interpolation
// puts it), or the triangle itself behind another one. Past a junction that point lies behind
// the other wall, where the sun or a probe on the far side reaches it: a bright line along
// every junction. The position that is lit is therefore where the ray of a sample that shows
// the triangle meets it (as the CPU renders' primary rays find it), clamped onto the triangle
// against rounding.
// Conventions follow the CPU renders (cpu/lighting.cpp, cpu/embree_scene.cpp): two-sided
// diffuse surfaces whose shading normal is turned to the viewer's side, one-sided emitters
// whose front is the mesh's counter-clockwise side. Needs client_common.glsl first, and
// TEXTURE_COUNT declared.
#ifndef PC_CLIENT_SURFACE_GLSL
#define PC_CLIENT_SURFACE_GLSL

#extension GL_EXT_nonuniform_qualifier : require
#include "client_geometry.glsl"
#include "../interop/normal_map.h"

layout(set = 0, binding = PC_CLIENT_BIND_TEXTURES) uniform sampler2D textures[TEXTURE_COUNT];

struct Surface {
  vec3 position;
  vec3 normal;        // shading normal (normal-mapped), on the viewer's side
  vec3 vertexNormal;  // the interpolated vertex normal alone, on the viewer's side
  vec3 albedo;
  vec3 emission;
  float distance;  // along the ray from the eye
  float metallic;  // brdf.h's terms (DrawData: the material's factors)
  float roughness;
};

// `dx`, `dy`: how uv changes to the next pixel across and down (the footprint a fragment
// shader's derivatives would give), which picks the mip level and anisotropy.
vec3 textureRgb(int index, vec2 uv, vec2 dx, vec2 dy) {
  if (index < 0 || index >= TEXTURE_COUNT) return vec3(1.0);
  return textureGrad(textures[nonuniformEXT(index)], uv, dx, dy).rgb;
}

// Whether draw `d` has a normal map its mesh's tangents can apply (scene_pack.cpp).
bool drawHasNormalMap(DrawData d) {
  return d.normalTexture >= 0 && d.normalTexture < TEXTURE_COUNT;
}

// Ray against the plane of the triangle p0 + b1 e1 + b2 e2 (Moller-Trumbore without the inside
// test; tv = eye - p0, qv = cross(tv, e1)): (b1, b2, distance along `ray`). A triangle seen
// exactly edge-on covers no sample centre of its own; the guard keeps the division finite
// for the rare sample that still names one (and gives a neighbour's ray along the plane a
// huge footprint, as a surface seen edge-on has).
vec3 planeHit(vec3 ray, vec3 e1, vec3 e2, vec3 tv, vec3 qv) {
  vec3 pv = cross(ray, e2);
  float det = dot(e1, pv);
  if (abs(det) < 1e-30) det = det < 0.0 ? -1e-30 : 1e-30;
  return vec3(dot(tv, pv), dot(ray, qv), dot(e2, qv)) / det;
}

// Clamps a uv difference to a finite footprint (1e4 texture repeats: the coarsest level).
vec2 footprint(vec2 d) { return clamp(d, vec2(-1e4), vec2(1e4)); }

// Triangle id `triangle` of draw `d`: its corners' records, and its first corner and edges
// in world space.
struct WorldTriangle {
  VertexRecord v0, v1, v2;
  vec3 p0, e1, e2;
};
WorldTriangle worldTriangle(DrawData d, uint triangle) {
  uint i0, i1, i2;
  triangleVertices(d, triangle, i0, i1, i2);
  WorldTriangle w;
  w.v0 = vertexAt(i0);
  w.v1 = vertexAt(i1);
  w.v2 = vertexAt(i2);
  w.p0 = (d.model * vec4(w.v0.position, 1.0)).xyz;
  w.e1 = (d.model * vec4(w.v1.position, 1.0)).xyz - w.p0;
  w.e2 = (d.model * vec4(w.v2.position, 1.0)).xyz - w.p0;
  return w;
}

// `id`: a non-zero visibility value; `eye`, `ray` (unit): the pixel-centre ray of its view;
// `rayDx`, `rayDy`: the next pixel's centre rays across and down (any length); `sampleRay`
// (unit): the ray through a sample that shows the triangle (the centre ray where all do).
Surface surfaceOf(uint id, vec3 eye, vec3 ray, vec3 rayDx, vec3 rayDy, vec3 sampleRay) {
  uint triangle = id - 1u;
  DrawData d = draws[drawOfTriangle(triangle)];
  WorldTriangle w = worldTriangle(d, triangle);
  VertexRecord v0 = w.v0, v1 = w.v1, v2 = w.v2;
  vec3 p0 = w.p0, e1 = w.e1, e2 = w.e2;

  vec3 tv = eye - p0;
  vec3 qv = cross(tv, e1);
  vec3 hit = planeHit(ray, e1, e2, tv, qv);
  float b1 = hit.x, b2 = hit.y;
  float b0 = 1.0 - b1 - b2;

  Surface s;
  s.distance = max(hit.z, 0.0);
  s.position = eye + ray * s.distance;
  if (sampleRay != ray) {
    // The sample's ray, then the barycentrics clamped, as an offset from the ray's point (no
    // large world coordinates cancel).
    vec3 sampleHit = planeHit(sampleRay, e1, e2, tv, qv);
    s.position = eye + sampleRay * max(sampleHit.z, 0.0);
    vec3 b = vec3(1.0 - sampleHit.x - sampleHit.y, sampleHit.x, sampleHit.y);
    vec3 clamped = max(b, vec3(0.0));
    clamped /= clamped.x + clamped.y + clamped.z;
    s.position += (clamped.y - b.y) * e1 + (clamped.z - b.z) * e2;
  }
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
  float side = dot(ns, ng) < 0.0 ? -1.0 : 1.0;
  s.vertexNormal = side * ns;
  s.normal = s.vertexNormal;

  vec2 uv = b0 * v0.uv + b1 * v1.uv + b2 * v2.uv;
  bool normalMapped = drawHasNormalMap(d);
  // The neighbouring pixels' rays on the same plane: uv there minus uv here (only where a
  // texture is read; untextured surfaces skip the two extra plane intersections).
  vec2 dx = vec2(0.0), dy = vec2(0.0);
  if (d.textures.x >= 0 || d.textures.y >= 0 || d.metallicRoughnessTexture >= 0 || normalMapped) {
    vec2 du1 = v1.uv - v0.uv, du2 = v2.uv - v0.uv;
    vec2 bx = planeHit(rayDx, e1, e2, tv, qv).xy - hit.xy;
    vec2 by = planeHit(rayDy, e1, e2, tv, qv).xy - hit.xy;
    dx = footprint(bx.x * du1 + bx.y * du2);
    dy = footprint(by.x * du1 + by.y * du2);
  }
  s.albedo = d.baseColor.rgb * textureRgb(d.textures.x, uv, dx, dy);
  s.emission = front ? d.emissive.rgb * textureRgb(d.textures.y, uv, dx, dy) : vec3(0.0);
  s.metallic = d.metallic;
  s.roughness = d.roughness;
  if (d.metallicRoughnessTexture >= 0) {  // linear data: B metallic, G roughness (glTF)
    vec3 mr = textureRgb(d.metallicRoughnessTexture, uv, dx, dy);
    s.metallic *= mr.b;
    s.roughness *= mr.g;
  }
  // As the CPU renders do (cpu/embree_scene.cpp): the map perturbs the unflipped normal in the
  // mesh's frame, tangents following the model matrix (they lie in the surface) and their
  // handedness the sign of its determinant; the result is turned as the vertex normal was.
  if (normalMapped) {
    vec4 t = b0 * v0.tangent + b1 * v1.tangent + b2 * v2.tangent;
    vec3 m = pcNormalMapDirection(textureRgb(d.normalTexture, uv, dx, dy), d.normalScale);
    s.normal = side * pcPerturbNormal(ns, mat3(d.model) * t.xyz, t.w * float(d.geometry.w), m);
  }
  return s;
}

// ---- cut-outs (Material::isCutOut, pc::coveredAt) ----
// DrawData carries the base alpha in baseColor.w, the cutoff in emissive.w (0: opaque) and the
// alpha texture in textures.w (4 x index + channel; -1: none). The test reads level 0
// bilinearly, as the CPU's Texture::sample, so every renderer and tracer cuts the same holes.

bool drawIsCutOut(DrawData d) { return d.emissive.w > 0.0; }

bool coveredAtUv(DrawData d, vec2 uv) {
  float alpha = d.baseColor.w;
  int t = d.textures.w;
  if (t >= 0 && (t >> 2) < TEXTURE_COUNT)
    alpha *= textureLod(textures[nonuniformEXT(t >> 2)], uv, 0.0)[t & 3];
  return alpha >= d.emissive.w;
}

// Whether triangle id `triangle` of draw `d` exists where `ray` from `eye` meets its plane.
bool coveredOnRay(DrawData d, uint triangle, vec3 eye, vec3 ray) {
  WorldTriangle w = worldTriangle(d, triangle);
  vec3 tv = eye - w.p0;
  vec3 hit = planeHit(ray, w.e1, w.e2, tv, cross(tv, w.e1));
  return coveredAtUv(d, (1.0 - hit.x - hit.y) * w.v0.uv + hit.x * w.v1.uv + hit.y * w.v2.uv);
}

// The ray of view `view` through window position `pixel` (in pixels from the top left corner;
// pixel centres at + 0.5): from the view's eye to a point under the pixel, unnormalized. Made
// relative to the eye by the matrix itself, so no large coordinates cancel here.
vec3 rayUnderPixel(int view, vec2 pixel) {
  vec2 ndc = pixel / frame.viewport * 2.0 - 1.0;
  vec4 p = frame.views[view].invViewProjFromEye * vec4(ndc, 0.5, 1.0);
  return p.xyz / p.w;
}

#endif
