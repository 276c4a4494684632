// Datagrams of the streaming protocol (datagram.fbs): brick update fragments from the server,
// at most kMaxDatagramBytes each, a CRC-32 at the end. Also the receiver's reassembly of
// fragmented payloads, with capped memory and a timeout.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <span>
#include <vector>

#include "common/result.h"
#include "protocol/stream_limits.h"

namespace pc {

// The update a fragment belongs to, repeated in every fragment of it.
struct UpdateHeader {
  std::uint32_t updateId = 0;
  int cascade = 0;
  std::uint32_t brick = 0;
  std::uint64_t version = 0;
  std::uint64_t baseVersion = 0;  // 0: self-contained
  std::uint8_t codec = 0;
  std::uint32_t totalSize = 0;  // payload bytes
  // Precision levels (brick_precision.h) of the payload's codes and of the base it is a
  // residual on; 0: the codec's own.
  std::uint8_t precision = 0, basePrecision = 0;
  bool sameUpdate(const UpdateHeader& o) const {
    return updateId == o.updateId && cascade == o.cascade && brick == o.brick &&
           version == o.version && baseVersion == o.baseVersion && codec == o.codec &&
           totalSize == o.totalSize && precision == o.precision && basePrecision == o.basePrecision;
  }
};

// For encoding: a fragment that refers to payload bytes held elsewhere.
struct FragmentRef {
  UpdateHeader update;
  std::uint16_t index = 0;
  std::span<const std::uint8_t> data;
};

struct Fragment {
  UpdateHeader update;
  std::uint16_t index = 0, count = 0;
  std::vector<std::uint8_t> data;
};

struct Datagram {
  std::uint32_t sessionId = 0;
  std::uint32_t sequence = 0;
  std::uint64_t fieldVersion = 0;
  std::vector<Fragment> fragments;
};

// Payloads larger than this are refused (the brick codec's worst case, rounded up).
inline constexpr std::size_t kMaxUpdatePayloadBytes = 128 * 1024;

// Fragments a payload of `totalSize` bytes is split into.
std::uint16_t fragmentCount(std::uint32_t totalSize);
// Upper bounds of the encoded size: a datagram's fixed part (header, CRC) and each fragment's
// part besides its data. A sender packs fragments while the sum stays within kMaxDatagramBytes.
inline constexpr std::size_t kDatagramOverheadBytes = 64;
inline constexpr std::size_t kFragmentOverheadBytes = 96;

std::vector<std::uint8_t> encodeDatagram(std::uint32_t sessionId, std::uint32_t sequence,
                                         std::uint64_t fieldVersion,
                                         std::span<const FragmentRef> fragments);
// Size limit, CRC, identifier, Verifier, then each fragment's sizes and indices.
Result<Datagram> decodeDatagram(std::span<const std::uint8_t> bytes);

struct ReassemblyOptions {
  // s: a partial payload that got no fragment for this long is dropped. Counted from its latest
  // fragment, not its first: a sender resends a lost update whole (the same id and bytes) until
  // it is acknowledged, and each resend fills in what the last one lost.
  double timeout = 1.0;
  std::size_t maxUpdates = 64;      // partial payloads held at once
  std::size_t maxBytes = 4u << 20;  // their buffers together
  // Selective repair (takeGaps). An update's fragments leave the sender in consecutive
  // datagrams, so once a datagram `gapReorder` or more sequence numbers past the one that
  // brought a partial payload's latest fragment has arrived, and `gapQuiet` s have passed since
  // that fragment (for links that reorder by more datagrams), what it lacks was lost: it is
  // reported. The evidence is sequence numbers, so a client that reads its socket late reports
  // nothing early. It is reported again while fragments are missing: on the same evidence past
  // the answer's fragments, or `gapRepeat` s after the last report where no answer came (at
  // least this, and at least twice the time answers took).
  std::uint32_t gapReorder = 3;
  double gapQuiet = 0.01;
  double gapRepeat = 0.05;
};

// A partial payload's missing fragments (Reassembler::takeGaps).
struct FragmentGap {
  UpdateHeader update;
  std::uint16_t fragmentCount = 0;
  std::vector<std::uint16_t> missing;
};

struct CompletedUpdate {
  UpdateHeader update;
  std::vector<std::uint8_t> payload;
};

// Puts fragmented payloads back together. Keyed by update id; fragments whose header differs
// from the partial payload's replace it (ids are hashes, which two updates may share). When the
// caps are reached the partial payload that heard nothing for longest is dropped: memory stays
// bounded whatever arrives.
class Reassembler {
 public:
  explicit Reassembler(ReassemblyOptions options = {}) : options_(options) {}
  // The completed payload when `fragment` completes one.
  // `sequence`: the datagram's that brought the fragment (selective repair).
  std::optional<CompletedUpdate> add(Fragment&& fragment, double now, std::uint32_t sequence = 0);
  void expire(double now);
  // The partial payloads due a report of their missing fragments now, given the newest datagram
  // sequence received (ReassemblyOptions: gapReorder, gapRepeat), the longest waiting first,
  // at most `maxGaps`; each is marked reported at `now`.
  std::vector<FragmentGap> takeGaps(double now, std::uint32_t newestSequence, std::size_t maxGaps);
  // Smoothed time from a report to the first fragment answering it (0 before any).
  double repairRoundTrip() const { return repairRtt_; }
  std::size_t pendingUpdates() const { return partial_.size(); }
  std::size_t pendingBytes() const { return bytes_; }
  std::uint64_t dropped() const { return dropped_; }

 private:
  struct Partial {
    UpdateHeader update;
    std::vector<std::uint8_t> payload;
    std::vector<bool> have;
    std::size_t received = 0;
    double lastSeen = 0;             // when its latest fragment arrived
    std::uint32_t lastSequence = 0;  // the datagram that brought it
    double reportedAt = -1;          // when its gaps were last reported (takeGaps); -1: never
    bool answered = true;            // a fragment arrived since that report
  };
  void erase(std::map<std::uint32_t, Partial>::iterator it);

  ReassemblyOptions options_;
  std::map<std::uint32_t, Partial> partial_;
  std::size_t bytes_ = 0;
  std::uint64_t dropped_ = 0;
  double repairRtt_ = 0;
};

}  // namespace pc
