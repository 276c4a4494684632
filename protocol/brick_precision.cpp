#include "brick_precision.h"

#include <algorithm>

namespace pc {

namespace {

using namespace brick_layout;

// `c` rounded to the nearest multiple of 2^bits, never above the largest multiple within
// maxCode; zero stays zero (irradiance: no light).
std::uint16_t roundCode(std::uint16_t c, int bits, std::uint32_t maxCode) {
  if (bits <= 0 || c == 0) return c;
  const std::uint32_t rounded = ((std::uint32_t(c) + (1u << (bits - 1))) >> bits) << bits;
  return std::uint16_t(std::min(rounded, (maxCode >> bits) << bits));
}

// Rounds each code in [begin, end) to `bits` dropped bits.
void roundCodes(QuantizedBrick& q, std::size_t begin, std::size_t end, int bits,
                std::uint32_t maxCode) {
  for (std::size_t i = begin; i < end; ++i) q.codes[i] = roundCode(q.codes[i], bits, maxCode);
}

}  // namespace

int droppedIrradianceBits(int precision, std::uint16_t code) {
  if (code == 0 || precision <= 0) return 0;
  // The code's exponent slot s holds e in [2^(s-16), 2^(s-15)), where one mantissa step is
  // 2^(s-23); 2^d steps stay within the level's step 2^(L-8) while d <= L + 15 - s.
  const int slot = code >> kIrradianceMantissaBits;
  return std::clamp(std::min(precision, kMaxPrecision) + 15 - slot, 0, kMaxIrradianceDropBits);
}
int droppedDepthBits(int precision) { return std::clamp(2 * precision, 0, 6); }
int droppedOcclusionBits(int precision) { return std::clamp(precision, 0, 3); }

QuantizedBrick coarsenBrick(const QuantizedBrick& q, int precision) {
  QuantizedBrick out = q;
  precision = std::min(precision, kMaxPrecision);
  if (precision <= 0 || out.codes.size() != kCodes) return out;
  // The irradiance code is a float (exponent over mantissa), so rounding the integer rounds the
  // mantissa and carries into the exponent (to a code whose mantissa is 0, which rounding
  // again leaves as it is); its largest code has every bit set.
  for (std::size_t i = kIrradiance; i < kDepth; ++i) {
    std::uint16_t& c = out.codes[i];
    c = roundCode(c, droppedIrradianceBits(precision, c), 0xFFF);
  }
  roundCodes(out, kDepth, kOcclusion, droppedDepthBits(precision), 0xFFFF);
  roundCodes(out, kOcclusion, kOffset, droppedOcclusionBits(precision), 0xFF);
  return out;
}

}  // namespace pc
