// Probe math shared by the Embree path, the CPU renders and the shaders: octahedral mapping,
// ray directions, probe and brick indexing, atlas addressing and tile borders.
#ifndef PC_PROBE_MATH_H
#define PC_PROBE_MATH_H

#include "field_desc.h"

PC_BEGIN

// ---- octahedral mapping ------------------------------------------------------------------
// Unit direction <-> point of [-1,1]^2. The +z hemisphere maps to the inner diamond.

PC_FN float pcSignNotZero(float v) { return v >= 0.0f ? 1.0f : -1.0f; }

PC_FN vec2 pcOctEncode(vec3 n) {
  float l1 = abs(n.x) + abs(n.y) + abs(n.z);
  vec2 uv = vec2(n.x / l1, n.y / l1);
  if (n.z < 0.0f) {
    uv = vec2((1.0f - abs(uv.y)) * pcSignNotZero(uv.x), (1.0f - abs(uv.x)) * pcSignNotZero(uv.y));
  }
  return uv;
}

PC_FN vec3 pcOctDecode(vec2 uv) {
  vec3 n = vec3(uv.x, uv.y, 1.0f - abs(uv.x) - abs(uv.y));
  if (n.z < 0.0f) {
    n = vec3((1.0f - abs(uv.y)) * pcSignNotZero(uv.x), (1.0f - abs(uv.x)) * pcSignNotZero(uv.y),
             n.z);
  }
  return normalize(n);
}

// Direction through the centre of interior texel (tx, ty) of an n x n tile.
PC_FN vec3 pcTexelDirection(int tx, int ty, int n) {
  vec2 uv = vec2((float(tx) + 0.5f) / float(n), (float(ty) + 0.5f) / float(n));
  return pcOctDecode(vec2(uv.x * 2.0f - 1.0f, uv.y * 2.0f - 1.0f));
}

// Continuous texel coordinate (texel centres at k + 0.5) inside a bordered tile of n interior
// texels for direction d: the value to sample bilinearly, in [1, n + 1].
PC_FN vec2 pcTileCoord(vec3 d, int n) {
  vec2 uv = pcOctEncode(d);
  return vec2(1.0f + (uv.x * 0.5f + 0.5f) * float(n), 1.0f + (uv.y * 0.5f + 0.5f) * float(n));
}

// The interior texel a border texel copies, for a tile of n interior texels with a 1-texel
// border: (bx, by) in [0, n+1]^2 on the border; returns interior coordinates in [0, n-1]^2.
// Edges mirror (the octahedral fold), corners take the diagonally opposite interior corner.
PC_FN ivec2 pcBorderSource(int bx, int by, int n) {
  bool left = bx == 0, right = bx == n + 1, top = by == 0, bottom = by == n + 1;
  if ((left || right) && (top || bottom)) {
    return ivec2(left ? n - 1 : 0, top ? n - 1 : 0);
  }
  if (top || bottom) return ivec2(n - bx, top ? 0 : n - 1);
  return ivec2(left ? 0 : n - 1, n - by);
}

// ---- ray directions ------------------------------------------------------------------------

// Spherical Fibonacci point i of count: near-uniform, deterministic directions.
PC_FN vec3 pcFibonacciDirection(int i, int count) {
  const float goldenFrac = 0.61803398875f;  // fractional part of the golden ratio
  float k = float(i) * goldenFrac;
  float phi = 2.0f * PC_PI * (k - floor(k));
  float cosTheta = 1.0f - (2.0f * float(i) + 1.0f) / float(count);
  float sinTheta = sqrt(clamp(1.0f - cosTheta * cosTheta, 0.0f, 1.0f));
  return vec3(cos(phi) * sinTheta, sin(phi) * sinTheta, cosTheta);
}

// PCG hash: well-mixed 32-bit values from a counter, the same on CPU and GPU.
PC_FN uint pcHash(uint v) {
  uint state = v * 747796405u + 2891336453u;
  uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
  return (word >> 22u) ^ word;
}
PC_FN float pcHashToFloat(uint h) { return float(h >> 8u) * (1.0f / 16777216.0f); }

// The first state of a probe ray's random stream in a field update: `seed` the update's
// rotation seed, `rayIndex` = request index x rays per probe + ray. Each draw hashes the state
// again (pcHash) and maps it with pcHashToFloat. Both backends shade a ray with this stream
// (probe_shade.comp, server/embree_tracer.cpp), so they sample the same points on emitters.
PC_FN uint pcRayRandomSeed(uint seed, uint rayIndex) {
  return pcHash(seed * 0x9E3779B9u ^ pcHash(rayIndex));
}

// Rec. 709 luminance of linear RGB.
PC_FN float pcLuminance(vec3 c) { return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z; }

// Uniformly random rotation (Shoemake's quaternion method) from a seed; one per update so
// the fixed Fibonacci set covers the sphere over time.
PC_FN mat3 pcRandomRotation(uint seed) {
  float u1 = pcHashToFloat(pcHash(seed * 3u + 0u));
  float u2 = pcHashToFloat(pcHash(seed * 3u + 1u));
  float u3 = pcHashToFloat(pcHash(seed * 3u + 2u));
  float a = sqrt(1.0f - u1), b = sqrt(u1);
  float qx = a * sin(2.0f * PC_PI * u2), qy = a * cos(2.0f * PC_PI * u2);
  float qz = b * sin(2.0f * PC_PI * u3), qw = b * cos(2.0f * PC_PI * u3);
  // Column-major, as GLSL and GLM both store it.
  return mat3(vec3(1.0f - 2.0f * (qy * qy + qz * qz), 2.0f * (qx * qy + qz * qw),
                   2.0f * (qx * qz - qy * qw)),
              vec3(2.0f * (qx * qy - qz * qw), 1.0f - 2.0f * (qx * qx + qz * qz),
                   2.0f * (qy * qz + qx * qw)),
              vec3(2.0f * (qx * qz + qy * qw), 2.0f * (qy * qz - qx * qw),
                   1.0f - 2.0f * (qx * qx + qy * qy)));
}

// ---- probe and brick indexing --------------------------------------------------------------

PC_FN ivec3 pcWrap(ivec3 v, ivec3 n) {
  return ivec3(((v.x % n.x) + n.x) % n.x, ((v.y % n.y) + n.y) % n.y, ((v.z % n.z) + n.z) % n.z);
}

// Logical grid coordinate -> physical storage coordinate (toroidal scroll). Both the
// coordinate and the scroll lie in [0, counts), so one conditional subtraction wraps: this runs
// for every probe of every cage, and integer division by a variable is slow on every processor.
PC_FN int pcWrapOnce(int v, int n) { return v >= n ? v - n : v; }
PC_FN ivec3 pcPhysicalCoord(PC_IN(CascadeDesc) c, ivec3 logical) {
  ivec3 v = logical + c.scroll;
  return ivec3(pcWrapOnce(v.x, c.counts.x), pcWrapOnce(v.y, c.counts.y),
               pcWrapOnce(v.z, c.counts.z));
}
PC_FN ivec3 pcLogicalCoord(PC_IN(CascadeDesc) c, ivec3 physical) {
  ivec3 v = physical - c.scroll + c.counts;
  return ivec3(pcWrapOnce(v.x, c.counts.x), pcWrapOnce(v.y, c.counts.y),
               pcWrapOnce(v.z, c.counts.z));
}

// Physical coordinate -> index within the cascade. Probes are stored brick by brick so a
// brick's probes are contiguous (one range to read, upload or send).
PC_FN ivec3 pcBrickCounts(PC_IN(CascadeDesc) c) {
  return ivec3((c.counts.x + PC_BRICK_SIZE - 1) / PC_BRICK_SIZE,
               (c.counts.y + PC_BRICK_SIZE - 1) / PC_BRICK_SIZE,
               (c.counts.z + PC_BRICK_SIZE - 1) / PC_BRICK_SIZE);
}
PC_FN int pcBrickCount(PC_IN(CascadeDesc) c) {
  ivec3 b = pcBrickCounts(c);
  return b.x * b.y * b.z;
}
PC_FN int pcBrickIndex(PC_IN(CascadeDesc) c, ivec3 physical) {
  ivec3 b = pcBrickCounts(c);
  ivec3 bc = physical / PC_BRICK_SIZE;
  return bc.x + b.x * (bc.y + b.y * bc.z);
}
PC_FN ivec3 pcBrickCoord(PC_IN(CascadeDesc) c, int brick) {
  ivec3 b = pcBrickCounts(c);
  return ivec3(brick % b.x, (brick / b.x) % b.y, brick / (b.x * b.y));
}
PC_CONST int PC_PROBES_PER_BRICK = PC_BRICK_SIZE * PC_BRICK_SIZE * PC_BRICK_SIZE;
// Slot index of a probe inside the cascade: brick * 64 + position in brick. Slots of bricks
// that overhang the grid edge are allocated but never hold a probe.
PC_FN int pcProbeSlot(PC_IN(CascadeDesc) c, ivec3 physical) {
  ivec3 inb = physical - (physical / PC_BRICK_SIZE) * PC_BRICK_SIZE;
  return pcBrickIndex(c, physical) * PC_PROBES_PER_BRICK + inb.x +
         PC_BRICK_SIZE * (inb.y + PC_BRICK_SIZE * inb.z);
}
PC_FN ivec3 pcSlotCoord(PC_IN(CascadeDesc) c, int slot) {
  ivec3 bc = pcBrickCoord(c, slot / PC_PROBES_PER_BRICK);
  int s = slot % PC_PROBES_PER_BRICK;
  return bc * PC_BRICK_SIZE + ivec3(s % PC_BRICK_SIZE, (s / PC_BRICK_SIZE) % PC_BRICK_SIZE,
                                    s / (PC_BRICK_SIZE * PC_BRICK_SIZE));
}
PC_FN int pcSlotCount(PC_IN(CascadeDesc) c) { return pcBrickCount(c) * PC_PROBES_PER_BRICK; }
PC_FN bool pcSlotValid(PC_IN(CascadeDesc) c, int slot) {
  ivec3 p = pcSlotCoord(c, slot);
  return p.x < c.counts.x && p.y < c.counts.y && p.z < c.counts.z;
}

// World position of a probe's grid point (before relocation).
PC_FN vec3 pcProbeGridPosition(PC_IN(CascadeDesc) c, ivec3 logical) {
  return c.origin + vec3(logical) * c.spacing;
}

// Where a probe's rays start, as a share of the spacing past the probe. A grid aligned with the
// walls puts whole rows of probes on their planes, and a ray from a point on a plane hits it at
// t = 0 or misses it as the tracer's rounding falls: Embree and the GPU then saw different
// surfaces, and classified and relocated those probes differently. Past this distance, the
// plane a probe sits on is never hit; a probe this close to a surface counts as on it.
PC_CONST float PC_PROBE_RAY_NEAR = 1e-3f;
PC_FN float pcProbeRayNear(PC_IN(CascadeDesc) c) { return PC_PROBE_RAY_NEAR * c.spacing; }

// Where a probe ray's hit sends its shadow rays from: off the surface along the geometric
// normal (on the side the probe ray came from) by 16 float steps of the largest coordinate of
// the triangle's corners. The hit point's rounding and a tracer's ray-triangle test both err in
// proportion to the coordinates involved, and NVIDIA's test errs more than Embree's: on the
// ground of rtxgi-tunnel (two triangles 870 units across), shadow rays from the hit point
// itself, stopped only by a near distance of 1e-4, found their own triangle on the GPU, and
// its field came out 1.7% darker than Embree's. Only the shadow rays leave from here; the
// lights are evaluated at the hit point. Far fewer steps would not clear the test's error; far
// more skip nearby occluders: the built-in room 3000 units from the origin comes out 0.2%
// darker than at the origin (test RoomFarFromTheOriginLightsAsAtTheOrigin), and with 256
// steps, the lights evaluated there too, it was 17% brighter.
PC_CONST float PC_SHADOW_ORIGIN_OFFSET = 1.0f / 524288.0f;
PC_CONST float PC_SHADOW_ORIGIN_MIN_OFFSET = 1.0f / 65536.0f;  // near the world's origin
PC_FN float pcTriangleExtent(vec3 p0, vec3 p1, vec3 p2) {
  vec3 m = max(abs(p0), max(abs(p1), abs(p2)));
  return max(m.x, max(m.y, m.z));
}
PC_FN vec3 pcShadowOrigin(vec3 P, vec3 geometricNormal, float extent) {
  return P + geometricNormal * max(PC_SHADOW_ORIGIN_MIN_OFFSET, extent * PC_SHADOW_ORIGIN_OFFSET);
}

// ---- atlas addressing -------------------------------------------------------------------------
// Every channel's atlas holds one bordered tile per probe slot, PC_ATLAS_TILES_PER_ROW tiles per
// row; cascade k starts at tile row c.atlasTileRow. Tile size = interior texels + 2.

PC_FN int pcAtlasTileRows(int slotCount) {
  return (slotCount + PC_ATLAS_TILES_PER_ROW - 1) / PC_ATLAS_TILES_PER_ROW;
}
// Pixel origin (top-left border texel) of a slot's tile in an atlas of tiles of `tileSize`.
PC_FN ivec2 pcAtlasTileOrigin(PC_IN(CascadeDesc) c, int slot, int tileSize) {
  return ivec2((slot % PC_ATLAS_TILES_PER_ROW) * tileSize,
               (c.atlasTileRow + slot / PC_ATLAS_TILES_PER_ROW) * tileSize);
}

PC_END

#endif
