#version 460
// Blends one probe's ray results into its tiles: one workgroup per requested probe, the same
// steps and shared math as the CPU's blendProbe (server/probe_blend.cpp):
//   1. classification and relocation from backface share and closest hits,
//   2. irradiance (cosine lobe), depth moments (cos^exponent lobe), occlusion (share of rays
//      past d_max), blended with hysteresis after a running mean,
//   3. the tiles' 1-texel borders,
// and records the largest change of an encoded irradiance texel for change detection.
// The probe's ray results are read from global memory once, into shared memory; the lobe
// weights come from the update's tap lists (PC_BIND_TAPS), the CPU's own, so each texel sums
// the same rays with the same weights in the same order as the CPU.
#extension GL_GOOGLE_include_directive : require
#include "field_buffers.glsl"
#include "interop/probe_update.h"

layout(local_size_x = PC_BLEND_THREADS) in;

layout(std430, set = 0, binding = PC_BIND_PARAMS) readonly buffer Params { UpdateParams params; };
layout(std430, set = 0, binding = PC_BIND_REQUESTS) readonly buffer Requests { ivec2 requests[]; };
layout(std430, set = 0, binding = PC_BIND_RAY_DIRS) readonly buffer RayDirs { vec4 rayDirs[]; };
layout(std430, set = 0, binding = PC_BIND_RAYS) readonly buffer Rays { vec4 rays[]; };
layout(std430, set = 0, binding = PC_BIND_CHANGES) writeonly buffer Changes { float changes[]; };
layout(std430, set = 0, binding = PC_BIND_TAPS) readonly buffer Taps { uvec2 taps[]; };

const uint kInfinityBits = 0x7f800000u;

// The probe's rays: radiance and signed distance, and the distance the depth moments use.
shared vec4 sRay[PC_MAX_RAYS_PER_PROBE];
shared float sDepth[PC_MAX_RAYS_PER_PROBE];
// Reductions: backface count and the closest back/front hits (distance, then ray index, so
// ties resolve to the first ray as on the CPU).
shared uint sBackfaces[PC_BLEND_THREADS];
shared float sBackDist[PC_BLEND_THREADS];
shared int sBackRay[PC_BLEND_THREADS];
shared float sFrontDist[PC_BLEND_THREADS];
shared int sFrontRay[PC_BLEND_THREADS];
shared float sAlpha;
shared bool sInside;
shared uint sMaxChange;  // float bits; non-negative floats order like their bits

bool closer(float d, int i, float bestD, int bestI) { return d < bestD || (d == bestD && i < bestI); }

void main() {
  int request = int(gl_WorkGroupID.y) * PC_BLEND_ROWS + int(gl_WorkGroupID.x);
  if (request >= params.probeCount) return;  // uniform across the workgroup
  int tid = int(gl_LocalInvocationIndex);
  ivec2 ref = requests[request];
  CascadeDesc c = field.cascades[ref.x];
  int slot = ref.y;
  int record = c.firstProbe + slot;
  int rayCount = params.rayCount;
  int rayBase = request * rayCount;

  // ---- 1. classification and relocation ----
  uint backfaces = 0u;
  float backDist = PC_MISS_DISTANCE, frontDist = PC_MISS_DISTANCE;
  int backRay = rayCount, frontRay = rayCount;
  for (int i = tid; i < rayCount; i += PC_BLEND_THREADS) {
    vec4 r = rays[rayBase + i];
    float d = r.w;
    sRay[i] = r;
    sDepth[i] = d < 0.0f ? -d * PC_BACKFACE_DEPTH_SCALE : min(d, c.maxRayDistance);
    if (d < 0.0f) {
      ++backfaces;
      if (-d < backDist) backDist = -d, backRay = i;
    } else if (d < frontDist) {
      frontDist = d, frontRay = i;
    }
  }
  sBackfaces[tid] = backfaces;
  sBackDist[tid] = backDist;
  sBackRay[tid] = backRay;
  sFrontDist[tid] = frontDist;
  sFrontRay[tid] = frontRay;
  barrier();
  for (int stride = PC_BLEND_THREADS / 2; stride > 0; stride /= 2) {
    if (tid < stride) {
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
  if (tid == 0) {
    GpuProbeRecord r = probes[record];
    float backfaceFraction = float(sBackfaces[0]) / float(max(rayCount, 1));
    vec3 backDir = sBackRay[0] < rayCount ? rayDirs[sBackRay[0]].xyz : vec3(0.0f);
    vec3 frontDir = sFrontRay[0] < rayCount ? rayDirs[sFrontRay[0]].xyz : vec3(0.0f);
    int oldState = r.state;
    vec3 oldOffset = r.offset;
    bool inside = pcProbeInside(backfaceFraction, oldState);
    r.offset = pcRelocate(r.offset, inside, sBackDist[0], backDir, sFrontDist[0], frontDir,
                          0.2f * c.spacing, 0.45f * c.spacing);
    bool moved = length(r.offset - oldOffset) > 0.01f * c.spacing;
    if (inside) {
      // Inside geometry: never sampled, history dropped, tiles left alone.
      r.state = PC_PROBE_INSIDE;
      r.updates = 0u;
      sInside = true;
      changes[request] = (oldState != PC_PROBE_INSIDE || moved) ? uintBitsToFloat(kInfinityBits) : 0.0f;
    } else {
      float reach = sqrt(3.0f) * c.spacing;
      r.state = (sBackfaces[0] == 0u && sFrontDist[0] > reach) ? PC_PROBE_SLEEPING : PC_PROBE_ACTIVE;
      bool hasHistory = r.updates > 0u && !moved;
      sAlpha = hasHistory ? min(params.hysteresis, float(r.updates) / float(r.updates + 1u)) : 0.0f;
      r.updates = hasHistory ? r.updates + 1u : 1u;
      sInside = false;
      sMaxChange = (oldState != r.state || moved) ? kInfinityBits : 0u;
    }
    probes[record] = r;
  }
  barrier();
  if (sInside) return;  // uniform: read after the barrier by every invocation
  float alpha = sAlpha;

  // ---- 2. tiles: irradiance (threads 0-63), occlusion (64-127), depth (all 256) ----
  const int ni = PC_IRRADIANCE_TEXELS, nd = PC_DEPTH_TEXELS, no = PC_OCCLUSION_TEXELS;
  bool doIrradiance = tid < ni * ni;
  bool doOcclusion = tid >= ni * ni && tid < ni * ni + no * no;
  int ot = tid - ni * ni;
  float dmax = field.occlusionDistance;

  vec3 irrSum = vec3(0.0f);
  float irrWeight = 0.0f, m1 = 0.0f, m2 = 0.0f, depthWeight = 0.0f, open = 0.0f, occWeight = 0.0f;
  if (doIrradiance) {
    uvec2 h = taps[tid];
    for (uint j = 0u; j < h.x; ++j) {
      uvec2 e = taps[h.y + j * uint(ni * ni)];
      vec4 r = sRay[e.x];
      if (r.w < 0.0f) continue;  // backface hits carry no light
      float w = uintBitsToFloat(e.y);
      irrSum += w * r.xyz;
      irrWeight += w;
    }
  } else if (doOcclusion) {
    uvec2 h = taps[ni * ni + nd * nd + ot];
    for (uint j = 0u; j < h.x; ++j) {
      uvec2 e = taps[h.y + j * uint(no * no)];
      float w = uintBitsToFloat(e.y);
      open += sRay[e.x].w > dmax ? w : 0.0f;
      occWeight += w;
    }
  }
  {
    uvec2 h = taps[ni * ni + tid];
    for (uint j = 0u; j < h.x; ++j) {
      uvec2 e = taps[h.y + j * uint(nd * nd)];
      float w = uintBitsToFloat(e.y);
      float dist = sDepth[e.x];
      m1 += w * dist;
      m2 += w * dist * dist;
      depthWeight += w;
    }
  }

  if (doIrradiance && irrWeight > 0.0f) {
    ivec2 o = pcAtlasTileOrigin(c, slot, ni + 2);
    int i = pcIrradianceIndex(o + ivec2(1 + tid % ni, 1 + tid / ni));
    vec3 sample_ = pcEncodeIrradiance(PC_PI * irrSum / irrWeight);
    vec3 old = vec3(irradianceTexels[i], irradianceTexels[i + 1], irradianceTexels[i + 2]);
    vec3 blended = mix(sample_, old, alpha);
    vec3 delta = abs(blended - old);
    atomicMax(sMaxChange, floatBitsToUint(max(delta.x, max(delta.y, delta.z))));
    irradianceTexels[i] = blended.x;
    irradianceTexels[i + 1] = blended.y;
    irradianceTexels[i + 2] = blended.z;
  }
  if (doOcclusion && occWeight > 0.0f) {
    ivec2 o = pcAtlasTileOrigin(c, slot, no + 2);
    int i = pcOcclusionIndex(o + ivec2(1 + ot % no, 1 + ot / no));
    occlusionTexels[i] = mix(open / occWeight, occlusionTexels[i], alpha);
  }
  if (depthWeight > 0.0f) {
    ivec2 o = pcAtlasTileOrigin(c, slot, nd + 2);
    int i = pcDepthIndex(o + ivec2(1 + tid % nd, 1 + tid / nd));
    depthTexels[i] = mix(m1 / depthWeight, depthTexels[i], alpha);
    depthTexels[i + 1] = mix(m2 / depthWeight, depthTexels[i + 1], alpha);
  }
  memoryBarrierBuffer();
  barrier();

  // ---- 3. borders: each border texel copies its interior source (pcBorderSource) ----
  // Border texels of a tile of size s = n + 2, walked as top row, bottom row, left and right
  // columns: 4 (s - 1) of them.
  const int si = ni + 2, sd = nd + 2, so = no + 2;
  const int bi = 4 * (si - 1), bd = 4 * (sd - 1), bo = 4 * (so - 1);
  int b = tid, s, n;
  int channel;  // 0 irradiance, 1 depth, 2 occlusion, -1 idle
  if (b < bi) {
    channel = 0, s = si, n = ni;
  } else if (b < bi + bd) {
    channel = 1, s = sd, n = nd, b -= bi;
  } else if (b < bi + bd + bo) {
    channel = 2, s = so, n = no, b -= bi + bd;
  } else {
    channel = -1, s = 0, n = 0;
  }
  if (channel >= 0) {
    ivec2 bxy = b < s ? ivec2(b, 0)
              : b < 2 * s ? ivec2(b - s, s - 1)
              : b < 3 * s - 2 ? ivec2(0, 1 + b - 2 * s)
              : ivec2(s - 1, 1 + b - (3 * s - 2));
    ivec2 src = pcBorderSource(bxy.x, bxy.y, n) + ivec2(1);
    ivec2 o = pcAtlasTileOrigin(c, slot, s);
    if (channel == 0) {
      int from = pcIrradianceIndex(o + src), to = pcIrradianceIndex(o + bxy);
      irradianceTexels[to] = irradianceTexels[from];
      irradianceTexels[to + 1] = irradianceTexels[from + 1];
      irradianceTexels[to + 2] = irradianceTexels[from + 2];
    } else if (channel == 1) {
      int from = pcDepthIndex(o + src), to = pcDepthIndex(o + bxy);
      depthTexels[to] = depthTexels[from];
      depthTexels[to + 1] = depthTexels[from + 1];
    } else {
      occlusionTexels[pcOcclusionIndex(o + bxy)] = occlusionTexels[pcOcclusionIndex(o + src)];
    }
  }
  if (tid == 0) changes[request] = uintBitsToFloat(sMaxChange);
}
