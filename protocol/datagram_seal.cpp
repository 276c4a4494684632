#include "protocol/datagram_seal.h"

#include <sodium.h>

#include <cstring>
#include <string>

#include "protocol/sodium_init.h"

namespace pc {

namespace {

constexpr std::uint8_t kMagic[4] = {'P', 'C', 'S', 'D'};
constexpr std::size_t kNonceBytes = crypto_aead_chacha20poly1305_IETF_NPUBBYTES;
static_assert(kNonceBytes == 12 && crypto_aead_chacha20poly1305_IETF_ABYTES == kSealTagBytes &&
              crypto_aead_chacha20poly1305_IETF_KEYBYTES == kDatagramKeyBytes);

void putLe(std::uint8_t* p, std::uint64_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) p[i] = std::uint8_t(v >> (8 * i));
}

std::uint64_t getLe(const std::uint8_t* p, int bytes) {
  std::uint64_t v = 0;
  for (int i = 0; i < bytes; ++i) v |= std::uint64_t(p[i]) << (8 * i);
  return v;
}

// 4 zero bytes, then the counter little-endian: unique per datagram under one key.
std::array<std::uint8_t, kNonceBytes> nonceFor(std::uint64_t counter) {
  std::array<std::uint8_t, kNonceBytes> nonce{};
  putLe(nonce.data() + 4, counter, 8);
  return nonce;
}

}  // namespace

DatagramKeys deriveDatagramKeys(std::span<const std::uint8_t, kDatagramExporterBytes> exported) {
  DatagramKeys keys;
  std::memcpy(keys.serverToClient.data(), exported.data(), kDatagramKeyBytes);
  std::memcpy(keys.clientToServer.data(), exported.data() + kDatagramKeyBytes, kDatagramKeyBytes);
  return keys;
}

std::optional<std::uint32_t> peekSessionId(std::span<const std::uint8_t> bytes) {
  if (bytes.size() < kSealOverheadBytes || std::memcmp(bytes.data(), kMagic, 4) != 0)
    return std::nullopt;
  return std::uint32_t(getLe(bytes.data() + 4, 4));
}

std::string_view openRefusalName(OpenRefusal cause) {
  switch (cause) {
    case OpenRefusal::Malformed:
      return "malformed";
    case OpenRefusal::WrongSession:
      return "wrong_session";
    case OpenRefusal::Forged:
      return "forged";
    case OpenRefusal::Replayed:
      return "replayed";
    case OpenRefusal::TooOld:
      return "too_old";
  }
  return "unknown";
}

DatagramSealer::DatagramSealer(const DatagramKey& key, std::uint32_t sessionId)
    : key_(key), sessionId_(sessionId) {
  ensureSodium();
}

DatagramSealer::DatagramSealer(DatagramSealer&& other) noexcept
    : key_(other.key_), sessionId_(other.sessionId_), next_(other.next_) {
  sodium_memzero(other.key_.data(), other.key_.size());
  other.next_ = kMaxSealCounter + 1;  // its counters are this sealer's now
}

DatagramSealer& DatagramSealer::operator=(DatagramSealer&& other) noexcept {
  if (this != &other) {
    key_ = other.key_;
    sessionId_ = other.sessionId_;
    next_ = other.next_;
    sodium_memzero(other.key_.data(), other.key_.size());
    other.next_ = kMaxSealCounter + 1;
  }
  return *this;
}

DatagramSealer::~DatagramSealer() { sodium_memzero(key_.data(), key_.size()); }

Status DatagramSealer::skipTo(std::uint64_t next) {
  if (next < next_)
    return Error{"the sealer's counter is at " + std::to_string(next_) + ": cannot go back to " +
                 std::to_string(next)};
  next_ = next;
  return Status::success();
}

Status DatagramSealer::seal(std::span<const std::uint8_t> plain, std::vector<std::uint8_t>& out) {
  if (next_ > kMaxSealCounter)
    return Error{"session " + std::to_string(sessionId_) +
                 ": the datagram counter is used up (2^62 datagrams sealed, or the sealer was "
                 "moved from); a new key is needed"};
  const std::size_t start = out.size();
  out.resize(start + plain.size() + kSealOverheadBytes);
  std::uint8_t* header = out.data() + start;
  std::memcpy(header, kMagic, 4);
  putLe(header + 4, sessionId_, 4);
  putLe(header + 8, next_, 8);
  const auto nonce = nonceFor(next_);
  std::uint8_t* cipher = header + kSealHeaderBytes;
  crypto_aead_chacha20poly1305_ietf_encrypt_detached(
      cipher, cipher + plain.size(), nullptr, plain.data(), plain.size(), header, kSealHeaderBytes,
      nullptr, nonce.data(), key_.data());
  ++next_;
  return Status::success();
}

DatagramOpener::DatagramOpener(const DatagramKey& key, std::uint32_t sessionId)
    : key_(key), sessionId_(sessionId) {
  ensureSodium();
}

DatagramOpener::DatagramOpener(DatagramOpener&& other) noexcept
    : key_(other.key_),
      sessionId_(other.sessionId_),
      window_(other.window_),
      plain_(std::move(other.plain_)),
      stats_(other.stats_),
      live_(other.live_) {
  sodium_memzero(other.key_.data(), other.key_.size());
  other.live_ = false;
}

DatagramOpener& DatagramOpener::operator=(DatagramOpener&& other) noexcept {
  if (this != &other) {
    key_ = other.key_;
    sessionId_ = other.sessionId_;
    window_ = other.window_;
    plain_ = std::move(other.plain_);
    stats_ = other.stats_;
    live_ = other.live_;
    sodium_memzero(other.key_.data(), other.key_.size());
    other.live_ = false;
  }
  return *this;
}

DatagramOpener::~DatagramOpener() { sodium_memzero(key_.data(), key_.size()); }

bool ReplayWindow::accepted(std::uint64_t counter) const {
  if (counter == 0 || counter > highest_ || counter + kReplayWindowCounters <= highest_)
    return false;
  const std::uint64_t bit = counter % kReplayWindowCounters;
  return (bits_[bit / 64] >> (bit % 64)) & 1;
}

ReplayWindow::Verdict ReplayWindow::check(std::uint64_t counter) const {
  if (counter + kReplayWindowCounters <= highest_) return Verdict::TooOld;
  return accepted(counter) ? Verdict::Replayed : Verdict::Fresh;
}

void ReplayWindow::accept(std::uint64_t counter) {
  if (counter > highest_) {
    // Counters passed over become free slots of the window (they may still arrive).
    const std::uint64_t advance = counter - highest_;
    if (advance >= kReplayWindowCounters) {
      bits_.fill(0);
    } else {
      for (std::uint64_t c = highest_ + 1; c <= counter; ++c) {
        const std::uint64_t bit = c % kReplayWindowCounters;
        bits_[bit / 64] &= ~(std::uint64_t(1) << (bit % 64));
      }
    }
    highest_ = counter;
  }
  const std::uint64_t bit = counter % kReplayWindowCounters;
  bits_[bit / 64] |= std::uint64_t(1) << (bit % 64);
}

Result<std::span<const std::uint8_t>> DatagramOpener::open(std::span<const std::uint8_t> sealed,
                                                           OpenRefusal* cause) {
  if (sealed.size() >= kSealOverheadBytes && sealed.size() <= kMaxSealedDatagramBytes)
    plain_.resize(sealed.size() - kSealOverheadBytes);
  return open(sealed, plain_, cause);
}

Result<std::span<const std::uint8_t>> DatagramOpener::open(std::span<const std::uint8_t> sealed,
                                                           std::span<std::uint8_t> plainOut,
                                                           OpenRefusal* cause) {
  auto refuse = [&](OpenRefusal why, const std::string& what) -> Error {
    ++stats_.refused[std::size_t(why)];
    if (cause) *cause = why;
    return Error{"sealed datagram refused (" + std::string(openRefusalName(why)) + "): " + what};
  };
  if (!live_) return Error{"sealed datagram refused: the opener was moved from"};
  if (sealed.size() < kSealOverheadBytes || sealed.size() > kMaxSealedDatagramBytes)
    return refuse(OpenRefusal::Malformed, std::to_string(sealed.size()) + " bytes");
  if (std::memcmp(sealed.data(), kMagic, 4) != 0)
    return refuse(OpenRefusal::Malformed, "no PCSD magic");
  const std::uint64_t counter = getLe(sealed.data() + 8, 8);
  if (counter == 0 || counter > kMaxSealCounter)
    return refuse(OpenRefusal::Malformed, "counter " + std::to_string(counter) + " out of range");
  const std::uint32_t session = std::uint32_t(getLe(sealed.data() + 4, 4));
  if (session != sessionId_)
    return refuse(OpenRefusal::WrongSession,
                  "session " + std::to_string(session) + ", not " + std::to_string(sessionId_));
  const std::size_t plainBytes = sealed.size() - kSealOverheadBytes;
  if (plainOut.size() < plainBytes)
    return Error{"sealed datagram of " + std::to_string(sealed.size()) +
                 " bytes: the output buffer holds only " + std::to_string(plainOut.size())};

  // Authenticated first, so that every refusal below is of a datagram the peer did send, and
  // nothing unauthenticated touches the window.
  const auto nonce = nonceFor(counter);
  const std::uint8_t* cipher = sealed.data() + kSealHeaderBytes;
  if (crypto_aead_chacha20poly1305_ietf_decrypt_detached(
          plainOut.data(), nullptr, cipher, plainBytes, cipher + plainBytes, sealed.data(),
          kSealHeaderBytes, nonce.data(), key_.data()) != 0)
    return refuse(OpenRefusal::Forged,
                  "authentication failed (counter " + std::to_string(counter) + ")");
  switch (window_.check(counter)) {
    case ReplayWindow::Verdict::TooOld:
      return refuse(OpenRefusal::TooOld, "counter " + std::to_string(counter) +
                                             " is behind the window (highest " +
                                             std::to_string(window_.highest()) + ")");
    case ReplayWindow::Verdict::Replayed:
      return refuse(OpenRefusal::Replayed, "counter " + std::to_string(counter) + " seen before");
    case ReplayWindow::Verdict::Fresh:
      break;
  }
  window_.accept(counter);
  ++stats_.opened;
  return std::span<const std::uint8_t>(plainOut.data(), plainBytes);
}

}  // namespace pc
