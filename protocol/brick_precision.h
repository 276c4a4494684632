// Coarser precision for a brick's codes: the quality ladder's other half (StreamSender). A
// client whose link cannot carry every change at full precision is sent versions rounded to
// fewer bits, which leaves most codes of a residual unchanged from what it holds (ray noise
// stays below one coarse step) and costs less per code that does change. A coarse brick is
// an ordinary QuantizedBrick: the receiver decodes and applies it as any other, and records the
// precision the update names, since a residual must be built on exactly the codes it holds.
// PROTOCOL.md ("Precision levels") states the bounds below.
//
// Beyond the ladder's levels lies the sync level, the form a client is first sent a brick in:
// its depth moments (three quarters of a brick's bytes) at a quarter of the resolution per
// axis, so that a client holds a usable whole field within a second of joining, and is
// refined to the ladder's level afterwards with what room the link has.
#pragma once

#include <cstdint>

#include "protocol/brick_codec.h"

namespace pc {

// Precision 0 is the codec's own; each level up drops bits, up to this level.
inline constexpr int kMaxLadderPrecision = 4;
// The first-sync form (protocol version 9), coarser than every ladder level: the coarsest
// level on the wire.
inline constexpr int kSyncPrecision = 5;
inline constexpr int kMaxPrecision = kSyncPrecision;

// The sync level's form. Depth: each kSyncDepthBlock x kSyncDepthBlock block of a probe's depth
// tile holds one direction's moments, merged as a mip level merges them (the block's mean,
// and the standard deviation of the block's distances: its texels' variances plus the spread
// of their means), then kSyncDepthDropBits dropped. Irradiance is rounded as at ladder level
// kSyncIrradianceLevel, occlusion as at kSyncOcclusionLevel; offsets and states stay exact.
inline constexpr int kSyncDepthBlock = 4;
inline constexpr int kSyncDepthDropBits = 6;
inline constexpr int kSyncIrradianceLevel = 1;
inline constexpr int kSyncOcclusionLevel = 3;

// Bits dropped at `precision`, per section. Irradiance: the gamma-encoded e is already a
// perceptual value, so level L rounds every code to a step of at most 2^(L-8) in e (1/128 at
// level 1 .. 1/16 at level 4), never more than kMaxIrradianceDropBits of its 7 mantissa bits:
// a dim texel loses more bits than a bright one, and the error of level L is within 2^(L-9)
// everywhere (a PSNR of the gamma-encoded field of at least 53, 47, 41 and 35 dB). Depth
// moments drop 2 bits a level, at most 6 (1/2048 of the ray distance); occlusion one a level,
// at most 3 (1/64). Relocation offsets and probe states are never rounded: they move the
// sampled positions and switch probes on and off. The sync level: see above.
inline constexpr int kMaxIrradianceDropBits = 5;
int droppedIrradianceBits(int precision, std::uint16_t code);
int droppedDepthBits(int precision);
int droppedOcclusionBits(int precision);

// `q` rounded to `precision` (0 or out of range below: `q` unchanged; above kMaxPrecision:
// kMaxPrecision). Each code is rounded to the nearest multiple of 2^dropped within its range
// (idempotent); zero stays zero; at the sync level depth is merged into blocks first. The
// sender always coarsens a version's exact codes, never codes already coarsened, so a level's
// content is one function of the version.
QuantizedBrick coarsenBrick(const QuantizedBrick& q, int precision);

}  // namespace pc
