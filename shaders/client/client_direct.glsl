// Direct light at a surface point: punctual lights and emitter stand-ins with their shadow maps
// (3x3 PCF from four gathers). Evaluated in the compute pass that also samples the field, not in
// a fragment shader: the raster pass only writes visibility ids, which keeps the raster work
// small where graphics units are few (an H100: docs/BENCHMARKS.md), and surfaces are shaded
// once per distinct triangle of a pixel.
// Needs client_common.glsl first.
layout(set = 0, binding = PC_CLIENT_BIND_LIGHTS, std430) readonly buffer LightBlock { GpuLight lights[]; };
layout(set = 0, binding = PC_CLIENT_BIND_SHADOW_MATRICES, std430) readonly buffer ShadowBlock {
  mat4 shadowMatrices[];
};
layout(set = 0, binding = PC_CLIENT_BIND_SHADOW_MAPS) uniform sampler2DArrayShadow shadowMaps[3];

// Cube face of direction v, in the order the client renders them: +x, -x, +y, -y, +z, -z.
int cubeFace(vec3 v) {
  vec3 a = abs(v);
  if (a.x >= a.y && a.x >= a.z) return v.x >= 0.0 ? 0 : 1;
  if (a.y >= a.z) return v.y >= 0.0 ? 2 : 3;
  return v.z >= 0.0 ? 4 : 5;
}

// Share of the light that reaches P, from the light's shadow map with 3x3 percentage-closer
// filtering: the mean of nine bilinear 2x2 comparisons one texel apart. Those nine taps cover
// a 4x4 block of texels with per-axis weights (1 - f, 1, 1, f) (f: the bilinear fraction),
// so four gathered comparisons of that block, weighted here, give the same filter with four
// fetches instead of nine. The receiver moves along its normal by a texel's footprint so
// surfaces do not shadow themselves.
float shadowVisibility(GpuLight l, vec3 P, vec3 N, float dist) {
  if (l.shadowLayer < 0) return 1.0;
  bool perspective = l.type != PC_LIGHT_DIRECTIONAL;
  vec3 offsetP = P + N * (perspective ? l.normalOffset * dist : l.normalOffset);
  int matrixIndex = l.shadowMatrix;
  int layer = l.shadowLayer;
  if (l.type == PC_LIGHT_POINT || l.type == PC_LIGHT_AREA) {
    int face = cubeFace(offsetP - l.position);
    matrixIndex += face;
    layer += face;
  }
  vec4 clip = shadowMatrices[matrixIndex] * vec4(offsetP - l.position, 1.0);  // from the light
  if (clip.w <= 0.0) return 1.0;
  vec3 ndc = clip.xyz / clip.w;
  vec2 uv = ndc.xy * 0.5 + 0.5;
  if (any(lessThan(uv, vec2(0.0))) || any(greaterThan(uv, vec2(1.0))) || ndc.z >= 1.0) return 1.0;
  float ref = ndc.z - l.depthBias;
  vec3 coord = vec3(uv, float(layer));
  // Gather components: x (low u, high v), y (high u, high v), z (high u, low v), w (low, low).
  vec4 a = textureGatherOffset(shadowMaps[l.shadowArray], coord, ref, ivec2(-1, -1));
  vec4 b = textureGatherOffset(shadowMaps[l.shadowArray], coord, ref, ivec2(1, -1));
  vec4 c = textureGatherOffset(shadowMaps[l.shadowArray], coord, ref, ivec2(-1, 1));
  vec4 d = textureGatherOffset(shadowMaps[l.shadowArray], coord, ref, ivec2(1, 1));
  vec4 all4 = a + b + c + d;
  float total = all4.x + all4.y + all4.z + all4.w;
  if (total == 0.0 || total == 16.0) return total / 16.0;  // fully shadowed or fully lit
  vec2 f = fract(uv / l.shadowTexel - 0.5);
  vec2 lo = 1.0 - f;  // weight of the lowest texel row/column; the middle two weigh 1
  float sum = dot(a, vec4(lo.x, 1.0, 1.0, lo.x) * vec4(1.0, 1.0, lo.y, lo.y)) +
              dot(b, vec4(1.0, f.x, f.x, 1.0) * vec4(1.0, 1.0, lo.y, lo.y)) +
              dot(c, vec4(lo.x, 1.0, 1.0, lo.x) * vec4(f.y, f.y, 1.0, 1.0)) +
              dot(d, vec4(1.0, f.x, f.x, 1.0) * vec4(f.y, f.y, 1.0, 1.0));
  return sum / 9.0;
}

// Every light at P, each shadowed by its map; the light itself is the shared light model
// (shaders/interop/light_model.h), as the tracers evaluate it. N: the shading normal (the
// light's cosine); Nbias: the vertex normal, along which the receiver moves off its surface
// for the shadow lookup (a normal-mapped normal would move it off the real surface).
vec3 directIrradiance(vec3 P, vec3 N, vec3 Nbias) {
  vec3 E = vec3(0.0);
  for (int i = 0; i < frame.lightCount; ++i) {
    GpuLight l = lights[i];
    vec3 wi;
    float d;
    float scale = pcLightScale(l, P, N, wi, d);
    if (!(scale > 0.0)) continue;  // behind P, outside its cone or range
    // Two calls, so that the sun's lookup is compiled apart from the perspective maps' (it
    // needs neither the distance nor a cube face): 2% of the pass on an H200.
    if (l.type == PC_LIGHT_DIRECTIONAL) {
      E += l.power * (scale * shadowVisibility(l, P, Nbias, 0.0));
    } else {
      E += l.power * (scale * shadowVisibility(l, P, Nbias, d));
    }
  }
  return E;
}
