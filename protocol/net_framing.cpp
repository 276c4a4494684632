#include "net_framing.h"

#include <cstring>
#include <string>

namespace pc {

namespace {
// Root offset (4 bytes) and identifier (4 bytes) follow the prefix.
constexpr std::size_t kMinFrameBytes = kFramePrefixBytes + 8;
}  // namespace

Result<std::size_t> frameSize(std::span<const std::uint8_t> prefix, std::size_t maxBytes) {
  if (prefix.size() < kFramePrefixBytes) return Error{"frame prefix truncated"};
  const std::size_t body = std::size_t(prefix[0]) | std::size_t(prefix[1]) << 8 |
                           std::size_t(prefix[2]) << 16 | std::size_t(prefix[3]) << 24;
  const std::size_t total = kFramePrefixBytes + body;
  if (total > maxBytes) {
    return Error{"frame of " + std::to_string(total) + " bytes exceeds the limit of " +
                 std::to_string(maxBytes)};
  }
  if (total < kMinFrameBytes)
    return Error{"frame of " + std::to_string(total) + " bytes is too short"};
  return total;
}

FrameKind classifyFrame(std::span<const std::uint8_t> frame) {
  if (frame.size() < kMinFrameBytes) return FrameKind::Unknown;
  const std::uint8_t* id = frame.data() + 8;
  if (std::memcmp(id, "PCSM", 4) == 0) return FrameKind::SessionMessage;
  if (std::memcmp(id, "PCDG", 4) == 0) return FrameKind::Datagram;
  return FrameKind::Unknown;
}

std::vector<std::uint8_t> datagramFrame(std::span<const std::uint8_t> datagram) {
  std::vector<std::uint8_t> frame(kFramePrefixBytes + datagram.size());
  const std::uint32_t n = std::uint32_t(datagram.size());
  for (int i = 0; i < 4; ++i) frame[i] = std::uint8_t(n >> (8 * i));
  std::memcpy(frame.data() + kFramePrefixBytes, datagram.data(), datagram.size());
  return frame;
}

}  // namespace pc
