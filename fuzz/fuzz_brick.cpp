// Brick payloads (protocol/brick_codec.h): decodeBrick on any bytes returns a brick whose codes
// are all in range, or an Error. The first input byte picks how the rest is used:
//   bit 0 clear: the rest is a payload, as received;
//   bit 0 set:   the rest is raw code planes (zero-padded), compressed here into a payload with
//                a valid header and zstd frame, so that mutations reach the code checks.
//   bit 1:       decode as a residual against a fixed base brick (the header's flag follows
//                in the second mode).
//   bit 2:       apply the decoded brick to a brick of the coarse cascade, whose padding slots
//                lie outside the grid, rather than to the fine cascade's first brick.
// A decoded brick is applied to a field, which must then pass validateField, and survives
// re-encoding unchanged.
#include <zstd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "fuzz_support.h"
#include "protocol/baked_file.h"

namespace {

using namespace pc;

constexpr std::size_t kRawBytes = brick_layout::kCodes * 2;

// 'Q' 'Z', format 2, flags, then one zstd frame with its content size and checksum
// (PROTOCOL.md, "Brick codec").
std::vector<std::uint8_t> sealPayload(std::span<const std::uint8_t> planes, bool residual) {
  std::vector<std::uint8_t> raw(kRawBytes, 0);
  for (std::size_t i = 0; i < planes.size() && i < kRawBytes; ++i) raw[i] = planes[i];
  std::vector<std::uint8_t> out(4 + ZSTD_compressBound(kRawBytes));
  out[0] = 'Q';
  out[1] = 'Z';
  out[2] = 1;
  out[3] = residual ? 1 : 0;
  static ZSTD_CCtx* const cctx = ZSTD_createCCtx();  // reused: creating one costs more
  ZSTD_CCtx_setParameter(cctx, ZSTD_c_compressionLevel, 1);
  ZSTD_CCtx_setParameter(cctx, ZSTD_c_checksumFlag, 1);
  ZSTD_CCtx_setParameter(cctx, ZSTD_c_contentSizeFlag, 1);
  const std::size_t n =
      ZSTD_compress2(cctx, out.data() + 4, out.size() - 4, raw.data(), raw.size());
  if (ZSTD_isError(n)) std::abort();
  out.resize(4 + n);
  return out;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const std::uint8_t mode = data[0];
  const std::span<const std::uint8_t> rest(data + 1, size - 1);
  const QuantizedBrick* base = (mode & 2) ? &fuzz::baseBrick() : nullptr;

  std::vector<std::uint8_t> sealed;
  std::span<const std::uint8_t> payload = rest;
  if (mode & 1) {
    sealed = sealPayload(rest, base != nullptr);
    payload = sealed;
  }
  Result<QuantizedBrick> q = decodeBrick(payload, base);
  if (!q) return 0;
  if (q->codes.size() != brick_layout::kCodes) std::abort();

  static Field field = fuzz::smallField(2);
  const int cascade = (mode & 4) ? 1 : 0;
  applyBrick(field, cascade, 0, q.value());
  if (Status s = validateField(field); !s) {
    std::fprintf(stderr, "applied brick leaves an invalid field: %s\n", s.error().message.c_str());
    std::abort();
  }
  // The codec is lossless on codes.
  Result<QuantizedBrick> again = decodeBrick(encodeBrick(q.value(), base, 1), base);
  if (!again || !(again.value() == q.value())) std::abort();
  return 0;
}
