// Sealed datagrams: each UDP datagram of a session encrypted and authenticated with that
// session's key (ChaCha20-Poly1305-IETF), so that nobody on the path can read a session's
// stream or write into it, and a datagram cannot be replayed. The key comes from the session's
// TLS connection (deriveDatagramKeys). Wire format, nonce rule and replay window: PROTOCOL.md,
// "Sealed datagrams".
//
//   DatagramSealer sealer(keys.serverToClient, sessionId);   // server
//   sealer.seal(datagram, out);
//   DatagramOpener opener(keys.serverToClient, sessionId);   // client
//   Result<std::span<const std::uint8_t>> plain = opener.open(received);
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include "common/result.h"

namespace pc {

inline constexpr std::size_t kSealHeaderBytes = 16;  // magic, session id, counter
inline constexpr std::size_t kSealTagBytes = 16;     // Poly1305 tag
inline constexpr std::size_t kSealOverheadBytes = kSealHeaderBytes + kSealTagBytes;
inline constexpr std::size_t kDatagramKeyBytes = 32;
// What an opener takes at most (a UDP payload's limit); larger inputs are refused unread.
inline constexpr std::size_t kMaxSealedDatagramBytes = 65507;
// The last counter a sealer uses; a session that reached it needs a new key (a new session).
inline constexpr std::uint64_t kMaxSealCounter = std::uint64_t(1) << 62;
// How many counters behind the highest authentic one an opener still accepts (once each).
inline constexpr std::uint64_t kReplayWindowCounters = 1024;
// Bytes of TLS exported keying material deriveDatagramKeys takes.
inline constexpr std::size_t kDatagramExporterBytes = 64;

using DatagramKey = std::array<std::uint8_t, kDatagramKeyBytes>;

// The two keys of a session: server->client datagrams (the stream) and client->server ones.
struct DatagramKeys {
  DatagramKey serverToClient{};
  DatagramKey clientToServer{};
};
// Splits 64 bytes of TLS exported keying material (RFC 8446 section 7.5, label
// "EXPORTER-probecast-datagram-keys", empty context) into the two keys: bytes 0..31 are the
// server->client key, bytes 32..63 the client->server key. Both ends of the TLS connection
// export the same bytes, and nobody else can.
DatagramKeys deriveDatagramKeys(std::span<const std::uint8_t, kDatagramExporterBytes> exported);

// The session id of a sealed datagram (bytes 4..8), for the receiver to find the session whose
// opener to use; nullopt when the bytes are too short to be one or lack the magic. Not
// authenticated until that opener has opened it.
std::optional<std::uint32_t> peekSessionId(std::span<const std::uint8_t> bytes);

// Seals one session's datagrams in one direction under one key. Its counter starts at 1 and
// rises by one per datagram, so no nonce is ever used twice under the key; hence a sealer
// cannot be copied, and a moved-from sealer refuses to seal.
class DatagramSealer {
 public:
  DatagramSealer(const DatagramKey& key, std::uint32_t sessionId);
  DatagramSealer(const DatagramSealer&) = delete;
  DatagramSealer& operator=(const DatagramSealer&) = delete;
  DatagramSealer(DatagramSealer&& other) noexcept;
  DatagramSealer& operator=(DatagramSealer&& other) noexcept;
  ~DatagramSealer();

  // Appends the sealed form of `plain` (kSealOverheadBytes longer) to `out`; allocates only
  // when `out` lacks the capacity. `plain` must not lie inside `out`. An Error, and nothing
  // appended, once the counter passed kMaxSealCounter.
  Status seal(std::span<const std::uint8_t> plain, std::vector<std::uint8_t>& out);

  std::uint32_t sessionId() const { return sessionId_; }
  // The counter the next seal uses.
  std::uint64_t nextCounter() const { return next_; }
  // Moves the counter forward to `next` (never back: a counter is never used twice), for a
  // sender that resumes above counters it may have used, and for tests of exhaustion.
  Status skipTo(std::uint64_t next);

 private:
  DatagramKey key_{};
  std::uint32_t sessionId_ = 0;
  std::uint64_t next_ = 1;
};

// Which counters of one direction of a session were accepted: the highest, H, and a bitmap of
// the counters H-1023..H (bit c mod 1024 for counter c). A counter above H moves H up,
// clearing the bits of the counters it passes over (they may still arrive); a counter in the
// window that was not accepted yet is fresh; one behind the window never is.
class ReplayWindow {
 public:
  enum class Verdict : std::uint8_t { Fresh, Replayed, TooOld };
  Verdict check(std::uint64_t counter) const;
  // Records `counter`, which check() found fresh, as accepted.
  void accept(std::uint64_t counter);
  // The highest counter accepted (0 before the first).
  std::uint64_t highest() const { return highest_; }
  // Whether `counter` was accepted (inside the window; false for counters behind it).
  bool accepted(std::uint64_t counter) const;

 private:
  std::uint64_t highest_ = 0;
  std::array<std::uint64_t, kReplayWindowCounters / 64> bits_{};
};

// Why an opener refused a datagram (its stats count each); openRefusalName gives the metric
// label.
enum class OpenRefusal : std::uint8_t {
  Malformed,     // shorter than the overhead, longer than kMaxSealedDatagramBytes, wrong magic,
                 // or counter 0 or past kMaxSealCounter
  WrongSession,  // another session's id
  Forged,        // the tag does not authenticate header and ciphertext under this key
  Replayed,      // authentic, but its counter was already accepted
  TooOld,        // authentic, but its counter is behind the replay window
};
inline constexpr std::size_t kOpenRefusalCount = 5;
std::string_view openRefusalName(OpenRefusal cause);

struct OpenerStats {
  std::uint64_t opened = 0;
  std::array<std::uint64_t, kOpenRefusalCount> refused{};  // indexed by OpenRefusal
  std::uint64_t refusedCount(OpenRefusal cause) const { return refused[std::size_t(cause)]; }
};

// Opens one session's datagrams in one direction: checks form and session id, authenticates,
// and accepts each counter once within a window of kReplayWindowCounters behind the highest
// accepted one, so reordered datagrams still open. Only an authentic datagram moves the window.
class DatagramOpener {
 public:
  DatagramOpener(const DatagramKey& key, std::uint32_t sessionId);
  DatagramOpener(const DatagramOpener&) = delete;
  DatagramOpener& operator=(const DatagramOpener&) = delete;
  // A moved-from opener refuses everything (two openers must not share one window).
  DatagramOpener(DatagramOpener&& other) noexcept;
  DatagramOpener& operator=(DatagramOpener&& other) noexcept;
  ~DatagramOpener();

  // The plain datagram, in a buffer of the opener's valid until the next open; or an Error
  // naming the cause, counted in stats() (and put in `*cause` when given).
  Result<std::span<const std::uint8_t>> open(std::span<const std::uint8_t> sealed,
                                             OpenRefusal* cause = nullptr);
  // The same into `plainOut`, which must hold sealed.size() - kSealOverheadBytes bytes; the
  // result is its first part.
  Result<std::span<const std::uint8_t>> open(std::span<const std::uint8_t> sealed,
                                             std::span<std::uint8_t> plainOut,
                                             OpenRefusal* cause = nullptr);

  std::uint32_t sessionId() const { return sessionId_; }
  const OpenerStats& stats() const { return stats_; }
  // The highest counter accepted (0 before the first).
  std::uint64_t highestCounter() const { return window_.highest(); }
  // Whether `counter` was accepted (inside the window; false for counters behind it).
  bool accepted(std::uint64_t counter) const { return window_.accepted(counter); }

 private:
  DatagramKey key_{};
  std::uint32_t sessionId_ = 0;
  ReplayWindow window_;
  std::vector<std::uint8_t> plain_;
  OpenerStats stats_;
  bool live_ = true;
};

}  // namespace pc
