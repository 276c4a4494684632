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

// Where probe k's depth-moment distance of `ray` lies in sDepth (in floats).
int depthAt(bool fourLanes, int k, int ray, int rowStride) { return fourLanes ? 4 * ray + k : k * rowStride + ray; }

bool closer(float d, int i, float bestD, int bestI) { return d < bestD || (d == bestD && i < bestI); }

void main() {
  const int ni = PC_IRRADIANCE_TEXELS, nd = PC_DEPTH_TEXELS, no = PC_OCCLUSION_TEXELS;
  int tid = int(gl_LocalInvocationIndex);
  int rayCount = params.rayCount;
  int groupProbes = pcBlendProbes(rayCount);
  int firstRequest = (int(gl_WorkGroupID.y) * PC_DISPATCH_ROWS + int(gl_WorkGroupID.x)) * groupProbes;
  if (firstRequest >= params.probeCount) return;  // uniform across the workgroup
  int probesHere = min(groupProbes, params.probeCount - firstRequest);
  int rowStride = rayCount + 1;  // of the shared ray rows
  // Groups of four probes sum their tiles in vec4s (step 2).
  const bool fourLanes = groupProbes == 4 && K == 4;

  // ---- each probe's cascade: ray reach and tile origins ----
  if (tid < probesHere) {
    ivec2 ref = requests[firstRequest + tid];
    CascadeDesc c = field.cascades[ref.x];
    sMaxDistance[tid] = c.maxRayDistance;
    sIrradianceOrigin[tid] = pcAtlasTileOrigin(c, ref.y, ni + 2);
    sDepthOrigin[tid] = pcAtlasTileOrigin(c, ref.y, nd + 2);
    sOcclusionOrigin[tid] = pcAtlasTileOrigin(c, ref.y, no + 2);
  }
  barrier();

  // ---- 0. the rays: the group's requests are neighbours in launch order, so the reads of
  // one ray of all of them are contiguous. kLoads items per thread at a time, their loads
  // issued together (then the dependent shadow-light loads), rather than one round trip per item ----
  const int kLoads = 4;
  // No shadow slots, or the rounds' resolve passes added their light already.
  const bool lightsInRays = params.shadowSlots == 0 || params.lightsResolved != 0;
  int items = probesHere * rayCount;
  for (int first = tid; first < items; first += kLoads * PC_BLEND_THREADS) {
    vec4 r[kLoads];
    uint mask0[kLoads];
    uint at[kLoads];
    [[unroll]] for (int u = 0; u < kLoads; ++u) {
      int item = min(first + u * PC_BLEND_THREADS, items - 1);  // past the end: a repeat, not stored
      int k = item % probesHere, ray = item / probesHere;
      at[u] = pcProbeRayLaunchIndex(firstRequest + k, ray, params.probeCount, rayCount);
      r[u] = rays[at[u]];
      mask0[u] = lightsInRays ? 0u : shadowMask[at[u]];
    }
    [[unroll]] for (int u = 0; u < kLoads; ++u) {
      int item = first + u * PC_BLEND_THREADS;
      if (item >= items) break;
      int k = item % probesHere, ray = item / probesHere;
      float d = r[u].w;
      sRay[k * rowStride + ray] = vec4(lightsInRays ? r[u].xyz : pcAddVisibleLight(at[u], r[u].xyz, mask0[u]), d);
      int slot = depthAt(fourLanes, k, ray, rowStride);
      sDepth[slot >> 2][slot & 3] = d < 0.0f ? -d * PC_BACKFACE_DEPTH_SCALE : min(d, sMaxDistance[k]);
    }
  }
  barrier();

  // ---- 1. classification and relocation: a power-of-two share of the threads per probe ----
  {
    int share = PC_BLEND_THREADS / groupProbes;
    int k = tid / share, lane = tid - k * share;
    uint backfaces = 0u;
    float backDist = PC_MISS_DISTANCE, frontDist = PC_MISS_DISTANCE;
    int backRay = rayCount, frontRay = rayCount;
    for (int ray = k < probesHere ? lane : rayCount; ray < rayCount; ray += share) {
      float d = sRay[k * rowStride + ray].w;
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
    if (lane == 0 && k < probesHere) {
      int request = firstRequest + k;
      ivec2 ref = requests[request];
      CascadeDesc c = field.cascades[ref.x];
      int record = c.firstProbe + ref.y;
      GpuProbeRecord r = probes[record];
      float backfaceFraction = float(sBackfaces[tid]) / float(max(rayCount, 1));
      vec3 backDir = sBackRay[tid] < rayCount ? rayDirs[sBackRay[tid]].xyz : vec3(0.0f);
      vec3 frontDir = sFrontRay[tid] < rayCount ? rayDirs[sFrontRay[tid]].xyz : vec3(0.0f);
      int oldState = r.state;
      vec3 oldOffset = r.offset;
      bool inside = pcProbeInside(backfaceFraction, oldState);
      r.offset = pcRelocate(r.offset, inside, sBackDist[tid], backDir, sFrontDist[tid], frontDir,
                            0.2f * c.spacing, 0.45f * c.spacing);
      bool moved = length(r.offset - oldOffset) > 0.01f * c.spacing;
      sInside[k] = inside;
      if (inside) {
        // Inside geometry: never sampled, history dropped, tiles left alone.
        r.state = PC_PROBE_INSIDE;
        r.updates = 0u;
        changes[request] = (oldState != PC_PROBE_INSIDE || moved) ? uintBitsToFloat(kInfinityBits) : 0.0f;
      } else {
        float reach = sqrt(3.0f) * c.spacing;
        r.state = (sBackfaces[tid] == 0u && sFrontDist[tid] > reach) ? PC_PROBE_SLEEPING : PC_PROBE_ACTIVE;
        bool hasHistory = r.updates > 0u && !moved;
        sAlpha[k] = hasHistory ? min(params.hysteresis, float(r.updates) / float(r.updates + 1u)) : 0.0f;
        r.updates = hasHistory ? r.updates + 1u : 1u;
        sMaxChange[k] = (oldState != r.state || moved) ? kInfinityBits : 0u;
      }
      probes[record] = r;
    }
  }
  barrier();

  // ---- 2. tiles: irradiance and occlusion (one texel per thread of the first n_i^2), depth
  // (the other threads, several texels each); texels of inside probes are left alone. Groups
  // of four probes sum in vec4s, probe k in component k (the same sums in the same order as
  // the arrays that fewer probes use; the blend takes 0.62 ms on an H200, 0.71 with the arrays) ----
  const int irrTexelCount = ni * ni, depthTexelCount = nd * nd;
  if (tid < irrTexelCount) {
    float dmax = field.occlusionDistance;
    vec3 irrSum[K];
    float irrWeight[K], open[K], occWeight[K];
    [[unroll]] for (int k = 0; k < K; ++k) {
      irrSum[k] = vec3(0.0f);
      irrWeight[k] = open[k] = occWeight[k] = 0.0f;
    }
    uvec2 h = tapHeader(tid);
    // Taps come four at a time, the next block loaded while this one is summed.
    const uint blockStride = 4u * uint(irrTexelCount);
    uint blocks = (h.x + 3u) / 4u;
    uvec4 nextBlock = blocks > 0u ? tapBlock(h.y) : uvec4(0u);
    if (fourLanes) {  // the same sums, probe k in component k
      vec4 sr = vec4(0.0f), sg = vec4(0.0f), sb = vec4(0.0f), wi = vec4(0.0f), op = vec4(0.0f), wo = vec4(0.0f);
      for (uint b = 0u; b < blocks; ++b) {
        uvec4 block = nextBlock;
        if (b + 1u < blocks) nextBlock = tapBlock(h.y + (b + 1u) * blockStride);
        [[unroll]] for (int u = 0; u < 4; ++u) {
          if (4u * b + uint(u) >= h.x) break;
          float w = tapWeight(block[u]);
          int ray = tapRay(block[u]);
          vec4 r0 = sRay[ray], r1 = sRay[rowStride + ray], r2 = sRay[2 * rowStride + ray], r3 = sRay[3 * rowStride + ray];
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
      blocks = 0u;
    }
    for (uint b = 0u; b < blocks; ++b) {
      uvec4 block = nextBlock;
      if (b + 1u < blocks) nextBlock = tapBlock(h.y + (b + 1u) * blockStride);
      [[unroll]] for (int u = 0; u < 4; ++u) {
        if (4u * b + uint(u) >= h.x) break;
        float w = tapWeight(block[u]);
        int ray = tapRay(block[u]);
        [[unroll]] for (int k = 0; k < K; ++k) {
          if (k >= probesHere) break;
          vec4 r = sRay[k * rowStride + ray];
          open[k] += r.w > dmax ? w : 0.0f;
          occWeight[k] += w;
          if (r.w >= 0.0f) {  // backface hits carry no light
            irrSum[k] += w * r.xyz;
            irrWeight[k] += w;
          }
        }
      }
    }
    [[unroll]] for (int k = 0; k < K; ++k) {
      if (k >= probesHere) break;
      if (sInside[k]) continue;
      ivec2 texel = ivec2(1 + tid % ni, 1 + tid / ni);
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
  } else {
    for (int t = tid - irrTexelCount; t < depthTexelCount; t += PC_BLEND_THREADS - irrTexelCount) {
      float m1[K], m2[K], depthWeight[K];
      [[unroll]] for (int k = 0; k < K; ++k) m1[k] = m2[k] = depthWeight[k] = 0.0f;
      uvec2 h = tapHeader(irrTexelCount + t);
      const uint blockStride = 4u * uint(depthTexelCount);
      uint blocks = (h.x + 3u) / 4u;
      uvec4 nextBlock = blocks > 0u ? tapBlock(h.y) : uvec4(0u);
      if (fourLanes) {  // the same sums, probe k in component k
        vec4 s1 = vec4(0.0f), s2 = vec4(0.0f), sw = vec4(0.0f);
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
        blocks = 0u;
      }
      for (uint b = 0u; b < blocks; ++b) {
        uvec4 block = nextBlock;
        if (b + 1u < blocks) nextBlock = tapBlock(h.y + (b + 1u) * blockStride);
        [[unroll]] for (int u = 0; u < 4; ++u) {
          if (4u * b + uint(u) >= h.x) break;
          float w = tapWeight(block[u]);
          int ray = tapRay(block[u]);
          [[unroll]] for (int k = 0; k < K; ++k) {
            if (k >= probesHere) break;
            int slot = depthAt(fourLanes, k, ray, rowStride);
            float dist = sDepth[slot >> 2][slot & 3];
            m1[k] += w * dist;
            m2[k] += w * dist * dist;
            depthWeight[k] += w;
          }
        }
      }
      [[unroll]] for (int k = 0; k < K; ++k) {
        if (k >= probesHere) break;
        if (sInside[k] || !(depthWeight[k] > 0.0f)) continue;
        int i = pcDepthIndex(sDepthOrigin[k] + ivec2(1 + t % nd, 1 + t / nd));
        depthTexels[i] = mix(vec2(m1[k], m2[k]) / depthWeight[k], depthTexels[i], sAlpha[k]);
      }
    }
  }
  memoryBarrierBuffer();
  barrier();

  // ---- 3. borders: each border texel copies its interior source (pcBorderSource) ----
  // Border texels of a tile of size s = n + 2, walked as top row, bottom row, left and right
  // columns: 4 (s - 1) of them per channel.
  const int si = ni + 2, sd = nd + 2, so = no + 2;
  const int bi = 4 * (si - 1), bd = 4 * (sd - 1), bo = 4 * (so - 1);
  for (int item = tid; item < probesHere * (bi + bd + bo); item += PC_BLEND_THREADS) {
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
    ivec2 o = channel == 0 ? sIrradianceOrigin[k] : channel == 1 ? sDepthOrigin[k] : sOcclusionOrigin[k];
    if (channel == 0) {
      irradianceTexels[pcIrradianceIndex(o + bxy)] = irradianceTexels[pcIrradianceIndex(o + src)];
    } else if (channel == 1) {
      depthTexels[pcDepthIndex(o + bxy)] = depthTexels[pcDepthIndex(o + src)];
    } else {
      occlusionTexels[pcOcclusionIndex(o + bxy)] = occlusionTexels[pcOcclusionIndex(o + src)];
    }
  }
  if (tid < probesHere && !sInside[tid]) changes[firstRequest + tid] = uintBitsToFloat(sMaxChange[tid]);
}
