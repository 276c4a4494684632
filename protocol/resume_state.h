// What a client's mirror holds, in the form a Resume message carries it (protocol version 7,
// PROTOCOL.md "Resuming a session"): the identity of the field (scene hash and the field
// server run's epoch) and per brick the version held and its precision level. A client moving
// to another endpoint of the same field sends it, and that endpoint sends only what is newer.
//
// Versions travel as one zstd frame of every brick's version (little-endian uint64, in cascade
// then brick order), split into 8 byte planes (all lowest bytes first): versions of one field
// differ in their low bytes only, so the high planes compress to almost nothing. Precisions
// travel as exceptions (bricks held at a level above 0), as in an Ack.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "common/result.h"
#include "protocol/session_messages.h"

namespace pc {

// One brick as a client holds it: version 0 is nothing.
struct HeldBrick {
  std::uint64_t version = 0;
  int precision = 0;
};
// [cascade][brick]
using HeldBricks = std::vector<std::vector<HeldBrick>>;

// The Resume message for a mirror of the field (sceneHash, epoch) holding `held`.
ResumeMsg resumeMessage(std::uint64_t sceneHash, std::uint64_t epoch, const HeldBricks& held);

// What a Resume claims, laid out as a field of `bricksPerCascade` bricks per cascade. An Error
// (naming what was wrong) when the claim covers another number of bricks, the versions do not
// decompress to exactly one per brick, or a precision names a brick outside the field or a
// level past kMaxPrecision. The versions themselves are not judged here: the sender compares
// them with what it holds.
Result<HeldBricks> heldBricksOf(const ResumeMsg& resume,
                                const std::vector<std::size_t>& bricksPerCascade);

}  // namespace pc
