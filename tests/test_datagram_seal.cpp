// Sealed datagrams (protocol/datagram_seal.h): the wire format checked against an independent
// implementation of PROTOCOL.md with libsodium, and the opener's refusals, each counted under
// its cause: forgeries under another key at any counter (which never move the replay window),
// any flipped bit, replays, counters behind the window, another session; reordering within the
// window accepted; the sealer's counter never reused nor run past 2^62.
#include <gtest/gtest.h>
#include <sodium.h>

#include <algorithm>
#include <cstring>
#include <numeric>
#include <random>
#include <vector>

#include "protocol/datagram_seal.h"
#include "protocol/secure_io.h"

namespace {

using namespace pc;
using Bytes = std::vector<std::uint8_t>;

DatagramKey keyOf(std::uint8_t b) {
  DatagramKey k;
  for (std::size_t i = 0; i < k.size(); ++i) k[i] = std::uint8_t(b + 31 * i);
  return k;
}

Bytes plainOf(std::size_t n, std::uint8_t salt) {
  Bytes p(n);
  for (std::size_t i = 0; i < n; ++i) p[i] = std::uint8_t(i * 13 + salt);
  return p;
}

// A sealed datagram made as PROTOCOL.md describes, with libsodium directly: any counter, any key.
Bytes sealAt(const DatagramKey& key, std::uint32_t session, std::uint64_t counter,
             const Bytes& plain) {
  Bytes out = {'P', 'C', 'S', 'D'};
  for (int i = 0; i < 4; ++i) out.push_back(std::uint8_t(session >> (8 * i)));
  for (int i = 0; i < 8; ++i) out.push_back(std::uint8_t(counter >> (8 * i)));
  std::uint8_t nonce[12] = {};
  for (int i = 0; i < 8; ++i) nonce[4 + i] = std::uint8_t(counter >> (8 * i));
  out.resize(16 + plain.size() + 16);
  crypto_aead_chacha20poly1305_ietf_encrypt(out.data() + 16, nullptr, plain.data(), plain.size(),
                                            out.data(), 16, nullptr, nonce, key.data());
  return out;
}

Bytes sealOne(DatagramSealer& sealer, const Bytes& plain) {
  Bytes out;
  EXPECT_TRUE(sealer.seal(plain, out).ok());
  return out;
}

// The opener's window as a list of accepted counters around its top.
std::vector<std::uint64_t> windowOf(const DatagramOpener& o) {
  std::vector<std::uint64_t> seen;
  const std::uint64_t top = o.highestCounter();
  for (std::uint64_t c = top > 1100 ? top - 1100 : 1; c <= top + 1100; ++c)
    if (o.accepted(c)) seen.push_back(c);
  return seen;
}

TEST(DatagramSeal, RoundTripMatchesTheSpecifiedFormat) {
  const DatagramKey key = keyOf(1);
  DatagramSealer sealer(key, 0x01020304);
  DatagramOpener opener(key, 0x01020304);
  for (std::size_t n : {std::size_t(0), std::size_t(1), std::size_t(100), std::size_t(1200)}) {
    const Bytes plain = plainOf(n, std::uint8_t(n));
    const std::uint64_t counter = sealer.nextCounter();
    const Bytes sealed = sealOne(sealer, plain);
    ASSERT_EQ(sealed.size(), n + kSealOverheadBytes);
    // Magic, session id and counter little-endian, ciphertext and tag: byte for byte what the
    // independent implementation makes.
    EXPECT_EQ(sealed, sealAt(key, 0x01020304, counter, plain));
    EXPECT_EQ(std::memcmp(sealed.data(), "PCSD\x04\x03\x02\x01", 8), 0);
    EXPECT_EQ(sealed[8], std::uint8_t(counter));
    EXPECT_EQ(peekSessionId(sealed), std::optional<std::uint32_t>(0x01020304));
    if (n > 0) {
      EXPECT_NE(std::memcmp(sealed.data() + 16, plain.data(), n), 0) << "not encrypted";
    }
    auto opened = opener.open(sealed);
    ASSERT_TRUE(opened.ok()) << opened.error().message;
    EXPECT_EQ(Bytes(opened->begin(), opened->end()), plain);
  }
  EXPECT_EQ(sealer.nextCounter(), 5u);
  EXPECT_EQ(opener.highestCounter(), 4u);
  EXPECT_EQ(opener.stats().opened, 4u);
  EXPECT_FALSE(peekSessionId(Bytes(31, 'P')).has_value());
  EXPECT_FALSE(peekSessionId(Bytes(40, 0)).has_value());
}

TEST(DatagramSeal, SealAppendsWithoutAllocatingWhenThereIsRoom) {
  DatagramSealer sealer(keyOf(2), 9);
  DatagramOpener opener(keyOf(2), 9);
  Bytes out = {0xaa, 0xbb};
  out.reserve(4096);
  const std::uint8_t* before = out.data();
  const Bytes plain = plainOf(1000, 3);
  ASSERT_TRUE(sealer.seal(plain, out).ok());
  EXPECT_EQ(out.data(), before);
  ASSERT_EQ(out.size(), 2 + 1000 + kSealOverheadBytes);
  EXPECT_EQ(out[0], 0xaa);
  EXPECT_EQ(out[1], 0xbb);
  auto opened = opener.open(std::span<const std::uint8_t>(out).subspan(2));
  ASSERT_TRUE(opened.ok()) << opened.error().message;
  EXPECT_TRUE(std::equal(opened->begin(), opened->end(), plain.begin(), plain.end()));

  // Into the caller's buffer: exactly the plain size is enough, one byte less is not.
  const Bytes sealed = sealOne(sealer, plain);
  Bytes small(999), exact(1000);
  EXPECT_FALSE(opener.open(sealed, small).ok());
  EXPECT_EQ(opener.highestCounter(), 1u) << "a refused buffer leaves the window alone";
  auto into = opener.open(sealed, exact);
  ASSERT_TRUE(into.ok()) << into.error().message;
  EXPECT_EQ(into->data(), exact.data());
  EXPECT_EQ(exact, plain);
}

TEST(DatagramSeal, KeysAreTheExportedSecretSplitInTwo) {
  std::array<std::uint8_t, 64> exported;
  for (std::size_t i = 0; i < exported.size(); ++i) exported[i] = std::uint8_t(i);
  const DatagramKeys keys = deriveDatagramKeys(exported);
  for (std::size_t i = 0; i < 32; ++i) {
    EXPECT_EQ(std::size_t(keys.serverToClient[i]), i);
    EXPECT_EQ(std::size_t(keys.clientToServer[i]), 32 + i);
  }
  // The two directions cannot open each other's datagrams.
  DatagramSealer s2c(keys.serverToClient, 1);
  DatagramOpener c2sOpener(keys.clientToServer, 1);
  OpenRefusal cause = OpenRefusal::Malformed;
  EXPECT_FALSE(c2sOpener.open(sealOne(s2c, plainOf(10, 1)), &cause).ok());
  EXPECT_EQ(cause, OpenRefusal::Forged);
}

TEST(DatagramSeal, ForgeriesAtAnyCounterNeverMoveTheWindow) {
  const DatagramKey key = keyOf(3), wrong = keyOf(4);
  DatagramSealer sealer(key, 42);
  DatagramOpener opener(key, 42);
  std::vector<Bytes> genuine;
  for (int i = 0; i < 12; ++i) genuine.push_back(sealOne(sealer, plainOf(50, std::uint8_t(i))));
  // Open 1..10 except 7 (still in flight).
  for (int i = 0; i < 10; ++i)
    if (i != 6) {
      ASSERT_TRUE(opener.open(genuine[i]).ok());
    }
  const std::vector<std::uint64_t> window = windowOf(opener);
  ASSERT_EQ(window.size(), 9u);

  std::uint64_t forged = 0;
  for (std::uint64_t counter :
       {std::uint64_t(1), std::uint64_t(5), std::uint64_t(7), std::uint64_t(10), std::uint64_t(11),
        std::uint64_t(2000), std::uint64_t(1) << 40, kMaxSealCounter}) {
    for (std::size_t n : {std::size_t(0), std::size_t(50)}) {
      OpenRefusal cause = OpenRefusal::Malformed;
      auto r = opener.open(sealAt(wrong, 42, counter, plainOf(n, 9)), &cause);
      ASSERT_FALSE(r.ok()) << "forgery at counter " << counter << " accepted";
      EXPECT_EQ(cause, OpenRefusal::Forged) << r.error().message;
      ++forged;
    }
    // A genuine header and ciphertext with a random tag is a forgery too.
    Bytes tampered = sealAt(key, 42, counter, plainOf(50, 9));
    randomBytes(std::span<std::uint8_t>(tampered).last(16));
    EXPECT_FALSE(opener.open(tampered).ok());
    ++forged;
  }
  EXPECT_EQ(opener.stats().refusedCount(OpenRefusal::Forged), forged);
  EXPECT_EQ(opener.stats().opened, 9u);
  EXPECT_EQ(opener.highestCounter(), 10u);
  EXPECT_EQ(windowOf(opener), window);
  // The genuine 7, 11 and 12 still open: the forged 2000 and 2^62 did not push them out.
  EXPECT_TRUE(opener.open(genuine[6]).ok());
  EXPECT_TRUE(opener.open(genuine[10]).ok());
  EXPECT_TRUE(opener.open(genuine[11]).ok());
  EXPECT_EQ(opener.highestCounter(), 12u);
}

TEST(DatagramSeal, EveryFlippedBitIsRefused) {
  const DatagramKey key = keyOf(5);
  DatagramSealer sealer(key, 77);
  DatagramOpener opener(key, 77);
  ASSERT_TRUE(opener.open(sealOne(sealer, plainOf(20, 1))).ok());
  const Bytes sealed = sealOne(sealer, plainOf(100, 2));
  std::array<std::uint64_t, kOpenRefusalCount> byCause{};
  for (std::size_t bit = 0; bit < sealed.size() * 8; ++bit) {
    Bytes flipped = sealed;
    flipped[bit / 8] ^= std::uint8_t(1u << (bit % 8));
    OpenRefusal cause = OpenRefusal::Replayed;
    auto r = opener.open(flipped, &cause);
    ASSERT_FALSE(r.ok()) << "bit " << bit << " flipped was accepted";
    ++byCause[std::size_t(cause)];
    ASSERT_EQ(opener.highestCounter(), 1u) << "bit " << bit << " moved the window";
  }
  // Magic bits, and the counter bits that make it 0 or put it past 2^62 (bits 1, 62, 63 of
  // counter 2), fail the form; session id bits name another session; the rest (the counter's
  // other bits, ciphertext, tag) fail authentication.
  EXPECT_EQ(byCause[std::size_t(OpenRefusal::Malformed)], 32u + 3u);
  EXPECT_EQ(byCause[std::size_t(OpenRefusal::WrongSession)], 32u);
  EXPECT_EQ(byCause[std::size_t(OpenRefusal::Forged)], sealed.size() * 8 - 67);
  EXPECT_EQ(byCause[std::size_t(OpenRefusal::Replayed)], 0u);
  EXPECT_EQ(opener.stats().refusedCount(OpenRefusal::Forged), sealed.size() * 8 - 67);
  EXPECT_TRUE(opener.open(sealed).ok()) << "the original still opens after all that";
}

TEST(DatagramSeal, ReplaysAndCountersBehindTheWindowAreRefused) {
  const DatagramKey key = keyOf(6);
  DatagramSealer sealer(key, 1);
  DatagramOpener opener(key, 1);
  std::vector<Bytes> sealed(3001);  // index = counter
  for (std::uint64_t c = 1; c <= 3000; ++c)
    sealed[c] = sealOne(sealer, plainOf(8, std::uint8_t(c)));

  ASSERT_TRUE(opener.open(sealed[1100]).ok());
  OpenRefusal cause = OpenRefusal::Malformed;
  EXPECT_FALSE(opener.open(sealed[1100], &cause).ok());
  EXPECT_EQ(cause, OpenRefusal::Replayed);

  // Everything up to 1023 behind the top opens once, in any order; anything older is refused.
  std::vector<std::uint64_t> order(1099);
  std::iota(order.begin(), order.end(), 1);
  std::shuffle(order.begin(), order.end(), std::mt19937(3));
  std::uint64_t opened = 1, tooOld = 0;
  for (std::uint64_t c : order) {
    auto r = opener.open(sealed[c], &cause);
    if (c >= 1100 - 1023) {
      ASSERT_TRUE(r.ok()) << c << ": " << r.error().message;
      ++opened;
    } else {
      ASSERT_FALSE(r.ok()) << c;
      EXPECT_EQ(cause, OpenRefusal::TooOld);
      ++tooOld;
    }
  }
  EXPECT_EQ(opened, 1024u);
  EXPECT_EQ(tooOld, 76u);
  for (std::uint64_t c : order) {
    if (c < 1100 - 1023) continue;
    ASSERT_FALSE(opener.open(sealed[c], &cause).ok());
    EXPECT_EQ(cause, OpenRefusal::Replayed);
  }
  EXPECT_EQ(opener.stats().refusedCount(OpenRefusal::Replayed), 1 + 1023u);
  EXPECT_EQ(opener.stats().refusedCount(OpenRefusal::TooOld), 76u);

  // A jump far ahead leaves only the new window; the counters skipped inside it still open.
  ASSERT_TRUE(opener.open(sealed[3000]).ok());
  EXPECT_FALSE(opener.open(sealed[1100], &cause).ok());
  EXPECT_EQ(cause, OpenRefusal::TooOld);
  EXPECT_FALSE(opener.open(sealed[3000 - 1024], &cause).ok());
  EXPECT_EQ(cause, OpenRefusal::TooOld);
  EXPECT_TRUE(opener.open(sealed[3000 - 1023]).ok());
  EXPECT_TRUE(opener.open(sealed[2999]).ok());
  EXPECT_EQ(opener.stats().opened, 1024u + 3);
}

TEST(DatagramSeal, SmallStepsClearTheSlotsTheyPass) {
  // The window reuses slot (counter mod 1024): a counter 1024 past one accepted must open.
  const DatagramKey key = keyOf(7);
  DatagramSealer sealer(key, 1);
  DatagramOpener opener(key, 1);
  std::vector<Bytes> sealed(2200);
  for (std::uint64_t c = 1; c < sealed.size(); ++c) sealed[c] = sealOne(sealer, plainOf(4, 1));
  for (std::uint64_t c = 1; c < sealed.size(); c += 3)
    ASSERT_TRUE(opener.open(sealed[c]).ok()) << c;
  for (std::uint64_t c = sealed.size() - 1000; c < sealed.size(); ++c)
    EXPECT_EQ(opener.open(sealed[c]).ok(), (c - 1) % 3 != 0) << c;
}

TEST(DatagramSeal, OtherSessionsAndMalformedInputAreRefused) {
  const DatagramKey key = keyOf(8);
  DatagramSealer sealer(key, 7);
  DatagramOpener opener(key, 8);
  OpenRefusal cause = OpenRefusal::Forged;
  EXPECT_FALSE(opener.open(sealOne(sealer, plainOf(10, 1)), &cause).ok());
  EXPECT_EQ(cause, OpenRefusal::WrongSession);

  DatagramOpener right(key, 7);
  auto malformed = [&](const Bytes& b) {
    OpenRefusal c = OpenRefusal::Forged;
    auto r = right.open(b, &c);
    EXPECT_FALSE(r.ok());
    EXPECT_EQ(c, OpenRefusal::Malformed) << r.error().message;
  };
  malformed({});
  malformed(Bytes(31, 0));
  Bytes good = sealOne(sealer, plainOf(10, 2));
  Bytes noMagic = good;
  noMagic[3] = 'G';
  malformed(noMagic);
  malformed(sealAt(key, 7, 0, plainOf(10, 2)));                    // counter 0
  malformed(sealAt(key, 7, kMaxSealCounter + 1, plainOf(10, 2)));  // authentic, out of range
  malformed(Bytes(kMaxSealedDatagramBytes + 1, 'P'));
  EXPECT_EQ(right.stats().refusedCount(OpenRefusal::Malformed), 6u);
  EXPECT_TRUE(right.open(good).ok());
  EXPECT_EQ(openRefusalName(OpenRefusal::WrongSession), "wrong_session");
  EXPECT_EQ(openRefusalName(OpenRefusal::TooOld), "too_old");
}

TEST(DatagramSeal, CounterIsNeverReusedNorRunPastTheLimit) {
  const DatagramKey key = keyOf(9);
  DatagramSealer sealer(key, 3);
  DatagramOpener opener(key, 3);
  ASSERT_TRUE(opener.open(sealOne(sealer, plainOf(5, 1))).ok());
  EXPECT_FALSE(sealer.skipTo(1).ok()) << "going back would reuse counter 1";
  ASSERT_TRUE(sealer.skipTo(kMaxSealCounter - 1).ok());
  ASSERT_TRUE(opener.open(sealOne(sealer, plainOf(5, 2))).ok());
  ASSERT_TRUE(opener.open(sealOne(sealer, plainOf(5, 3))).ok());
  EXPECT_EQ(opener.highestCounter(), kMaxSealCounter);
  Bytes out = {1, 2, 3};
  Status s = sealer.seal(plainOf(5, 4), out);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("used up"), std::string::npos) << s.error().message;
  EXPECT_EQ(out, (Bytes{1, 2, 3})) << "nothing appended";
  EXPECT_FALSE(sealer.seal({}, out).ok());

  // A moved-from sealer or opener refuses rather than share counters or a window.
  DatagramSealer first(key, 4);
  DatagramSealer second(std::move(first));
  EXPECT_FALSE(first.seal(plainOf(5, 5), out).ok());  // NOLINT(bugprone-use-after-move)
  DatagramOpener openerA(key, 4);
  const Bytes one = sealOne(second, plainOf(5, 6));
  DatagramOpener openerB(std::move(openerA));
  EXPECT_FALSE(openerA.open(one).ok());  // NOLINT(bugprone-use-after-move)
  EXPECT_TRUE(openerB.open(one).ok());
}

}  // namespace
