// How the session's byte stream (TCP) carries two kinds of frames: session messages (a
// size-prefixed flatbuffer with identifier PCSM) and, in TCP-only mode, datagrams (the same
// 4-byte little-endian size prefix, then the datagram bytes, whose identifier PCDG sits at the
// same offset). A reader tells them apart by the identifier at bytes 8..12 of the frame. No
// sockets here: the network layers read the prefix, ask frameSize, read the rest, classify.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "common/result.h"

namespace pc {

enum class FrameKind { SessionMessage, Datagram, Unknown };

inline constexpr std::size_t kFramePrefixBytes = 4;

// Whole frame size from its first 4 bytes; an Error when it announces more than `maxBytes`
// or fewer than a flatbuffer needs.
Result<std::size_t> frameSize(std::span<const std::uint8_t> prefix, std::size_t maxBytes);
FrameKind classifyFrame(std::span<const std::uint8_t> frame);
// A datagram wrapped for the byte stream.
std::vector<std::uint8_t> datagramFrame(std::span<const std::uint8_t> datagram);
// The datagram inside a datagram frame.
inline std::span<const std::uint8_t> datagramOfFrame(std::span<const std::uint8_t> frame) {
  return frame.subspan(kFramePrefixBytes);
}

}  // namespace pc
