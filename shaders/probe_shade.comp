#version 460
// The shade pass of the wavefront (interop/gpu_trace.h): shades each probe ray's stored hit as
// the Embree backend does (server/embree_tracer.cpp, cpu/embree_scene.cpp, cpu/lighting.cpp):
// direct light from punctual lights and light-sampled emissive triangles, emission when not
// light-sampled, indirect light from the previous field through the shared sampling code, all
// reflected toward the probe by the material (interop/probe_hit_shading.h).
// Direct light needs shadow rays: for each slot with a real shadow ray this pass writes what
// the light adds to the ray's radiance if visible (the BRDF toward the probe x irradiance;
// albedo / pi x irradiance on a Lambert surface) in the slot's
// fixed place, and appends the ray to its slot's compacted shadow list, a subgroup at a time
// (interop/gpu_trace.h); probe_shadow.rgen traces the list and sets the visible slots' bits
// in the ray's mask, cleared here, and the blend adds them. Backface hits report a negative
// distance and no light, but a cut-out's back, which is shaded as a front face
// (pcBackfaceIsSurface). One invocation per ray, in launch order.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_nonuniform_qualifier : require
#extension GL_KHR_shader_subgroup_ballot : require
#include "field_sampling.glsl"
#include "interop/probe_hit_shading.h"
#include "interop/probe_update.h"
#include "interop/shadow_roulette.h"

layout(local_size_x = PC_SHADE_THREADS) in;

// Whether the tracer plays shadow-ray roulette (TracerOptions::shadowRouletteShare > 0): the
// pipeline is specialized on it, so that without it the pass does none of its work (on an
// H200, pandora: 0.465 ms with the roulette's code present but off, 0.458 without it).
layout(constant_id = 1) const bool kRoulette = false;

layout(std430, set = 0, binding = PC_BIND_PARAMS) readonly buffer Params { UpdateParams params; };
layout(std430, set = 0, binding = PC_BIND_RAY_DIRS) readonly buffer RayDirs { vec4 rayDirs[]; };
layout(std430, set = 0, binding = PC_BIND_HITS) readonly buffer Hits { GpuHit hits[]; };
layout(std430, set = 0, binding = PC_BIND_RAYS) writeonly buffer Rays { vec4 rays[]; };
layout(std430, set = 0, binding = PC_BIND_SHADOW_MASK) writeonly buffer ShadowMask { uint shadowMask[]; };
layout(std430, set = 0, binding = PC_BIND_SHADOW_RAYS) writeonly buffer ShadowRays { GpuShadowRay shadowRays[]; };
layout(std430, set = 0, binding = PC_BIND_SHADOW_LIGHT) writeonly buffer ShadowLight { GpuShadowLight shadowLight[]; };
layout(std430, set = 0, binding = PC_BIND_VERTICES) readonly buffer Vertices { GpuVertex vertices[]; };
layout(std430, set = 0, binding = PC_BIND_INDICES) readonly buffer Indices { uint indices[]; };
layout(std430, set = 0, binding = PC_BIND_MESHES) readonly buffer Meshes { GpuMesh meshes[]; };
layout(std430, set = 0, binding = PC_BIND_INSTANCES) readonly buffer Instances { GpuInstance instances[]; };
layout(std430, set = 0, binding = PC_BIND_MATERIALS) readonly buffer Materials { GpuMaterial materials[]; };
layout(std430, set = 0, binding = PC_BIND_LIGHTS) readonly buffer Lights { GpuLight lights[]; };
layout(std430, set = 0, binding = PC_BIND_EMISSIVE) readonly buffer Emissive { GpuEmissiveTriangle emissive[]; };
layout(std430, set = 0, binding = PC_BIND_COUNTERS) buffer Counters { uint counters[]; };
// push.slotBase: the first shadow slot of this round (pcShadowRounds). Every round requests
// its own slots' shadow rays; only the first writes the rays' records.
layout(push_constant) uniform Push { TracePush push; };
layout(set = 0, binding = PC_BIND_TEXTURES) uniform sampler2D textures[];

uint rngState;
float rnd() {
  rngState = pcHash(rngState);
  return pcHashToFloat(rngState);
}

// This ray's launch index, the stride between its slots' records, and the hit's reflection
// toward the probe (what a light's irradiance is scaled by on its way there).
uint launchIndex;
// Request x rays per probe + ray, the request index counted over the whole update (not the
// slice): the ray's random streams are keyed by it, as on the CPU.
uint rayIndex;
uint slotStride;
vec3 hitNormal, hitView, hitBaseColor;
float hitMetallic, hitRoughness;
// The shadow ray of the slot last requested, until appendRequest lists it (tmax 0: none).
GpuShadowRay pending;

// Whether slot `slot` is in this round; its place in the round indexes its list and lights.
bool inRound(int slot) { return slot >= push.slotBase && slot < push.slotBase + params.roundSlots; }

// Slot `slot`'s request: a shadow ray that adds the hit's reflection of `irradiance`, arriving
// along `dir`, to the ray's radiance when nothing blocks it. tmax 0 leaves the slot empty
// (nothing is written: its mask bit stays clear). appendRequest then lists the ray. Slots of
// other rounds are left alone (their requests are computed all the same, so that the random
// streams stay in step).
void request(int slot, vec3 origin, vec3 dir, float tmax, vec3 irradiance) {
  if (!inRound(slot)) return;
  uint light = uint(slot - push.slotBase) * slotStride + launchIndex;
  if (tmax > 0.0f) {
    vec3 weight =
        pcProbeHitLightWeight(hitNormal, hitView, dir, hitBaseColor, hitMetallic, hitRoughness);
    shadowLight[light] = GpuShadowLight(weight * irradiance, 0.0f);
  }
  pending = GpuShadowRay(origin, tmax, dir, light);
}
void noRequest(int slot) { request(slot, vec3(0.0f), vec3(0.0f), 0.0f, vec3(0.0f)); }

// Appends the pending shadow rays of the subgroup's active invocations to slot `slot`'s shadow
// list: one atomic per subgroup, the rays in lane order (launch order). Called where the
// invocations that made requests for the slot have reconverged.
void appendRequest(int slot) {
  if (!inRound(slot)) return;  // uniform: the slot is the same for the whole subgroup
  bool real = pending.tmax > 0.0f;
  uvec4 ballot = subgroupBallot(real);
  uint count = subgroupBallotBitCount(ballot);
  if (count == 0u) return;
  uint base = 0u;
  if (subgroupElect()) base = atomicAdd(counters[slot * PC_COUNTER_WORDS], count);
  base = subgroupBroadcastFirst(base) + uint(slot - push.slotBase) * slotStride;
  if (real) shadowRays[base + subgroupBallotExclusiveBitCount(ballot)] = pending;
  pending.tmax = 0.0f;
}

vec3 skyRadiance(vec3 dir) {
  float len = length(dir);
  float y = len > 0.0f ? clamp(dir.y / len, -1.0f, 1.0f) : 0.0f;
  return y >= 0.0f ? mix(params.skyHorizon, params.skyZenith, y) : mix(params.skyHorizon, params.skyGround, -y);
}

// A light's unshadowed irradiance at P and the shadow ray that decides it (`far` 0: the light
// does not reach P): the shared light model, as the Embree tracer evaluates it.
vec3 punctualSample(GpuLight light, vec3 P, vec3 N, out vec3 wi, out float far) {
  float distance;
  vec3 irradiance = pcLightIrradiance(light, P, N, wi, distance);
  far = distance * PC_SHADOW_FAR_SCALE;
  return irradiance;
}

// First triangle whose cumulative probability exceeds u (std::upper_bound on the CDF).
int pickEmissive(float u) {
  int lo = 0, hi = params.emissiveCount;
  while (lo < hi) {
    int mid = (lo + hi) / 2;
    if (emissive[mid].cdf > u) hi = mid;
    else lo = mid + 1;
  }
  return min(lo, params.emissiveCount - 1);
}

// Emissive sample `s`'s request (slot lightCount + s). Samples draw from the ray's stream in
// order: u, then the point on the triangle (none when the pick has no probability).
void emissiveRequest(int s, int samples, vec3 P, vec3 shadowOrigin, vec3 N) {
  int slot = params.lightCount + s;
  float u = (float(s) + rnd()) / float(samples);
  int k = pickEmissive(u);
  float pTriangle = emissive[k].cdf - (k > 0 ? emissive[k - 1].cdf : 0.0f);
  if (pTriangle <= 0.0f) {
    noRequest(slot);
    return;
  }
  GpuEmissiveTriangle tri = emissive[k];
  float u1 = rnd();
  float u2 = rnd();
  vec3 Q = pcTrianglePoint(tri.p0, tri.e1, tri.e2, u1, u2);
  float geometry = pcEmitterGeometry(Q, tri.normal, P, N);
  if (!(geometry > 0.0f)) {
    noRequest(slot);
    return;
  }
  // Aimed at a point lifted off the emitter, so that the emitter never shadows its own sample:
  // the ray runs from its origin straight to that point and stops just short of it, as on the
  // CPU (cpu/lighting.cpp).
  vec3 target = pcOffsetRayOrigin(Q, tri.normal);
  vec3 toTarget = target - shadowOrigin;
  float targetDistance = length(toTarget);
  if (!(targetDistance > 0.0f)) {
    noRequest(slot);
    return;
  }
  float pdfArea = pTriangle / tri.area;
  request(slot, shadowOrigin, toTarget / targetDistance, targetDistance * PC_SHADOW_FAR_SCALE,
          tri.radiance * (geometry / pdfArea) / float(samples));
}

// Every slot's request for a lit surface point: the lights evaluated at P, the shadow rays from
// shadowOrigin (P off its surface, pcShadowOrigin), as cpu/lighting.cpp directIrradiance.
void directRequests(vec3 P, vec3 shadowOrigin, vec3 N) {
  // The punctual lights' unshadowed luminance, for the shadow-ray roulette.
  float total = 0.0f;
  vec3 wi;
  float far;
  if (kRoulette)
    for (int i = 0; i < params.lightCount; ++i) total += pcLuminance(punctualSample(lights[i], P, N, wi, far));
  uint key = kRoulette ? pcShadowRouletteKey(params.seed, rayIndex) : 0u;
  for (int i = 0; i < params.lightCount; ++i) {
    vec3 irradiance = punctualSample(lights[i], P, N, wi, far);
    float weight = !(far > 0.0f) ? 0.0f
                 : kRoulette ? pcShadowRouletteWeight(pcLuminance(irradiance), total, params.shadowRouletteShare, key, i)
                 : 1.0f;
    if (weight > 0.0f) {
      request(i, shadowOrigin, wi, far, weight == 1.0f ? irradiance : irradiance * weight);
    } else {
      noRequest(i);
    }
    appendRequest(i);
  }
  int samples = params.shadowSlots - params.lightCount;
  for (int s = 0; s < samples; ++s) {
    emissiveRequest(s, samples, P, shadowOrigin, N);
    appendRequest(params.lightCount + s);
  }
}

vec3 textureRgb(int t, vec2 uv) {
  if (t < 0) return vec3(1.0f);
  return textureLod(textures[nonuniformEXT(t)], uv, 0.0f).rgb;
}

// The split-sum table's (A, B) at (N.V, roughness), from the parameters' copy.
#define PC_SPLIT_SUM_PAIR(p) params.splitSum[p]
#include "split_sum_lookup.glsl"

// The ray's record (first round) and a clear visibility mask for the round's slots (the
// shadow pass sets the visible bits).
void finish(vec3 radiance, float distance) {
  if (push.slotBase == 0) rays[launchIndex] = vec4(radiance, distance);
  int words = pcShadowMaskWords(params.roundSlots);
  for (int w = 0; w < words; ++w) shadowMask[uint(w) * slotStride + launchIndex] = 0u;
}

// Rays, shading record and shadow requests of a hit (cpu/embree_scene.cpp surface()).
void shadeHit(GpuHit hit, vec3 dir) {
  GpuInstance inst = instances[hit.instance];
  GpuMesh mesh = meshes[inst.mesh];
  uint base = uint(mesh.firstIndex) + 3u * uint(hit.primitive);
  GpuVertex v0 = vertices[mesh.firstVertex + int(indices[base])];
  GpuVertex v1 = vertices[mesh.firstVertex + int(indices[base + 1u])];
  GpuVertex v2 = vertices[mesh.firstVertex + int(indices[base + 2u])];
  vec3 p0 = vec3(inst.objectToWorld * vec4(v0.position, 1.0f));
  vec3 p1 = vec3(inst.objectToWorld * vec4(v1.position, 1.0f));
  vec3 p2 = vec3(inst.objectToWorld * vec4(v2.position, 1.0f));
  float u = hit.barycentric.x, v = hit.barycentric.y, w = 1.0f - u - v;
  vec3 P = w * p0 + u * p1 + v * p2;

  // Front face: counter-clockwise in world space (mirroring transforms flip it back).
  vec3 ng = inst.side * cross(p1 - p0, p2 - p0);
  float ngLength = length(ng);
  ng = ngLength > 0.0f ? ng / ngLength : -dir;
  bool backface = dot(dir, ng) > 0.0f;
  if (backface) {
    // A cut-out's back is a surface, shaded with its normals toward the ray and no emission
    // (pcBackfaceIsSurface, cpu/embree_scene.cpp surface()); any other backface: no light.
    if (mesh.material < 0 || !pcBackfaceIsSurface(materials[mesh.material].alphaCutoff)) {
      finish(vec3(0.0f), -hit.t);
      return;
    }
    ng = -ng;
  }

  mat3 normalMatrix = mat3(inst.normalToWorld);
  vec3 n0 = normalMatrix * v0.normal, n1 = normalMatrix * v1.normal, n2 = normalMatrix * v2.normal;
  n0 = length(n0) > 0.0f ? normalize(n0) : vec3(0.0f);
  n1 = length(n1) > 0.0f ? normalize(n1) : vec3(0.0f);
  n2 = length(n2) > 0.0f ? normalize(n2) : vec3(0.0f);
  vec3 ns = w * n0 + u * n1 + v * n2;
  float nsLength = length(ns);
  ns = nsLength > 0.0f ? ns / nsLength : ng;
  vec3 N = dot(ns, ng) < 0.0f ? -ns : ns;

  vec2 uv = w * vec2(v0.u, v0.v) + u * vec2(v1.u, v1.v) + v * vec2(v2.u, v2.v);
  vec3 albedo = vec3(0.0f), emission = vec3(0.0f);
  float metallic = 0.0f, roughness = 1.0f;
  bool sampled = false;
  if (mesh.material >= 0) {
    GpuMaterial m = materials[mesh.material];
    albedo = m.baseColor * textureRgb(m.baseColorTexture, uv);
    metallic = m.metallic;
    roughness = m.roughness;
    if (m.metallicRoughnessTexture >= 0) {  // linear data: B metallic, G roughness
      vec3 mr = textureRgb(m.metallicRoughnessTexture, uv);
      metallic *= mr.z;
      roughness *= mr.y;
    }
    if (!backface && (m.emissive.x > 0.0f || m.emissive.y > 0.0f || m.emissive.z > 0.0f))
      emission = m.emissive * textureRgb(m.emissiveTexture, uv);
    sampled = m.sampled != 0;
  }
  vec3 V = -dir;
  hitNormal = N;
  hitView = V;
  hitBaseColor = albedo;
  hitMetallic = metallic;
  hitRoughness = roughness;
  directRequests(P, pcShadowOrigin(P, ng, pcTriangleExtent(p0, p1, p2)), N);
  vec3 indirect = vec3(0.0f);
  if ((params.shading & 1) == 0 && push.slotBase == 0) {
    float coverage = 0.0f;
    vec3 E = pcSampleField(field, P, N, V, PC_SAMPLE_NO_OCCLUSION, coverage).xyz;
    // A glossy hit reads the field a second time, about its lobe's direction.
    vec3 lobeE = vec3(0.0f);
    vec2 ab = vec2(0.0f);
    if (pcHasSpecularLobe(metallic, roughness)) {
      vec3 lobeNormal = pcProbeHitSpecularNormal(N, V, roughness);
      lobeE = pcSampleFieldShaded(field, P, N, lobeNormal, V, PC_SAMPLE_NO_OCCLUSION, coverage).xyz;
      ab = splitSumAt(max(dot(N, V), 0.0f), roughness);
    }
    indirect = pcProbeHitIndirect(N, V, albedo, metallic, roughness, E, lobeE, ab);
  }
  // The CPU's emitted + reflected (direct + indirect), with the direct part left to the blend.
  finish((sampled ? vec3(0.0f) : emission) + indirect, hit.t);
}

void main() {
  launchIndex = (gl_WorkGroupID.y * uint(PC_DISPATCH_ROWS) + gl_WorkGroupID.x) * uint(PC_SHADE_THREADS) +
                gl_LocalInvocationID.x;
  slotStride = uint(params.probeCount) * uint(params.rayCount);
  if (launchIndex >= slotStride) return;
  pending.tmax = 0.0f;
  ivec2 pr = pcLaunchProbeRay(launchIndex, params.probeCount, params.rayCount);
  rayIndex = uint(params.requestBase + pr.x) * uint(params.rayCount) + uint(pr.y);
  rngState = pcRayRandomSeed(params.seed, rayIndex);
  vec3 dir = rayDirs[pr.y].xyz;
  GpuHit hit = hits[launchIndex];
  if (hit.instance < 0) {
    finish(skyRadiance(dir), PC_MISS_DISTANCE);
  } else {
    shadeHit(hit, dir);
  }
}
