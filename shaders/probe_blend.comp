#version 460
// Blends requested probes' ray results into their tiles, the same steps and shared math as the
// CPU's blendProbe (server/probe_blend.cpp):
//   1. classification and relocation from backface share and closest hits,
//   2. irradiance (cosine lobe), depth moments (cos^exponent lobe), occlusion (share of rays
//      past d_max), blended with hysteresis after a running mean,
//   3. the tiles' 1-texel borders,
// and records the largest change of an encoded irradiance texel for change detection.
//
// A workgroup takes pcBlendProbes consecutive requests (interop/gpu_trace.h). Their rays are
// read once, into shared memory, with the light of their visible shadow slots added (the
// last step of the shade wavefront; with shadow rounds, the resolve passes added it before). The lobe weights come from the update's tap lists
// (PC_BIND_TAPS), the CPU's own, so each texel sums the same rays with the same weights in
// the same order as the CPU; each tap loaded serves every probe of the group.
//
// Shared memory holds each probe's rays in a row of rayCount + 1 (probe-major, padded): the
// threads of a warp read different rays of one probe per tap, and with the padding those land
// in different banks (with rays interleaved by probe, a vec4 tap read hit only two of the
// eight 16-byte bank groups). The depth-moment distances, one float per probe and ray, are
// the exception: with four probes a ray's four sit side by side, so a depth tap is one
// 16-byte read for the whole group. Each probe's tile origins and ray reach are looked up
// once, up front, instead of per texel and per border texel.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
#include "field_buffers.glsl"
#include "interop/probe_update.h"

layout(local_size_x = PC_BLEND_THREADS) in;

// Rays the shared scratch holds: pcBlendScratch for this pipeline's ray count (the host
// always specializes it; the default, a literal as specialization constants need, is the
// most any ray count needs: PC_MAX_RAYS_PER_PROBE + PC_BLEND_MAX_PROBES).
layout(constant_id = 1) const int kScratch = 1028;

layout(std430, set = 0, binding = PC_BIND_PARAMS) readonly buffer Params { UpdateParams params; };
layout(std430, set = 0, binding = PC_BIND_REQUESTS) readonly buffer Requests { ivec2 requests[]; };
layout(std430, set = 0, binding = PC_BIND_RAY_DIRS) readonly buffer RayDirs { vec4 rayDirs[]; };
layout(std430, set = 0, binding = PC_BIND_RAYS) readonly buffer Rays { vec4 rays[]; };
layout(std430, set = 0, binding = PC_BIND_SHADOW_MASK) readonly buffer ShadowMask { uint shadowMask[]; };
layout(std430, set = 0, binding = PC_BIND_SHADOW_LIGHT) readonly buffer ShadowLight { GpuShadowLight shadowLight[]; };
layout(std430, set = 0, binding = PC_BIND_CHANGES) writeonly buffer Changes { float changes[]; };
layout(std430, set = 0, binding = PC_BIND_TAPS) readonly buffer Taps { uvec4 taps[]; };  // blocks of four words

#include "visible_light.glsl"

const uint kInfinityBits = 0x7f800000u;
const int K = PC_BLEND_MAX_PROBES;

// The group's rays, a padded row per probe ([k * (rayCount + 1) + ray]): radiance and signed
// distance. And the distance the depth moments use, at depthAt(k, ray): with four probes a
// ray's four distances side by side, one 16-byte load per depth tap instead of four.
shared vec4 sRay[kScratch];
shared vec4 sDepth[(kScratch + 3) / 4];
// Reductions, PC_BLEND_THREADS / groupProbes threads per probe: backface count and the closest
// back/front hits (distance, then ray index, so ties resolve to the first ray as on the CPU).
shared uint sBackfaces[PC_BLEND_THREADS];
shared float sBackDist[PC_BLEND_THREADS];
shared int sBackRay[PC_BLEND_THREADS];
shared float sFrontDist[PC_BLEND_THREADS];
shared int sFrontRay[PC_BLEND_THREADS];
shared float sAlpha[K];
shared float sMaxDistance[K];
shared ivec2 sIrradianceOrigin[K], sDepthOrigin[K], sOcclusionOrigin[K];  // tile origins (bordered)
shared bool sInside[K];
shared uint sMaxChange[K];  // float bits; non-negative floats order like their bits

// Texel t's tap count and first tap word (interop/gpu_trace.h).
uvec2 tapHeader(int t) {
  uvec4 pair = taps[t >> 1];
  return (t & 1) == 0 ? pair.xy : pair.zw;
}

// The block of four taps starting at word `first` (a multiple of four).
uvec4 tapBlock(uint first) { return taps[first >> 2]; }

// A tap word's ray and weight.
int tapRay(uint word) { return int(word & 0xffffu); }
float tapWeight(uint word) { return unpackHalf2x16(word).y; }

// The workgroup's share of the update: its requests, and how their rays lie in shared memory.
struct Group {
  int first;       // the first of its requests
  int probes;      // its requests: pcBlendProbes, or fewer in the last group
  int perGroup;    // pcBlendProbes for this ray count (what the host dispatched for)
  int rayCount;
  int rowStride;   // of the shared ray rows: rayCount + 1
  bool fourLanes;  // groups of four probes sum their tiles in vec4s, probe k in component k
};

// Where probe k's depth-moment distance of `ray` lies in sDepth (in floats).
int depthAt(Group g, int k, int ray) { return g.fourLanes ? 4 * ray + k : k * g.rowStride + ray; }

bool closer(float d, int i, float bestD, int bestI) {
  return d < bestD || (d == bestD && i < bestI);
}

// Each probe's cascade, looked up once: its ray reach and its tiles' origins (bordered).
void lookUpTiles(Group g, int tid) {
  if (tid >= g.probes) return;
  ivec2 ref = requests[g.first + tid];
  CascadeDesc c = field.cascades[ref.x];
  sMaxDistance[tid] = c.maxRayDistance;
  sIrradianceOrigin[tid] = pcAtlasTileOrigin(c, ref.y, PC_IRRADIANCE_TEXELS + 2);
  sDepthOrigin[tid] = pcAtlasTileOrigin(c, ref.y, PC_DEPTH_TEXELS + 2);
  sOcclusionOrigin[tid] = pcAtlasTileOrigin(c, ref.y, PC_OCCLUSION_TEXELS + 2);
}

// Step 0, the rays into shared memory, each with the light of its visible shadow slots. The
// group's requests are neighbours in launch order, so the reads of one ray of all of them are
// contiguous. kLoads items per thread at a time, their loads issued together (then the
// dependent shadow-light loads), rather than one round trip per item.
void gatherRays(Group g, int tid) {
  const int kLoads = 4;
  // No shadow slots, or the rounds' resolve passes added their light already.
  const bool lightsInRays = params.shadowSlots == 0 || params.lightsResolved != 0;
  int items = g.probes * g.rayCount;
  for (int first = tid; first < items; first += kLoads * PC_BLEND_THREADS) {
    vec4 r[kLoads];
    uint mask0[kLoads];
    uint at[kLoads];
    [[unroll]] for (int u = 0; u < kLoads; ++u) {
      // Past the end: a repeat, not stored.
      int item = min(first + u * PC_BLEND_THREADS, items - 1);
      int k = item % g.probes, ray = item / g.probes;
      at[u] = pcProbeRayLaunchIndex(g.first + k, ray, params.probeCount, g.rayCount);
      r[u] = rays[at[u]];
      mask0[u] = lightsInRays ? 0u : shadowMask[at[u]];
    }
    [[unroll]] for (int u = 0; u < kLoads; ++u) {
      int item = first + u * PC_BLEND_THREADS;
      if (item >= items) break;
      int k = item % g.probes, ray = item / g.probes;
      float d = r[u].w;
      vec3 radiance = lightsInRays ? r[u].xyz : pcAddVisibleLight(at[u], r[u].xyz, mask0[u]);
      sRay[k * g.rowStride + ray] = vec4(radiance, d);
      int slot = depthAt(g, k, ray);
      sDepth[slot >> 2][slot & 3] =
          d < 0.0f ? -d * PC_BACKFACE_DEPTH_SCALE : min(d, sMaxDistance[k]);
    }
  }
}

// Step 1's reduction over probe k's rays by its `share` threads (this one is `lane` of them):
// the backface count and the closest back and front hits, left in the shared entry of lane 0.
void reduceHits(Group g, int tid, int k, int lane, int share) {
  uint backfaces = 0u;
  float backDist = PC_MISS_DISTANCE, frontDist = PC_MISS_DISTANCE;
  int backRay = g.rayCount, frontRay = g.rayCount;
  for (int ray = k < g.probes ? lane : g.rayCount; ray < g.rayCount; ray += share) {
    float d = sRay[k * g.rowStride + ray].w;
    if (d < 0.0f) {
      ++backfaces;
      if (-d < backDist) backDist = -d, backRay = ray;
    } else if (d < frontDist) {
      frontDist = d, frontRay = ray;
    }
  }
  sBackfaces[tid] = backfaces;
  sBackDist[tid] = backDist;
  sBackRay[tid] = backRay;
  sFrontDist[tid] = frontDist;
  sFrontRay[tid] = frontRay;
  barrier();
  for (int stride = share / 2; stride > 0; stride /= 2) {
    if (lane < stride) {
      int o = tid + stride;
      sBackfaces[tid] += sBackfaces[o];
      if (closer(sBackDist[o], sBackRay[o], sBackDist[tid], sBackRay[tid])) {
        sBackDist[tid] = sBackDist[o];
        sBackRay[tid] = sBackRay[o];
      }
      if (closer(sFrontDist[o], sFrontRay[o], sFrontDist[tid], sFrontRay[tid])) {
        sFrontDist[tid] = sFrontDist[o];
        sFrontRay[tid] = sFrontRay[o];
      }
    }
    barrier();
  }
}

// Step 1 for probe k, from the reduction in entry `tid`: its state, offset and history, the
// blend weight of its tiles (sAlpha) and the change it reports so far.
void classifyProbe(Group g, int k, int tid) {
  int request = g.first + k;
  ivec2 ref = requests[request];
  CascadeDesc c = field.cascades[ref.x];
  int record = c.firstProbe + ref.y;
  GpuProbeRecord r = probes[record];
  float backfaceFraction = float(sBackfaces[tid]) / float(max(g.rayCount, 1));
  vec3 backDir = sBackRay[tid] < g.rayCount ? rayDirs[sBackRay[tid]].xyz : vec3(0.0f);
  vec3 frontDir = sFrontRay[tid] < g.rayCount ? rayDirs[sFrontRay[tid]].xyz : vec3(0.0f);
  int oldState = r.state;
  vec3 oldOffset = r.offset;
  bool inside = pcProbeInside(backfaceFraction, oldState);
  r.offset = pcRelocate(r.offset, inside, sBackDist[tid], backDir, sFrontDist[tid], frontDir,
                        PC_RELOCATE_MIN_FRONTFACE * c.spacing, PC_RELOCATE_MAX_OFFSET * c.spacing);
  bool moved = length(r.offset - oldOffset) > 0.01f * c.spacing;
  sInside[k] = inside;
  if (inside) {
    // Inside geometry: never sampled, history dropped, tiles left alone.
    r.state = PC_PROBE_INSIDE;
    r.updates = 0u;
    bool changed = oldState != PC_PROBE_INSIDE || moved;
    changes[request] = changed ? uintBitsToFloat(kInfinityBits) : 0.0f;
  } else {
    float reach = sqrt(3.0f) * c.spacing;
    bool asleep = sBackfaces[tid] == 0u && sFrontDist[tid] > reach;
    r.state = asleep ? PC_PROBE_SLEEPING : PC_PROBE_ACTIVE;
    bool hasHistory = r.updates > 0u && !moved;
    float runningMean = float(r.updates) / float(r.updates + 1u);
    sAlpha[k] = hasHistory ? min(c.hysteresis, runningMean) : 0.0f;
    r.updates = hasHistory ? r.updates + 1u : 1u;
    sMaxChange[k] = (oldState != r.state || moved) ? kInfinityBits : 0u;
  }
  probes[record] = r;
}

// Step 1, classification and relocation: a power-of-two share of the threads per probe.
void classifyAndRelocate(Group g, int tid) {
  int share = PC_BLEND_THREADS / g.perGroup;
  int k = tid / share, lane = tid - k * share;
  reduceHits(g, tid, k, lane, share);
  if (lane == 0 && k < g.probes) classifyProbe(g, k, tid);
}

// The sums of one texel's taps (from word `h.y`, `h.x` of them) come in two layouts with the
// same sums in the same order: a group of four probes sums in vec4s, probe k in component k
// (the blend takes 0.62 ms on an H200, 0.71 with the arrays); fewer probes sum in arrays.
// Taps come four at a time, the next block loaded while this one is summed.

// Irradiance and occlusion sums of one texel for a group of four probes: irradiance over
// front-face hits, occlusion the weight of rays past `dmax`.
void irradianceSumsInLanes(Group g, uvec2 h, float dmax, out vec3 irrSum[K],
                           out float irrWeight[K], out float open[K], out float occWeight[K]) {
  vec4 sr = vec4(0.0f), sg = vec4(0.0f), sb = vec4(0.0f);
  vec4 wi = vec4(0.0f), op = vec4(0.0f), wo = vec4(0.0f);
  const uint blockStride = 4u * uint(PC_IRRADIANCE_TEXELS * PC_IRRADIANCE_TEXELS);
  uint blocks = (h.x + 3u) / 4u;
  uvec4 nextBlock = blocks > 0u ? tapBlock(h.y) : uvec4(0u);
  for (uint b = 0u; b < blocks; ++b) {
    uvec4 block = nextBlock;
    if (b + 1u < blocks) nextBlock = tapBlock(h.y + (b + 1u) * blockStride);
    [[unroll]] for (int u = 0; u < 4; ++u) {
      if (4u * b + uint(u) >= h.x) break;
      float w = tapWeight(block[u]);
      int ray = tapRay(block[u]);
      vec4 r0 = sRay[ray], r1 = sRay[g.rowStride + ray];
      vec4 r2 = sRay[2 * g.rowStride + ray], r3 = sRay[3 * g.rowStride + ray];
      vec4 d = vec4(r0.w, r1.w, r2.w, r3.w);
      op += vec4(greaterThan(d, vec4(dmax))) * w;
      wo += w;
      vec4 lit = vec4(greaterThanEqual(d, vec4(0.0f))) * w;
      sr += lit * vec4(r0.x, r1.x, r2.x, r3.x);
      sg += lit * vec4(r0.y, r1.y, r2.y, r3.y);
      sb += lit * vec4(r0.z, r1.z, r2.z, r3.z);
      wi += lit;
    }
  }
  [[unroll]] for (int k = 0; k < K; ++k) {
    irrSum[k] = vec3(sr[k], sg[k], sb[k]);
    irrWeight[k] = wi[k];
    open[k] = op[k];
    occWeight[k] = wo[k];
  }
}

// The same sums for groups of fewer probes.
void irradianceSumsInArrays(Group g, uvec2 h, float dmax, out vec3 irrSum[K],
                            out float irrWeight[K], out float open[K], out float occWeight[K]) {
  [[unroll]] for (int k = 0; k < K; ++k) {
    irrSum[k] = vec3(0.0f);
    irrWeight[k] = open[k] = occWeight[k] = 0.0f;
  }
  const uint blockStride = 4u * uint(PC_IRRADIANCE_TEXELS * PC_IRRADIANCE_TEXELS);
  uint blocks = (h.x + 3u) / 4u;
  uvec4 nextBlock = blocks > 0u ? tapBlock(h.y) : uvec4(0u);
  for (uint b = 0u; b < blocks; ++b) {
    uvec4 block = nextBlock;
    if (b + 1u < blocks) nextBlock = tapBlock(h.y + (b + 1u) * blockStride);
    [[unroll]] for (int u = 0; u < 4; ++u) {
      if (4u * b + uint(u) >= h.x) break;
      float w = tapWeight(block[u]);
      int ray = tapRay(block[u]);
      [[unroll]] for (int k = 0; k < K; ++k) {
        if (k >= g.probes) break;
        vec4 r = sRay[k * g.rowStride + ray];
        open[k] += r.w > dmax ? w : 0.0f;
        occWeight[k] += w;
        if (r.w >= 0.0f) {  // backface hits carry no light
          irrSum[k] += w * r.xyz;
          irrWeight[k] += w;
        }
      }
    }
  }
}

// Step 2 for irradiance/occlusion texel t (row-major in the tile's interior) of every probe
// of the group not inside geometry: the new sample blended with the old texel, and the
// probe's largest change of an encoded irradiance texel.
void blendIrradianceAndOcclusion(Group g, int t) {
  const int ni = PC_IRRADIANCE_TEXELS;
  vec3 irrSum[K];
  float irrWeight[K], open[K], occWeight[K];
  uvec2 h = tapHeader(t);
  float dmax = field.occlusionDistance;
  if (g.fourLanes)
    irradianceSumsInLanes(g, h, dmax, irrSum, irrWeight, open, occWeight);
  else
    irradianceSumsInArrays(g, h, dmax, irrSum, irrWeight, open, occWeight);
  [[unroll]] for (int k = 0; k < K; ++k) {
    if (k >= g.probes) break;
    if (sInside[k]) continue;
    ivec2 texel = ivec2(1 + t % ni, 1 + t / ni);
    if (irrWeight[k] > 0.0f) {
      int i = pcIrradianceIndex(sIrradianceOrigin[k] + texel);
      vec3 sample_ = pcEncodeIrradiance(PC_PI * irrSum[k] / irrWeight[k]);
      vec3 old = irradianceTexels[i].xyz;
      vec3 blended = mix(sample_, old, sAlpha[k]);
      vec3 delta = abs(blended - old);
      atomicMax(sMaxChange[k], floatBitsToUint(max(delta.x, max(delta.y, delta.z))));
      irradianceTexels[i] = vec4(blended, 0.0f);
    }
    if (occWeight[k] > 0.0f) {
      int i = pcOcclusionIndex(sOcclusionOrigin[k] + texel);
      occlusionTexels[i] = mix(open[k] / occWeight[k], occlusionTexels[i], sAlpha[k]);
    }
  }
}

// Depth-moment sums (distance, distance squared, weight) of one depth texel for a group of
// four probes: a ray's four distances side by side, one 16-byte read per tap.
void depthSumsInLanes(uvec2 h, out float m1[K], out float m2[K], out float depthWeight[K]) {
  vec4 s1 = vec4(0.0f), s2 = vec4(0.0f), sw = vec4(0.0f);
  const uint blockStride = 4u * uint(PC_DEPTH_TEXELS * PC_DEPTH_TEXELS);
  uint blocks = (h.x + 3u) / 4u;
  uvec4 nextBlock = blocks > 0u ? tapBlock(h.y) : uvec4(0u);
  for (uint b = 0u; b < blocks; ++b) {
    uvec4 block = nextBlock;
    if (b + 1u < blocks) nextBlock = tapBlock(h.y + (b + 1u) * blockStride);
    [[unroll]] for (int u = 0; u < 4; ++u) {
      if (4u * b + uint(u) >= h.x) break;
      float w = tapWeight(block[u]);
      int ray = tapRay(block[u]);
      vec4 dist = sDepth[ray];
      s1 += w * dist;
      s2 += w * dist * dist;
      sw += w;
    }
  }
  [[unroll]] for (int k = 0; k < K; ++k) {
    m1[k] = s1[k];
    m2[k] = s2[k];
    depthWeight[k] = sw[k];
  }
}

// The same sums for groups of fewer probes.
void depthSumsInArrays(Group g, uvec2 h, out float m1[K], out float m2[K],
                       out float depthWeight[K]) {
  [[unroll]] for (int k = 0; k < K; ++k) m1[k] = m2[k] = depthWeight[k] = 0.0f;
  const uint blockStride = 4u * uint(PC_DEPTH_TEXELS * PC_DEPTH_TEXELS);
  uint blocks = (h.x + 3u) / 4u;
  uvec4 nextBlock = blocks > 0u ? tapBlock(h.y) : uvec4(0u);
  for (uint b = 0u; b < blocks; ++b) {
    uvec4 block = nextBlock;
    if (b + 1u < blocks) nextBlock = tapBlock(h.y + (b + 1u) * blockStride);
    [[unroll]] for (int u = 0; u < 4; ++u) {
      if (4u * b + uint(u) >= h.x) break;
      float w = tapWeight(block[u]);
      int ray = tapRay(block[u]);
      [[unroll]] for (int k = 0; k < K; ++k) {
        if (k >= g.probes) break;
        int slot = depthAt(g, k, ray);
        float dist = sDepth[slot >> 2][slot & 3];
        m1[k] += w * dist;
        m2[k] += w * dist * dist;
        depthWeight[k] += w;
      }
    }
  }
}

// Step 2 for depth texel t (row-major in the tile's interior) of every probe of the group not
// inside geometry: the new moments blended with the old texel.
void blendDepth(Group g, int t) {
  const int nd = PC_DEPTH_TEXELS;
  float m1[K], m2[K], depthWeight[K];
  uvec2 h = tapHeader(PC_IRRADIANCE_TEXELS * PC_IRRADIANCE_TEXELS + t);  // after irradiance's
  if (g.fourLanes)
    depthSumsInLanes(h, m1, m2, depthWeight);
  else
    depthSumsInArrays(g, h, m1, m2, depthWeight);
  [[unroll]] for (int k = 0; k < K; ++k) {
    if (k >= g.probes) break;
    if (sInside[k] || !(depthWeight[k] > 0.0f)) continue;
    int i = pcDepthIndex(sDepthOrigin[k] + ivec2(1 + t % nd, 1 + t / nd));
    depthTexels[i] = mix(vec2(m1[k], m2[k]) / depthWeight[k], depthTexels[i], sAlpha[k]);
  }
}

// Step 3, the tiles' borders: each border texel copies its interior source (pcBorderSource).
// Border texels of a tile of size s = n + 2, walked as top row, bottom row, left and right
// columns: 4 (s - 1) of them per channel.
void copyBorders(Group g, int tid) {
  const int ni = PC_IRRADIANCE_TEXELS, nd = PC_DEPTH_TEXELS, no = PC_OCCLUSION_TEXELS;
  const int si = ni + 2, sd = nd + 2, so = no + 2;
  const int bi = 4 * (si - 1), bd = 4 * (sd - 1), bo = 4 * (so - 1);
  for (int item = tid; item < g.probes * (bi + bd + bo); item += PC_BLEND_THREADS) {
    int k = item / (bi + bd + bo), b = item % (bi + bd + bo);
    if (sInside[k]) continue;
    int s, n;
    int channel;  // 0 irradiance, 1 depth, 2 occlusion
    if (b < bi) {
      channel = 0, s = si, n = ni;
    } else if (b < bi + bd) {
      channel = 1, s = sd, n = nd, b -= bi;
    } else {
      channel = 2, s = so, n = no, b -= bi + bd;
    }
    ivec2 bxy = b < s ? ivec2(b, 0)
              : b < 2 * s ? ivec2(b - s, s - 1)
              : b < 3 * s - 2 ? ivec2(0, 1 + b - 2 * s)
              : ivec2(s - 1, 1 + b - (3 * s - 2));
    ivec2 src = pcBorderSource(bxy.x, bxy.y, n) + ivec2(1);
    ivec2 o = channel == 0   ? sIrradianceOrigin[k]
              : channel == 1 ? sDepthOrigin[k]
                             : sOcclusionOrigin[k];
    if (channel == 0) {
      irradianceTexels[pcIrradianceIndex(o + bxy)] = irradianceTexels[pcIrradianceIndex(o + src)];
    } else if (channel == 1) {
      depthTexels[pcDepthIndex(o + bxy)] = depthTexels[pcDepthIndex(o + src)];
    } else {
      occlusionTexels[pcOcclusionIndex(o + bxy)] = occlusionTexels[pcOcclusionIndex(o + src)];
    }
  }
}

void main() {
  Group g;
  g.rayCount = params.rayCount;
  g.perGroup = pcBlendProbes(g.rayCount);
  g.first = (int(gl_WorkGroupID.y) * PC_DISPATCH_ROWS + int(gl_WorkGroupID.x)) * g.perGroup;
  if (g.first >= params.probeCount) return;  // uniform across the workgroup
  g.probes = min(g.perGroup, params.probeCount - g.first);
  g.rowStride = g.rayCount + 1;
  g.fourLanes = g.perGroup == 4 && K == 4;
  int tid = int(gl_LocalInvocationIndex);

  lookUpTiles(g, tid);
  barrier();
  gatherRays(g, tid);
  barrier();
  classifyAndRelocate(g, tid);
  barrier();
  // Step 2, the tiles: irradiance and occlusion one texel per thread of the first n_i^2, depth
  // the other threads, several texels each; texels of inside probes are left alone.
  const int irrTexelCount = PC_IRRADIANCE_TEXELS * PC_IRRADIANCE_TEXELS;
  const int depthTexelCount = PC_DEPTH_TEXELS * PC_DEPTH_TEXELS;
  if (tid < irrTexelCount) {
    blendIrradianceAndOcclusion(g, tid);
  } else {
    for (int t = tid - irrTexelCount; t < depthTexelCount; t += PC_BLEND_THREADS - irrTexelCount)
      blendDepth(g, t);
  }
  memoryBarrierBuffer();  // the borders read texels other threads wrote
  barrier();
  copyBorders(g, tid);
  if (tid < g.probes && !sInside[tid]) changes[g.first + tid] = uintBitsToFloat(sMaxChange[tid]);
}
