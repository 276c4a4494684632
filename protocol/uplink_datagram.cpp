#include "protocol/uplink_datagram.h"

#include <cstring>
#include <string>

#include "protocol/net_framing.h"

namespace pc {

namespace {

constexpr std::uint8_t kSealedMagic[4] = {'P', 'C', 'S', 'D'};
constexpr std::uint8_t kPlainMagic[4] = {'P', 'C', 'S', 'P'};

std::uint64_t getLe(const std::uint8_t* p, int bytes) {
  std::uint64_t v = 0;
  for (int i = 0; i < bytes; ++i) v |= std::uint64_t(p[i]) << (8 * i);
  return v;
}

void putLe(std::uint8_t* p, std::uint64_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) p[i] = std::uint8_t(v >> (8 * i));
}

// Whether `bytes` is exactly one frame: its size prefix names every byte after it.
bool wholeFrame(std::span<const std::uint8_t> bytes) {
  if (bytes.size() < kFramePrefixBytes) return false;
  auto size = frameSize(bytes.first(kFramePrefixBytes), kMaxUplinkFrameBytes);
  return size && *size == bytes.size();
}

}  // namespace

UplinkWriter::UplinkWriter(const std::optional<DatagramKey>& key, std::uint32_t sessionId)
    : sessionId_(sessionId) {
  if (key) sealer_.emplace(*key, sessionId);
}

Result<std::vector<std::uint8_t>> UplinkWriter::wrap(std::span<const std::uint8_t> frame) {
  if (frame.size() > kMaxUplinkFrameBytes)
    return Error{"a frame of " + std::to_string(frame.size()) + " bytes is over the " +
                 std::to_string(kMaxUplinkFrameBytes) + " an uplink datagram carries"};
  std::vector<std::uint8_t> out;
  if (sealer_) {
    out.reserve(frame.size() + kSealOverheadBytes);
    if (Status s = sealer_->seal(frame, out); !s) return s.error();
    return out;
  }
  if (next_ > kMaxSealCounter) return Error{"the uplink datagram counter is used up"};
  out.resize(kUplinkHeaderBytes + frame.size());
  std::memcpy(out.data(), kPlainMagic, 4);
  putLe(out.data() + 4, sessionId_, 4);
  putLe(out.data() + 8, next_++, 8);
  std::memcpy(out.data() + kUplinkHeaderBytes, frame.data(), frame.size());
  return out;
}

std::optional<UplinkHeader> peekUplink(std::span<const std::uint8_t> bytes) {
  if (bytes.size() < kUplinkHeaderBytes) return std::nullopt;
  UplinkHeader h;
  if (std::memcmp(bytes.data(), kSealedMagic, 4) == 0) {
    h.sealed = true;
  } else if (std::memcmp(bytes.data(), kPlainMagic, 4) != 0) {
    return std::nullopt;
  }
  h.sessionId = std::uint32_t(getLe(bytes.data() + 4, 4));
  return h;
}

std::string_view uplinkDropName(UplinkDrop cause) {
  switch (cause) {
    case UplinkDrop::Malformed:
      return "malformed";
    case UplinkDrop::Oversized:
      return "oversized";
    case UplinkDrop::UnknownSession:
      return "unknown_session";
    case UplinkDrop::WrongMode:
      return "wrong_mode";
    case UplinkDrop::WrongSender:
      return "wrong_sender";
    case UplinkDrop::Forged:
      return "forged";
    case UplinkDrop::Replayed:
      return "replayed";
    case UplinkDrop::TooOld:
      return "too_old";
    case UplinkDrop::NotAFrame:
      return "not_a_frame";
  }
  return "unknown";
}

UplinkOpener::UplinkOpener(const std::optional<DatagramKey>& key, std::uint32_t sessionId)
    : sessionId_(sessionId) {
  if (key) opener_.emplace(*key, sessionId);
}

Result<std::span<const std::uint8_t>> UplinkOpener::open(std::span<const std::uint8_t> datagram,
                                                         UplinkDrop& cause) {
  auto drop = [&](UplinkDrop why, const std::string& what) -> Error {
    cause = why;
    return Error{"uplink datagram dropped (" + std::string(uplinkDropName(why)) + "): " + what};
  };
  if (datagram.size() > kMaxUplinkDatagramBytes)
    return drop(UplinkDrop::Oversized, std::to_string(datagram.size()) + " bytes");
  const std::optional<UplinkHeader> header = peekUplink(datagram);
  if (!header) return drop(UplinkDrop::Malformed, "no PCSD or PCSP header");
  if (header->sessionId != sessionId_)
    return drop(UplinkDrop::UnknownSession, "session " + std::to_string(header->sessionId));
  if (header->sealed != sealed())
    return drop(UplinkDrop::WrongMode, header->sealed ? "sealed, for a session without TLS"
                                                      : "in clear, for a session with TLS");
  std::span<const std::uint8_t> frame;
  if (opener_) {
    OpenRefusal refusal = OpenRefusal::Malformed;
    auto plain = opener_->open(datagram, &refusal);
    if (!plain) {
      switch (refusal) {
        case OpenRefusal::Forged:
          return drop(UplinkDrop::Forged, plain.error().message);
        case OpenRefusal::Replayed:
          return drop(UplinkDrop::Replayed, plain.error().message);
        case OpenRefusal::TooOld:
          return drop(UplinkDrop::TooOld, plain.error().message);
        case OpenRefusal::WrongSession:  // checked above
        case OpenRefusal::Malformed:
          break;
      }
      return drop(UplinkDrop::Malformed, plain.error().message);
    }
    frame = *plain;
  } else {
    const std::uint64_t counter = getLe(datagram.data() + 8, 8);
    if (counter == 0 || counter > kMaxSealCounter)
      return drop(UplinkDrop::Malformed, "counter " + std::to_string(counter) + " out of range");
    switch (window_.check(counter)) {
      case ReplayWindow::Verdict::Replayed:
        return drop(UplinkDrop::Replayed, "counter " + std::to_string(counter) + " seen before");
      case ReplayWindow::Verdict::TooOld:
        return drop(UplinkDrop::TooOld,
                    "counter " + std::to_string(counter) + " behind the window");
      case ReplayWindow::Verdict::Fresh:
        break;
    }
    frame = datagram.subspan(kUplinkHeaderBytes);
    // Nothing authenticates the plain form: its frame is checked before its counter counts.
    if (!wholeFrame(frame)) return drop(UplinkDrop::NotAFrame, "not one whole frame");
    window_.accept(counter);
    ++opened_;
    return frame;
  }
  if (!wholeFrame(frame)) return drop(UplinkDrop::NotAFrame, "not one whole frame");
  ++opened_;
  return frame;
}

}  // namespace pc
