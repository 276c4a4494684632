// The client session (protocol/client_session.h) fed anything a server or a stranger could
// send: TCP bytes in any pieces, UDP datagrams, time passing, reconnects. The input is a list
// of records, each an op byte, a 16-bit little-endian length and that many bytes:
//   op % 4 == 0  stream bytes (the session's framing reassembles them)
//   op % 4 == 1  a datagram; with op & 4, its CRC-32 is made valid first, so that mutations
//                reach the flatbuffer, fragment and brick checks behind it
//   op % 4 == 2  time passes (the first byte x 1/16 s), then poll
//   op % 4 == 3  the connection ends and a new one opens (UDP when op & 4, else TCP only)
// Nothing may crash, and the session's state must stay consistent: an error ends the session
// in Rejected or Failed, a streaming session has its receiver, and it never holds more bricks
// than its layout has.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <vector>

#include "protocol/client_session.h"
#include "protocol/crc32.h"

namespace {

using namespace pc;

ClientSessionOptions sessionOptions() {
  ClientSessionOptions o;
  o.token = "fuzz-token";
  // Layouts that would make the session allocate more than this are refused by its own
  // memory cap, which keeps the fuzzer's memory limit for allocations the cap misses.
  o.maxMirrorBytes = std::uint64_t(64) << 20;
  return o;
}

void checkState(const ClientSession& s) {
  if (s.streaming() && s.receiver() == nullptr) std::abort();
  if (s.bricksHeld() < 0 || s.bricksHeld() > s.bricksTotal()) std::abort();
  if (s.synced() && s.bricksHeld() != s.bricksTotal()) std::abort();
}

void ended(ClientSession& s, double now, bool udp) {
  const SessionPhase p = s.phase();
  if (p != SessionPhase::Rejected && p != SessionPhase::Failed) std::abort();
  if (s.error().empty()) std::abort();
  s.close();
  s.connecting(now);
  (void)s.connected(now, udp ? 4000 : 0);
}

std::vector<std::uint8_t> withValidCrc(std::span<const std::uint8_t> body) {
  std::vector<std::uint8_t> d(body.begin(), body.end());
  const std::uint32_t crc = crc32(d);
  for (int i = 0; i < 4; ++i) d.push_back(std::uint8_t(crc >> (8 * i)));
  return d;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  ClientSession session(sessionOptions());
  double now = 0.0;
  bool udp = true;
  session.connecting(now);
  (void)session.connected(now, 4000);
  std::size_t at = 0;
  while (at + 3 <= size) {
    const std::uint8_t op = data[at];
    std::size_t n = std::size_t(data[at + 1]) | std::size_t(data[at + 2]) << 8;
    at += 3;
    if (n > size - at) n = size - at;
    const std::span<const std::uint8_t> bytes(data + at, n);
    at += n;
    switch (op % 4) {
      case 0:
        if (!session.onStreamBytes(bytes, now)) ended(session, now, udp);
        break;
      case 1: {
        // A datagram's status never ends the session.
        const std::vector<std::uint8_t> d =
            (op & 4) ? withValidCrc(bytes) : std::vector<std::uint8_t>(bytes.begin(), bytes.end());
        (void)session.onDatagram(d, now);
        if (session.phase() == SessionPhase::Rejected) std::abort();
        break;
      }
      case 2: {
        now += (n > 0 ? double(bytes[0]) : 1.0) / 16.0;
        auto frames = session.poll(now);
        if (!frames) {
          ended(session, now, udp);
        } else {
          for (const std::vector<std::uint8_t>& f : *frames)
            if (f.size() < 4) std::abort();  // every frame carries its length prefix
        }
        break;
      }
      default:
        udp = (op & 4) != 0;
        session.close();
        session.connecting(now);
        (void)session.connected(now, udp ? 4000 : 0);
        break;
    }
    checkState(session);
    (void)session.takeChangedBricks();
  }
  return 0;
}
