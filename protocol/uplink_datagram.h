// Client->server datagrams (protocol version 6): a client's acks and repair requests travel
// over UDP instead of the session stream once the session's UDP path works, so that the
// server's network thread does not take each of them (about 50 a second per client) through
// the TLS engine. Each datagram carries one session message frame (size prefix and
// flatbuffer, exactly as on the stream), sealed with the session's client->server key in the
// format of datagram_seal.h (magic PCSD); on a session without TLS (--no-tls) the same
// 16-byte header with the magic PCSP and the frame in clear, without a tag. PROTOCOL.md,
// "Acks over UDP".
//
//   UplinkWriter writer(keys.clientToServer, sessionId);   // client
//   Result<Bytes> datagram = writer.wrap(ackFrame);
//   UplinkOpener opener(keys.clientToServer, sessionId);   // server, one per session
//   Result<std::span<const std::uint8_t>> frame = opener.open(datagram, cause);
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include "common/result.h"
#include "protocol/datagram_seal.h"
#include "protocol/stream_limits.h"

namespace pc {

// A frame larger than this goes over the session stream instead (a full ack of a large
// field): a datagram that fits the IPv6 minimum MTU is never fragmented.
inline constexpr std::size_t kMaxUplinkFrameBytes = kMaxDatagramBytes;
inline constexpr std::size_t kMaxUplinkDatagramBytes = kMaxUplinkFrameBytes + kSealOverheadBytes;
// The plain form's header: magic PCSP, session id, counter (as the sealed form's).
inline constexpr std::size_t kUplinkHeaderBytes = kSealHeaderBytes;

// Client side: numbers one session's uplink datagrams and, with a key, seals them.
class UplinkWriter {
 public:
  // `key`: the session's client->server key; nullopt for a session without TLS (plain form).
  UplinkWriter(const std::optional<DatagramKey>& key, std::uint32_t sessionId);
  // The datagram carrying `frame`; an Error when the frame is over kMaxUplinkFrameBytes or
  // the counter is used up.
  Result<std::vector<std::uint8_t>> wrap(std::span<const std::uint8_t> frame);
  bool sealed() const { return sealer_.has_value(); }

 private:
  std::optional<DatagramSealer> sealer_;
  std::uint32_t sessionId_ = 0;
  std::uint64_t next_ = 1;  // the plain form's counter
};

// What an uplink datagram's header says before anything is checked: which session it names
// and whether it is sealed. nullopt when it is too short for a header or has neither magic.
struct UplinkHeader {
  std::uint32_t sessionId = 0;
  bool sealed = false;
};
std::optional<UplinkHeader> peekUplink(std::span<const std::uint8_t> bytes);

// Why the server dropped an uplink datagram (a metric label each, uplinkDropName). Every one
// is dropped unanswered; only an authentic datagram changes anything.
enum class UplinkDrop : std::uint8_t {
  Malformed,       // no header, a counter out of range, or a plain form without a whole frame
  Oversized,       // over kMaxUplinkDatagramBytes (the socket cut it)
  UnknownSession,  // no session past its Hello with a UDP path has that id
  WrongMode,       // sealed for a session without TLS, or plain for one with it
  WrongSender,     // plain form from another address than the session's TCP peer
  Forged,          // the tag does not authenticate it under the session's key
  Replayed,        // its counter was accepted before
  TooOld,          // its counter is behind the replay window
  NotAFrame,       // authentic, but not one whole session message frame
};
inline constexpr std::size_t kUplinkDropCount = 9;
std::string_view uplinkDropName(UplinkDrop cause);

// Server side, one per session: checks form, mode and session id, authenticates (sealed
// form), accepts each counter once within the replay window (the one DatagramOpener keeps),
// and returns the frame inside, which must be exactly one session message frame of at most
// kMaxUplinkFrameBytes. Reordered datagrams open; only an accepted one moves the window.
class UplinkOpener {
 public:
  UplinkOpener(const std::optional<DatagramKey>& key, std::uint32_t sessionId);
  // The frame, in a buffer of the opener's (sealed) or inside `datagram` (plain), valid until
  // the next call; or an Error, with `cause` set.
  Result<std::span<const std::uint8_t>> open(std::span<const std::uint8_t> datagram,
                                             UplinkDrop& cause);
  bool sealed() const { return opener_.has_value(); }
  std::uint64_t opened() const { return opened_; }

 private:
  std::optional<DatagramOpener> opener_;
  ReplayWindow window_;  // the plain form's (the opener keeps its own)
  std::uint32_t sessionId_ = 0;
  std::uint64_t opened_ = 0;
};

}  // namespace pc
