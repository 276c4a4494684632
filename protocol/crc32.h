// CRC-32 (the IEEE 802.3 / zlib polynomial, reflected): the per-datagram checksum. UDP's own
// checksum is optional over IPv4 and weak; this one catches corruption on any link.
#pragma once

#include <cstdint>
#include <span>

namespace pc {

std::uint32_t crc32(std::span<const std::uint8_t> bytes, std::uint32_t crc = 0);

}  // namespace pc
