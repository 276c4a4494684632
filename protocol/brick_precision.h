// Coarser precision for a brick's codes: the quality ladder's other half (StreamSender). A
// client whose link cannot carry every change at full precision is sent versions rounded to
// fewer bits, which leaves most codes of a residual unchanged from what it holds (ray noise
// stays below one coarse step) and costs less per code that does change. A coarse brick is
// an ordinary QuantizedBrick: the receiver decodes and applies it as any other, and records the
// precision the update names, since a residual must be built on exactly the codes it holds.
// PROTOCOL.md ("Precision levels") states the bounds below.
#pragma once

#include <cstdint>

#include "protocol/brick_codec.h"

namespace pc {

// Precision 0 is the codec's own; each level up drops bits, up to this level.
inline constexpr int kMaxPrecision = 4;

// Bits dropped at `precision`, per section. Irradiance: the gamma-encoded e is already a
// perceptual value, so level L rounds every code to a step of at most 2^(L-8) in e (1/128 at
// level 1 .. 1/16 at level 4), never more than kMaxIrradianceDropBits of its 7 mantissa bits:
// a dim texel loses more bits than a bright one, and the error of level L is within 2^(L-9)
// everywhere (a PSNR of the gamma-encoded field of at least 53, 47, 41 and 35 dB). Depth
// moments drop 2 bits a level, at most 6 (1/2048 of the ray distance); occlusion one a level,
// at most 3 (1/64). Relocation offsets and probe states are never rounded: they move the
// sampled positions and switch probes on and off.
inline constexpr int kMaxIrradianceDropBits = 5;
int droppedIrradianceBits(int precision, std::uint16_t code);
int droppedDepthBits(int precision);
int droppedOcclusionBits(int precision);

// `q` rounded to `precision` (0 or out of range below: `q` unchanged; above kMaxPrecision:
// kMaxPrecision). Each code is rounded to the nearest multiple of 2^dropped within its range
// (idempotent); zero stays zero. The sender always coarsens a version's exact codes, never
// codes already coarsened, so a level's content is one function of the version.
QuantizedBrick coarsenBrick(const QuantizedBrick& q, int precision);

}  // namespace pc
