#include "crc64.h"

#include <array>

namespace pc {

namespace {

// One byte at a time from a table built at compile time: baked files are read once, so the
// simple loop (several hundred MB/s) is fast enough.
constexpr std::array<std::uint64_t, 256> makeTable() {
  std::array<std::uint64_t, 256> t{};
  for (std::uint64_t i = 0; i < 256; ++i) {
    std::uint64_t c = i;
    for (int k = 0; k < 8; ++k) c = (c & 1u) ? 0xC96C5795D7870F42ull ^ (c >> 1) : c >> 1;
    t[i] = c;
  }
  return t;
}
constexpr std::array<std::uint64_t, 256> kTable = makeTable();

}  // namespace

std::uint64_t crc64(std::span<const std::uint8_t> bytes, std::uint64_t crc) {
  crc = ~crc;
  for (std::uint8_t b : bytes) crc = kTable[(crc ^ b) & 0xFFu] ^ (crc >> 8);
  return ~crc;
}

}  // namespace pc
