// Sealed datagrams (protocol/datagram_seal.h): one DatagramOpener fed a list of records
//   op (1 byte), length (2 bytes LE), bytes
// as a client's socket would hand them over. Op bit 0 clear: the bytes are opened as they are.
// Bit 0 set: the bytes are a counter (8 bytes LE, zero-padded when shorter) and a plain
// datagram, which the target seals with the session's key as PROTOCOL.md says (libsodium
// directly), so that mutations reach the replay window; bit 1 then seals it for another
// session, bit 2 with another key. Bit 3 opens into a caller buffer instead of the opener's.
// Checked: what opens is exactly the plain datagram sealed; no counter opens twice; the window
// never moves but forward and never on a refusal; a refusal's cause is counted, and every call
// is counted once; a forgery (another key) never opens.
// The same bytes also go to the server's openers of acks sent as datagrams
// (protocol/uplink_datagram.h): the sealed one, which must open exactly what the opener above
// opens when that is one whole session message frame, and the plain one (op bit 4 rewrites
// the magic to PCSP first), which must open only whole frames, each counter once.
#include <sodium.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <optional>
#include <set>
#include <vector>

#include "fuzz_support.h"
#include "protocol/datagram_seal.h"
#include "protocol/net_framing.h"
#include "protocol/uplink_datagram.h"

namespace {

using namespace pc;
using Bytes = std::vector<std::uint8_t>;

Bytes sealAt(const DatagramKey& key, std::uint32_t session, std::uint64_t counter,
             std::span<const std::uint8_t> plain) {
  Bytes out = {'P', 'C', 'S', 'D'};
  for (int i = 0; i < 4; ++i) out.push_back(std::uint8_t(session >> (8 * i)));
  for (int i = 0; i < 8; ++i) out.push_back(std::uint8_t(counter >> (8 * i)));
  std::uint8_t nonce[12] = {};
  for (int i = 0; i < 8; ++i) nonce[4 + i] = std::uint8_t(counter >> (8 * i));
  out.resize(kSealHeaderBytes + plain.size() + kSealTagBytes);
  crypto_aead_chacha20poly1305_ietf_encrypt(out.data() + kSealHeaderBytes, nullptr, plain.data(),
                                            plain.size(), out.data(), kSealHeaderBytes, nullptr,
                                            nonce, key.data());
  return out;
}

std::uint64_t totalCalls(const OpenerStats& s) {
  std::uint64_t n = s.opened;
  for (std::uint64_t r : s.refused) n += r;
  return n;
}

bool wholeFrame(std::span<const std::uint8_t> bytes) {
  if (bytes.size() < kFramePrefixBytes) return false;
  auto size = frameSize(bytes.first(kFramePrefixBytes), kMaxUplinkFrameBytes);
  return size && *size == bytes.size();
}

std::uint64_t counterOf(std::span<const std::uint8_t> datagram) {
  std::uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v |= std::uint64_t(datagram[8 + i]) << (8 * i);
  return v;
}

// The plain uplink opener on `bytes` with the magic made PCSP (op bit 4): what opens is one
// whole frame inside the datagram, and no counter opens twice.
void checkPlainUplink(UplinkOpener& plain, std::set<std::uint64_t>& accepted, Bytes bytes,
                      bool rewriteMagic) {
  if (rewriteMagic && bytes.size() >= 4) bytes[3] = 'P';
  UplinkDrop cause = UplinkDrop(255);
  auto frame = plain.open(bytes, cause);
  if (!frame) {
    if (std::size_t(cause) >= kUplinkDropCount) std::abort();
    return;
  }
  if (bytes.size() < kUplinkHeaderBytes || bytes[3] != 'P') std::abort();
  if (frame->data() != bytes.data() + kUplinkHeaderBytes || !wholeFrame(*frame)) std::abort();
  if (!accepted.insert(counterOf(bytes)).second) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const DatagramKey key = fuzz::sealKey();
  DatagramKey otherKey = key;
  otherKey[0] ^= 1;
  DatagramOpener opener(key, fuzz::kSealSession);
  UplinkOpener uplink(key, fuzz::kSealSession);
  DatagramOpener uplinkMirror(key, fuzz::kSealSession);  // fed what `uplink` is fed
  UplinkOpener plainUplink(std::nullopt, fuzz::kSealSession);
  std::set<std::uint64_t> plainAccepted;
  std::set<std::uint64_t> accepted;
  std::uint64_t calls = 0;
  Bytes callerBuffer;
  std::size_t at = 0;
  while (at + 3 <= size) {
    const std::uint8_t op = data[at];
    const std::size_t length =
        std::min<std::size_t>(data[at + 1] | (data[at + 2] << 8), size - at - 3);
    const std::span<const std::uint8_t> bytes(data + at + 3, length);
    at += 3 + length;

    Bytes sealed;
    std::span<const std::uint8_t> plain;
    std::uint64_t counter = 0;
    const bool sealedHere = op & 1, forged = sealedHere && (op & 4);
    if (sealedHere) {
      for (std::size_t i = 0; i < 8 && i < bytes.size(); ++i)
        counter |= std::uint64_t(bytes[i]) << (8 * i);
      plain = bytes.subspan(std::min<std::size_t>(8, bytes.size()));
      sealed = sealAt(forged ? otherKey : key,
                      (op & 2) ? fuzz::kSealSession + 1 : fuzz::kSealSession, counter, plain);
    } else {
      sealed.assign(bytes.begin(), bytes.end());
    }

    checkPlainUplink(plainUplink, plainAccepted, sealed, op & 16);
    if (sealed.size() <= kMaxUplinkDatagramBytes) {
      // The sealed uplink opener opens what a DatagramOpener fed the same bytes opens, where
      // that is one whole frame.
      UplinkDrop uplinkCause = UplinkDrop(255);
      auto frame = uplink.open(sealed, uplinkCause);
      auto mirrored = uplinkMirror.open(sealed);
      if (frame && (!mirrored ||
                    !std::equal(frame->begin(), frame->end(), mirrored->begin(), mirrored->end())))
        std::abort();
      if (!frame && mirrored && wholeFrame(*mirrored)) std::abort();
      if (!frame && std::size_t(uplinkCause) >= kUplinkDropCount) std::abort();
    }
    const std::uint64_t highestBefore = opener.highestCounter();
    OpenRefusal cause = OpenRefusal(255);
    Result<std::span<const std::uint8_t>> opened = [&] {
      if (!(op & 8)) return opener.open(sealed, &cause);
      callerBuffer.assign(
          sealed.size() >= kSealOverheadBytes ? sealed.size() - kSealOverheadBytes : 0, 0);
      return opener.open(sealed, callerBuffer, &cause);
    }();
    ++calls;
    if (totalCalls(opener.stats()) != calls) std::abort();
    if (!opened) {
      if (std::size_t(cause) >= kOpenRefusalCount) std::abort();
      if (opener.highestCounter() != highestBefore) std::abort();
      continue;
    }
    if (forged) std::abort();
    if (opened->size() + kSealOverheadBytes != sealed.size()) std::abort();
    const std::uint64_t c = [&] {
      std::uint64_t v = 0;
      for (int i = 0; i < 8; ++i) v |= std::uint64_t(sealed[8 + i]) << (8 * i);
      return v;
    }();
    if (sealedHere &&
        (c != counter || !std::equal(opened->begin(), opened->end(), plain.begin(), plain.end())))
      std::abort();
    if (peekSessionId(sealed) != std::optional<std::uint32_t>(fuzz::kSealSession)) std::abort();
    if (!accepted.insert(c).second) std::abort();                  // a counter opened twice
    if (c + kReplayWindowCounters <= highestBefore) std::abort();  // behind the window
    if (opener.highestCounter() != std::max(highestBefore, c) || !opener.accepted(c)) std::abort();
  }
  return 0;
}
