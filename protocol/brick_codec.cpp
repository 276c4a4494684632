// The QuantZstd brick codec: quantization, prediction, byte planes, zstd (PROTOCOL.md, "Brick
// codec").
#include "brick_codec.h"

#include <zstd.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <memory>
#include <string>

#include "common/field_scroll.h"

namespace pc {

namespace {

using namespace pc::gpu;
using namespace brick_layout;

// Payload header: magic "QZ", format 2, flags (bit 0: residual; bit 1, protocol version 9: the
// layout stamp follows, three little-endian float32: the cascade's origin). Format 1
// (protocol version 1) had 9 irradiance mantissa bits.
constexpr std::uint8_t kMagic0 = 'Q', kMagic1 = 'Z', kFormat = 2, kFlagResidual = 1,
                       kFlagOrigin = 2;
constexpr std::size_t kHeaderBytes = 4, kOriginBytes = 12;
constexpr std::size_t kRawBytes = kCodes * 2;

// Irradiance mini-float: float bits rounded to kIrradianceMantissaBits mantissa bits; exponent
// slots 1..31 cover e in [2^-15, 2^16); slot 0 is zero.
constexpr int kDroppedBits = 23 - kIrradianceMantissaBits;
constexpr std::uint32_t kExponentOffset = 127 - 16;  // float exponent of slot 0
constexpr std::uint16_t kMaxIrradianceCode = (32u << kIrradianceMantissaBits) - 1;
constexpr std::uint16_t kMaxOcclusionCode = 255;
constexpr std::uint16_t kMaxStateCode = PC_PROBE_UNINITIALIZED;

std::uint16_t unitCode(float v, float scale, std::uint16_t maxCode) {
  if (!(v > 0.0f)) return 0;  // also NaN
  float x = std::min(v * scale, 1.0f);
  return std::uint16_t(std::lround(x * float(maxCode)));
}

std::uint16_t offsetCode(float v, float spacing) {
  float x = std::isfinite(v) ? std::clamp(v / spacing, -1.0f, 1.0f) : 0.0f;
  return std::uint16_t(32768 + std::lround(x * 32767.0f));
}
float offsetValue(std::uint16_t code, float spacing) {
  return float(int(code) - 32768) / 32767.0f * spacing;
}

// Slot -> tile origin of its interior texels in an atlas with bordered tiles of n + 2.
glm::ivec2 interiorOrigin(const CascadeDesc& c, int slot, int n) {
  return pcAtlasTileOrigin(c, slot, n + 2) + glm::ivec2(1);
}

std::uint16_t zigzag(std::uint16_t d) {
  auto s = std::int16_t(d);
  return std::uint16_t((std::uint16_t(s) << 1) ^ std::uint16_t(s >> 15));
}
std::uint16_t unzigzag(std::uint16_t z) {
  return std::uint16_t((z >> 1) ^ std::uint16_t(-std::int16_t(z & 1)));
}

// Spatial prediction for self-contained bricks. A plane of tiles (n x n texels each):
// predict a texel from its left neighbour, the first of a row from the one above, the first of
// a tile from the previous tile's first. Sequences of per-slot values: the previous value.
template <typename F>
void forEachPrediction(F&& f) {
  auto tiles = [&](std::size_t start, int planes, int n) {
    for (int p = 0; p < planes; ++p) {
      const std::size_t plane = start + std::size_t(p) * kSlots * n * n;
      for (int s = 0; s < kSlots; ++s) {
        const std::size_t tile = plane + std::size_t(s) * n * n;
        for (int y = 0; y < n; ++y) {
          for (int x = 0; x < n; ++x) {
            const std::size_t i = tile + std::size_t(y) * n + x;
            std::size_t pred;
            if (x > 0)
              pred = i - 1;
            else if (y > 0)
              pred = i - n;
            else if (s > 0)
              pred = tile - std::size_t(n) * n;
            else
              pred = i;  // first of the plane: predicted by 0 (see below)
            f(i, pred);
          }
        }
      }
    }
  };
  tiles(kIrradiance, 3, PC_IRRADIANCE_TEXELS);
  tiles(kDepth, 2, PC_DEPTH_TEXELS);
  tiles(kOcclusion, 1, PC_OCCLUSION_TEXELS);
  for (std::size_t plane = kOffset; plane < kCodes; plane += kSlots) {
    for (int s = 0; s < kSlots; ++s) f(plane + s, s > 0 ? plane + s - 1 : plane + s);
  }
}

struct CCtxDeleter {
  void operator()(ZSTD_CCtx* c) const { ZSTD_freeCCtx(c); }
};
struct DCtxDeleter {
  void operator()(ZSTD_DCtx* c) const { ZSTD_freeDCtx(c); }
};

Error fail(const std::string& what) { return Error{"brick payload: " + what}; }

}  // namespace

std::uint16_t quantizeIrradiance(float e) {
  if (!(e > 0.0f)) return 0;  // negative, zero, NaN
  if (!std::isfinite(e)) return kMaxIrradianceCode;
  // Rounding the bit pattern rounds the mantissa to nearest and carries into the exponent.
  const std::uint32_t bits = std::bit_cast<std::uint32_t>(e);
  const std::uint32_t rounded = (bits + (1u << (kDroppedBits - 1))) >> kDroppedBits;
  const std::uint32_t minCode = 1u << kIrradianceMantissaBits;  // 2^-15
  const std::uint32_t base = kExponentOffset << kIrradianceMantissaBits;
  if (rounded < base + minCode) {
    // Below 2^-15: zero or the smallest value, whichever is nearer.
    return e >= 0.5f * std::ldexp(1.0f, -15) ? std::uint16_t(minCode) : 0;
  }
  return std::uint16_t(std::min<std::uint32_t>(rounded - base, kMaxIrradianceCode));
}

float dequantizeIrradiance(std::uint16_t code) {
  if (code == 0) return 0.0f;
  const std::uint32_t c = std::min<std::uint32_t>(code, kMaxIrradianceCode);
  return std::bit_cast<float>((c + (kExponentOffset << kIrradianceMantissaBits)) << kDroppedBits);
}

QuantizedBrick quantizeBrick(const Field& field, int cascade, int brick) {
  const CascadeDesc& c = field.cascade(cascade);
  const float depthScale = c.maxRayDistance > 0.0f ? 1.0f / c.maxRayDistance : 0.0f;
  QuantizedBrick q;
  q.codes.assign(kCodes, 0);
  if (c.follows != 0) q.origin = c.origin;
  std::uint16_t* out = q.codes.data();
  for (int s = 0; s < kSlots; ++s) {
    const int slot = brick * kSlots + s;
    {
      constexpr int n = PC_IRRADIANCE_TEXELS;
      const glm::ivec2 o = interiorOrigin(c, slot, n);
      for (int y = 0; y < n; ++y) {
        for (int x = 0; x < n; ++x) {
          const float* t = field.irradiance.at(o.x + x, o.y + y);
          for (int ch = 0; ch < 3; ++ch) {
            out[kIrradiance + (std::size_t(ch) * kSlots + s) * kIrrTexels + y * n + x] =
                quantizeIrradiance(t[ch]);
          }
        }
      }
    }
    {
      constexpr int n = PC_DEPTH_TEXELS;
      const glm::ivec2 o = interiorOrigin(c, slot, n);
      for (int y = 0; y < n; ++y) {
        for (int x = 0; x < n; ++x) {
          const float* t = field.depth.at(o.x + x, o.y + y);
          const float mean = t[0];
          // Standard deviation rather than mean square: the visibility test needs the variance,
          // which is tiny near walls and would vanish in a 16-bit mean square.
          const float sigma = std::sqrt(std::max(t[1] - mean * mean, 0.0f));
          const std::size_t i = std::size_t(s) * kDepthTexels + y * n + x;
          out[kDepth + i] = unitCode(mean, depthScale, 65535);
          out[kDepth + std::size_t(kSlots) * kDepthTexels + i] = unitCode(sigma, depthScale, 65535);
        }
      }
    }
    {
      constexpr int n = PC_OCCLUSION_TEXELS;
      const glm::ivec2 o = interiorOrigin(c, slot, n);
      for (int y = 0; y < n; ++y) {
        for (int x = 0; x < n; ++x) {
          out[kOcclusion + std::size_t(s) * kOccTexels + y * n + x] =
              unitCode(*field.occlusion.at(o.x + x, o.y + y), 1.0f, kMaxOcclusionCode);
        }
      }
    }
    const ProbeRecord& p = field.probe(cascade, slot);
    for (int a = 0; a < 3; ++a) out[kOffset + a * kSlots + s] = offsetCode(p.offset[a], c.spacing);
    out[kState + s] =
        std::uint16_t(p.state >= 0 && p.state <= kMaxStateCode ? p.state : PC_PROBE_UNINITIALIZED);
  }
  return q;
}

void applyBrick(Field& field, int cascade, int brick, const QuantizedBrick& q) {
  const CascadeDesc& c = field.cascade(cascade);
  const std::uint16_t* in = q.codes.data();
  const float depthStep = c.maxRayDistance / 65535.0f;
  for (int s = 0; s < kSlots; ++s) {
    const int slot = brick * kSlots + s;
    {
      constexpr int n = PC_IRRADIANCE_TEXELS;
      const glm::ivec2 o = interiorOrigin(c, slot, n);
      for (int y = 0; y < n; ++y) {
        for (int x = 0; x < n; ++x) {
          float* t = field.irradiance.at(o.x + x, o.y + y);
          for (int ch = 0; ch < 3; ++ch) {
            t[ch] = dequantizeIrradiance(
                in[kIrradiance + (std::size_t(ch) * kSlots + s) * kIrrTexels + y * n + x]);
          }
        }
      }
    }
    {
      constexpr int n = PC_DEPTH_TEXELS;
      const glm::ivec2 o = interiorOrigin(c, slot, n);
      for (int y = 0; y < n; ++y) {
        for (int x = 0; x < n; ++x) {
          const std::size_t i = std::size_t(s) * kDepthTexels + y * n + x;
          const float mean = float(in[kDepth + i]) * depthStep;
          const float sigma =
              float(in[kDepth + std::size_t(kSlots) * kDepthTexels + i]) * depthStep;
          float* t = field.depth.at(o.x + x, o.y + y);
          t[0] = mean;
          t[1] = mean * mean + sigma * sigma;
        }
      }
    }
    {
      constexpr int n = PC_OCCLUSION_TEXELS;
      const glm::ivec2 o = interiorOrigin(c, slot, n);
      for (int y = 0; y < n; ++y) {
        for (int x = 0; x < n; ++x) {
          *field.occlusion.at(o.x + x, o.y + y) =
              float(in[kOcclusion + std::size_t(s) * kOccTexels + y * n + x]) / 255.0f;
        }
      }
    }
    field.fixBorders(cascade, slot);
  }
  applyBrickRecords(field, cascade, brick, q);
}

void applyBrickRecords(Field& field, int cascade, int brick, const QuantizedBrick& q) {
  const CascadeDesc& c = field.cascade(cascade);
  const std::uint16_t* in = q.codes.data();
  for (int s = 0; s < kSlots; ++s) {
    const int slot = brick * kSlots + s;
    ProbeRecord& p = field.probe(cascade, slot);
    p.updates = 0;
    if (q.origin && !slotMatchesStamp(c, *q.origin, pcSlotCoord(c, slot))) {
      // Data of another grid point: as the server's probe that scrolled in, not yet traced.
      p.offset = glm::vec3(0.0f);
      p.state = PC_PROBE_UNINITIALIZED;
      continue;
    }
    for (int a = 0; a < 3; ++a) p.offset[a] = offsetValue(in[kOffset + a * kSlots + s], c.spacing);
    p.state = int(in[kState + s]);
  }
}

BrickChange brickChange(const QuantizedBrick& a, const QuantizedBrick& b) {
  BrickChange ch;
  double sum = 0, squares = 0;
  for (std::size_t i = kIrradiance; i < kDepth; ++i) {
    if (a.codes[i] != b.codes[i]) {
      const float d = std::abs(dequantizeIrradiance(a.codes[i]) - dequantizeIrradiance(b.codes[i]));
      ch.irradiance = std::max(ch.irradiance, d);
      sum += d;
      squares += double(d) * d;
    }
  }
  ch.irradianceMean = float(sum / double(kDepth - kIrradiance));
  ch.irradianceMeanSquare = squares / double(kDepth - kIrradiance);
  int depthMax = 0;
  for (std::size_t i = kDepth; i < kDepth + std::size_t(kSlots) * kDepthTexels; ++i) {
    depthMax = std::max(depthMax, std::abs(int(a.codes[i]) - int(b.codes[i])));
  }
  ch.depth = float(depthMax) / 65535.0f;
  int occMax = 0;
  for (std::size_t i = kOcclusion; i < kOffset; ++i) {
    occMax = std::max(occMax, std::abs(int(a.codes[i]) - int(b.codes[i])));
  }
  ch.occlusion = float(occMax) / 255.0f;
  int offsetMax = 0;
  for (std::size_t i = kOffset; i < kState; ++i) {
    offsetMax = std::max(offsetMax, std::abs(int(a.codes[i]) - int(b.codes[i])));
  }
  ch.offset = float(offsetMax) / 32767.0f;
  for (std::size_t i = kState; i < kCodes; ++i) ch.states |= a.codes[i] != b.codes[i];
  // Another layout stamp moves which grid points the slots stand for: as a change of state, it
  // is never held back, or a client would hide the slots that scrolled in for good.
  ch.states |= a.origin != b.origin;
  return ch;
}

std::size_t holdSmallChanges(QuantizedBrick& q, const QuantizedBrick& previous,
                             const DeadZone& tolerance) {
  if (q.codes.size() != kCodes || previous.codes.size() != kCodes) return 0;
  std::size_t held = 0;
  if (tolerance.irradiance > 0) {
    for (std::size_t i = kIrradiance; i < kDepth; ++i) {
      std::uint16_t& c = q.codes[i];
      const std::uint16_t p = previous.codes[i];
      if (c != p &&
          std::abs(dequantizeIrradiance(c) - dequantizeIrradiance(p)) <= tolerance.irradiance) {
        c = p;
        ++held;
      }
    }
  }
  if (tolerance.depth > 0) {
    // Relative to the texel's mean distance: the visibility test compares the variance with
    // squared distances of that size, so a fixed fraction of it is equally harmless near a
    // wall and far from one.
    constexpr std::size_t kPlane = std::size_t(kSlots) * kDepthTexels;
    for (std::size_t i = 0; i < kPlane; ++i) {
      const float limit = tolerance.depth * float(q.codes[kDepth + i]);
      for (std::size_t plane : {kDepth, kDepth + kPlane}) {
        std::uint16_t& c = q.codes[plane + i];
        const std::uint16_t p = previous.codes[plane + i];
        if (c != p && float(std::abs(int(c) - int(p))) <= limit) {
          c = p;
          ++held;
        }
      }
    }
  }
  if (tolerance.occlusion > 0) {
    const int limit = int(tolerance.occlusion * float(kMaxOcclusionCode));
    for (std::size_t i = kOcclusion; i < kOffset; ++i) {
      std::uint16_t& c = q.codes[i];
      const std::uint16_t p = previous.codes[i];
      if (c != p && std::abs(int(c) - int(p)) <= limit) {
        c = p;
        ++held;
      }
    }
  }
  if (tolerance.offset > 0) {
    const int limit = int(tolerance.offset * 32767.0f);
    for (std::size_t i = kOffset; i < kState; ++i) {
      std::uint16_t& c = q.codes[i];
      const std::uint16_t p = previous.codes[i];
      // A probe that is not sampled (inside geometry, or without data) is never read by a
      // client, and an inside probe's relocation wanders every update: hold its offsets.
      const std::uint16_t state = q.codes[kState + (i - kOffset) % kSlots];
      const bool sampled = state == PC_PROBE_ACTIVE || state == PC_PROBE_SLEEPING;
      if (c != p && (!sampled || std::abs(int(c) - int(p)) <= limit)) {
        c = p;
        ++held;
      }
    }
  }
  if (tolerance.sleepingAsActive) {
    auto sampled = [](std::uint16_t s) { return s == PC_PROBE_ACTIVE || s == PC_PROBE_SLEEPING; };
    for (std::size_t i = kState; i < kCodes; ++i) {
      std::uint16_t& c = q.codes[i];
      const std::uint16_t p = previous.codes[i];
      if (c != p && sampled(c) && sampled(p)) {
        c = p;
        ++held;
      }
    }
  }
  return held;
}

std::size_t maxEncodedBrickBytes() {
  return kHeaderBytes + kOriginBytes + ZSTD_compressBound(kRawBytes);
}

std::vector<std::uint8_t> encodeBrick(const QuantizedBrick& q, const QuantizedBrick* base,
                                      int zstdLevel) {
  // Prediction residuals, zigzagged so small negative and positive values share small codes.
  std::vector<std::uint16_t> r(kCodes);
  if (base) {
    for (std::size_t i = 0; i < kCodes; ++i)
      r[i] = zigzag(std::uint16_t(q.codes[i] - base->codes[i]));
  } else {
    forEachPrediction([&](std::size_t i, std::size_t pred) {
      r[i] = zigzag(std::uint16_t(q.codes[i] - (pred == i ? 0 : q.codes[pred])));
    });
  }
  // Byte planes: the high bytes are mostly zero and compress to almost nothing together.
  std::vector<std::uint8_t> raw(kRawBytes);
  for (std::size_t i = 0; i < kCodes; ++i) {
    raw[i] = std::uint8_t(r[i] & 0xFF);
    raw[kCodes + i] = std::uint8_t(r[i] >> 8);
  }
  thread_local std::unique_ptr<ZSTD_CCtx, CCtxDeleter> cctx(ZSTD_createCCtx());
  ZSTD_CCtx_reset(cctx.get(), ZSTD_reset_session_and_parameters);
  ZSTD_CCtx_setParameter(cctx.get(), ZSTD_c_compressionLevel, zstdLevel);
  ZSTD_CCtx_setParameter(cctx.get(), ZSTD_c_checksumFlag, 1);
  ZSTD_CCtx_setParameter(cctx.get(), ZSTD_c_contentSizeFlag, 1);
  // Compress into a reused scratch buffer of compressBound, then copy out exactly the bytes
  // written. Returning the scratch buffer shrunk with resize() would keep its capacity: every
  // payload (about 4 KB for the built-in scene's bricks) would hold about 99 KB of heap for as
  // long as the encode cache keeps it, which is what made the server's memory grow by about
  // 0.9 MB per field update.
  thread_local std::vector<std::uint8_t> scratch(maxEncodedBrickBytes());
  scratch[0] = kMagic0;
  scratch[1] = kMagic1;
  scratch[2] = kFormat;
  scratch[3] = std::uint8_t((base ? kFlagResidual : 0) | (q.origin ? kFlagOrigin : 0));
  std::size_t header = kHeaderBytes;
  if (q.origin) {
    for (int a = 0; a < 3; ++a) {
      std::uint32_t bits;
      std::memcpy(&bits, &(*q.origin)[a], 4);
      for (int b = 0; b < 4; ++b) scratch[header++] = std::uint8_t(bits >> (8 * b));
    }
  }
  const std::size_t n = ZSTD_compress2(cctx.get(), scratch.data() + header, scratch.size() - header,
                                       raw.data(), raw.size());
  // Compressing into a buffer of compressBound cannot fail short of memory exhaustion.
  if (ZSTD_isError(n)) return {};
  return std::vector<std::uint8_t>(scratch.begin(), scratch.begin() + std::ptrdiff_t(header + n));
}

Result<QuantizedBrick> decodeBrick(std::span<const std::uint8_t> payload,
                                   const QuantizedBrick* base) {
  if (payload.size() < kHeaderBytes + 1) {
    return fail("truncated (" + std::to_string(payload.size()) + " bytes)");
  }
  if (payload.size() > maxEncodedBrickBytes()) {
    return fail("too large (" + std::to_string(payload.size()) + " bytes)");
  }
  if (payload[0] != kMagic0 || payload[1] != kMagic1) return fail("bad magic");
  if (payload[2] != kFormat) return fail("unknown format " + std::to_string(payload[2]));
  if ((payload[3] & ~(kFlagResidual | kFlagOrigin)) != 0) return fail("unknown flags");
  const bool residual = (payload[3] & kFlagResidual) != 0;
  std::size_t header = kHeaderBytes;
  std::optional<glm::vec3> origin;
  if ((payload[3] & kFlagOrigin) != 0) {
    if (payload.size() < kHeaderBytes + kOriginBytes + 1)
      return fail("truncated layout stamp (" + std::to_string(payload.size()) + " bytes)");
    glm::vec3 o;
    for (int a = 0; a < 3; ++a) {
      std::uint32_t bits = 0;
      for (int b = 0; b < 4; ++b) bits |= std::uint32_t(payload[header++]) << (8 * b);
      std::memcpy(&o[a], &bits, 4);
    }
    if (!std::isfinite(o.x) || !std::isfinite(o.y) || !std::isfinite(o.z))
      return fail("layout stamp is not finite");
    origin = o;
  }
  if (residual != (base != nullptr)) {
    return fail(residual ? "residual payload without a base"
                         : "self-contained payload given a base");
  }
  if (base && base->codes.size() != kCodes) return fail("base brick has the wrong size");

  const std::span<const std::uint8_t> frame = payload.subspan(header);
  const unsigned long long content = ZSTD_getFrameContentSize(frame.data(), frame.size());
  if (content == ZSTD_CONTENTSIZE_ERROR) return fail("not a zstd frame");
  if (content != kRawBytes) {
    return fail("frame announces " +
                (content == ZSTD_CONTENTSIZE_UNKNOWN ? std::string("no size")
                                                     : std::to_string(content) + " bytes") +
                ", a brick holds " + std::to_string(kRawBytes));
  }
  const std::size_t frameSize = ZSTD_findFrameCompressedSize(frame.data(), frame.size());
  if (ZSTD_isError(frameSize))
    return fail(std::string("bad zstd frame: ") + ZSTD_getErrorName(frameSize));
  if (frameSize != frame.size()) return fail("unexpected bytes after the zstd frame");

  thread_local std::unique_ptr<ZSTD_DCtx, DCtxDeleter> dctx(ZSTD_createDCtx());
  std::vector<std::uint8_t> raw(kRawBytes);
  const std::size_t n =
      ZSTD_decompressDCtx(dctx.get(), raw.data(), raw.size(), frame.data(), frame.size());
  if (ZSTD_isError(n)) return fail(std::string("zstd: ") + ZSTD_getErrorName(n));
  if (n != kRawBytes)
    return fail("decoded " + std::to_string(n) + " bytes, expected " + std::to_string(kRawBytes));

  QuantizedBrick q;
  q.origin = origin;
  q.codes.resize(kCodes);
  for (std::size_t i = 0; i < kCodes; ++i) {
    const std::uint16_t r = unzigzag(std::uint16_t(raw[i] | (raw[kCodes + i] << 8)));
    q.codes[i] = r;
  }
  if (base) {
    for (std::size_t i = 0; i < kCodes; ++i)
      q.codes[i] = std::uint16_t(base->codes[i] + q.codes[i]);
  } else {
    // Predictions come before the values they predict in forEachPrediction's order.
    forEachPrediction([&](std::size_t i, std::size_t pred) {
      if (pred != i) q.codes[i] = std::uint16_t(q.codes[i] + q.codes[pred]);
    });
  }
  // Codes out of range cannot come from an encoder; refuse them rather than clamp.
  for (std::size_t i = kIrradiance; i < kDepth; ++i) {
    if (q.codes[i] > kMaxIrradianceCode) return fail("irradiance code out of range");
  }
  for (std::size_t i = kOcclusion; i < kOffset; ++i) {
    if (q.codes[i] > kMaxOcclusionCode) return fail("occlusion code out of range");
  }
  for (std::size_t i = kOffset; i < kState; ++i) {
    if (q.codes[i] == 0) return fail("probe offset code out of range");
  }
  for (std::size_t i = kState; i < kCodes; ++i) {
    if (q.codes[i] > kMaxStateCode) return fail("probe state out of range");
  }
  return q;
}

}  // namespace pc
