// Whether a cut-out's hit is covered (Material::isCutOut, pc::coveredAt): baseAlpha x one
// channel of the alpha texture, bilinear level 0, against the cutoff, with the CPU's test, so
// that rays pass the open texels as Embree's filters let them. Shared by the ray-tracing
// backend's any-hit shader (probe_cutout.rahit) and the SDF backend's traversal
// (sdf_trace.glsl). The bilinear lookup is done here from four texel fetches with float
// weights, as Texture::sample does it: a sampler's filter weights keep only
// subTexelPrecisionBits of fraction (at least 4, by the Vulkan spec), which moves the cut-off's
// edge against the CPU's. The includer declares the vertices, indices, meshes, instances,
// materials and textures bindings (interop/gpu_trace.h) and enables GL_EXT_nonuniform_qualifier.
#ifndef PC_CUTOUT_COVERAGE_GLSL
#define PC_CUTOUT_COVERAGE_GLSL

// The texels whole texel coordinates f and f + 1 read on an axis of n texels with wrap mode
// `wrap` (common/scene_model.cpp texelPair; GLSL's mod is floored, so no negative fix-up).
ivec2 texelPair(float f, int n, int wrap) {
  if (wrap == 1) return ivec2(clamp(f, 0.0f, float(n - 1)), clamp(f + 1.0f, 0.0f, float(n - 1)));
  if (wrap == 2) {
    int k0 = int(mod(f, 2.0f * float(n))), k1 = int(mod(f + 1.0f, 2.0f * float(n)));
    return ivec2(k0 < n ? k0 : 2 * n - 1 - k0, k1 < n ? k1 : 2 * n - 1 - k1);
  }
  int i = int(mod(f, float(n)));
  return ivec2(i, (i + 1) % n);
}

// Texture t bilinear at level 0 (Texture::sample).
vec4 bilinear(int t, vec2 uv, int wrapU, int wrapV) {
  ivec2 size = textureSize(textures[nonuniformEXT(t)], 0);
  if (any(isnan(uv)) || any(isinf(uv))) uv = vec2(0.0f);
  float x = uv.x * float(size.x) - 0.5f, y = uv.y * float(size.y) - 0.5f;
  float fx0 = floor(x), fy0 = floor(y);
  float tx = x - fx0, ty = y - fy0;
  ivec2 xs = texelPair(fx0, size.x, wrapU), ys = texelPair(fy0, size.y, wrapV);
  vec4 top = mix(texelFetch(textures[nonuniformEXT(t)], ivec2(xs.x, ys.x), 0),
                 texelFetch(textures[nonuniformEXT(t)], ivec2(xs.y, ys.x), 0), tx);
  vec4 bottom = mix(texelFetch(textures[nonuniformEXT(t)], ivec2(xs.x, ys.y), 0),
                    texelFetch(textures[nonuniformEXT(t)], ivec2(xs.y, ys.y), 0), tx);
  return mix(top, bottom, ty);
}

// Whether triangle `primitive` of shading record `record` is covered at barycentrics `bary`
// (of its second and third corners); always where its material is no cut-out.
bool pcCutOutCovered(int record, int primitive, vec2 bary) {
  GpuInstance inst = instances[record];
  GpuMesh mesh = meshes[inst.mesh];
  if (mesh.material < 0) return true;
  GpuMaterial m = materials[mesh.material];
  if (m.alphaCutoff <= 0.0f) return true;
  float alpha = m.baseAlpha;
  if (m.alphaTexture >= 0) {
    uint base = uint(mesh.firstIndex) + 3u * uint(primitive);
    GpuVertex v0 = vertices[mesh.firstVertex + int(indices[base])];
    GpuVertex v1 = vertices[mesh.firstVertex + int(indices[base + 1u])];
    GpuVertex v2 = vertices[mesh.firstVertex + int(indices[base + 2u])];
    float u = bary.x, v = bary.y, w = 1.0f - u - v;
    vec2 uv = w * vec2(v0.u, v0.v) + u * vec2(v1.u, v1.v) + v * vec2(v2.u, v2.v);
    alpha *= bilinear(m.alphaTexture, uv, m.alphaWrapU, m.alphaWrapV)[m.alphaChannel];
  }
  return alpha >= m.alphaCutoff;
}

#endif
