// CRC-64/XZ (the ECMA-182 polynomial, reflected; as xz and Go's crc64.ECMA compute it): the
// whole-file checksum of baked field files. Catches every error burst of up to 64 bits and all
// but 2^-64 of the rest, where a 32-bit sum over a large file would miss one in four billion.
#pragma once

#include <cstdint>
#include <span>

namespace pc {

// `crc` continues an earlier call's result over the bytes that followed it (0 to start).
std::uint64_t crc64(std::span<const std::uint8_t> bytes, std::uint64_t crc = 0);

}  // namespace pc
