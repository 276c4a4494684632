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

// Bits dropped at `precision`, per section. Irradiance keeps at least 4 of its 7 mantissa bits
// (relative error within 1/32 at the last level, about 41 dB of the held-field PSNR); depth
// moments drop 2 bits a level, at most 6 (1/2048 of the ray distance); occlusion one a level,
// at most 3 (1/64). Relocation offsets and probe states are never rounded: they move the
// sampled positions and switch probes on and off.
int droppedIrradianceBits(int precision);
int droppedDepthBits(int precision);
int droppedOcclusionBits(int precision);

// `q` rounded to `precision` (0 or out of range below: `q` unchanged; above kMaxPrecision:
// kMaxPrecision). Each code is rounded to the nearest multiple of 2^dropped within its range
// (idempotent); zero stays zero. The sender always coarsens a version's exact codes, never
// codes already coarsened, so a level's content is one function of the version.
QuantizedBrick coarsenBrick(const QuantizedBrick& q, int precision);

}  // namespace pc
