// Secure sessions against a real server and client over loopback, tried as an attacker would:
// an eavesdropper on the path (every TCP segment and datagram captured by a proxy), forged and
// replayed datagrams aimed at another viewer's session, strangers who send without a session,
// and tokens that are wrong, tampered, expired, revoked or for another scene. A well-behaved
// client keeps receiving throughout.
#include <gtest/gtest.h>

#include <algorithm>
#include <deque>
#include <filesystem>
#include <fstream>

#include "protocol/datagram.h"
#include "protocol/datagram_seal.h"
#include "test_net_support.h"

namespace pc::nettest {
namespace {

namespace asio = boost::asio;
using asio::ip::tcp;
using asio::ip::udp;
using Bytes = std::vector<std::uint8_t>;

// A TCP proxy that forwards every connection to `target` and keeps a copy of every byte it
// carries, both ways: what an observer on the path sees.
class CapturingTcpProxy {
 public:
  explicit CapturingTcpProxy(std::uint16_t target)
      : acceptor_(io_, {asio::ip::make_address("127.0.0.1"), 0}), target_(target) {
    accept();
    thread_ = std::thread([this] { io_.run(); });
  }
  ~CapturingTcpProxy() {
    asio::post(io_, [this] {
      boost::system::error_code ec;
      acceptor_.close(ec);
      for (auto& s : sockets_) s->close(ec);
    });
    thread_.join();
  }
  std::uint16_t port() const { return acceptor_.local_endpoint().port(); }
  Bytes captured() const {
    std::lock_guard lock(mutex_);
    return captured_;
  }

 private:
  void accept() {
    acceptor_.async_accept([this](boost::system::error_code ec, tcp::socket socket) {
      if (ec) return;
      auto in = std::make_shared<tcp::socket>(std::move(socket));
      auto out = std::make_shared<tcp::socket>(io_);
      out->connect({asio::ip::make_address("127.0.0.1"), target_}, ec);
      if (!ec) {
        sockets_.push_back(in);
        sockets_.push_back(out);
        pump(in, out);
        pump(out, in);
      }
      accept();
    });
  }
  void pump(std::shared_ptr<tcp::socket> from, std::shared_ptr<tcp::socket> to) {
    auto buffer = std::make_shared<std::array<std::uint8_t, 16384>>();
    from->async_read_some(asio::buffer(*buffer), [this, from, to, buffer](
                                                     boost::system::error_code ec, std::size_t n) {
      if (ec) {
        boost::system::error_code ignored;
        to->shutdown(tcp::socket::shutdown_send, ignored);
        return;
      }
      {
        std::lock_guard lock(mutex_);
        captured_.insert(captured_.end(), buffer->begin(), buffer->begin() + n);
      }
      asio::write(*to, asio::buffer(buffer->data(), n), ec);
      if (!ec) pump(from, to);
    });
  }

  asio::io_context io_;
  tcp::acceptor acceptor_;
  std::uint16_t target_;
  std::vector<std::shared_ptr<tcp::socket>> sockets_;
  mutable std::mutex mutex_;
  Bytes captured_;
  std::thread thread_;
};

bool contains(const Bytes& haystack, std::span<const std::uint8_t> needle) {
  return std::search(haystack.begin(), haystack.end(), needle.begin(), needle.end()) !=
         haystack.end();
}
bool contains(const Bytes& haystack, std::string_view needle) {
  return contains(haystack,
                  std::span(reinterpret_cast<const std::uint8_t*>(needle.data()), needle.size()));
}

// What must never be seen on the path: the token, the client's name, a session message or
// datagram header (flatbuffer identifiers), a zstd frame (the brick payloads' magic).
void expectNothingInClear(const Bytes& seen, const std::string& token, const char* what) {
  const std::uint8_t zstdMagic[] = {0x28, 0xB5, 0x2F, 0xFD};
  EXPECT_FALSE(contains(seen, token)) << what << " carries the token in clear";
  EXPECT_FALSE(contains(seen, token.substr(5, 24))) << what << " carries part of the token";
  EXPECT_FALSE(contains(seen, "secure-viewer")) << what << " carries the client's name";
  EXPECT_FALSE(contains(seen, "PCSM")) << what << " carries a session message";
  EXPECT_FALSE(contains(seen, "PCDG")) << what << " carries a datagram in clear";
  EXPECT_FALSE(contains(seen, zstdMagic)) << what << " carries a zstd frame";
}

TEST(NetSecure, NoFieldPayloadTravelsInClear) {
  TestServer server(-1.0);  // the field keeps changing: bricks keep flowing
  CapturingTcpProxy proxy(server.port());
  UdpRelay relay;
  relay.capture(true);
  client::FieldMirror mirror;
  client::NetClientOptions o = secureClientOptions(server, "secure-viewer");
  o.port = proxy.port();
  o.udpAdvertisePort = relay.port();
  client::NetClient client(mirror, o);
  client.start();
  relay.setTarget(client.udpPort());
  ASSERT_TRUE(waitFor([&] { return client.stats().synced; }, 20.0)) << client.stats().lastError;
  sleepFor(1.0);  // updates after the sync, too
  client.stop();

  const Bytes tcp = proxy.captured();
  Bytes udp;
  const auto datagrams = relay.captured();
  for (const Bytes& d : datagrams) udp.insert(udp.end(), d.begin(), d.end());
  std::printf("captured: %zu TCP bytes, %zu datagrams (%zu bytes)\n", tcp.size(), datagrams.size(),
              udp.size());
  ASSERT_GT(tcp.size(), 1000u);
  ASSERT_GT(datagrams.size(), 10u);
  // The plain stream starts with a size prefix and a session message; TLS starts with a
  // handshake record (content type 22, version 3.x).
  EXPECT_EQ(tcp[0], 22);
  EXPECT_EQ(tcp[1], 3);
  expectNothingInClear(tcp, o.token, "the session stream");
  expectNothingInClear(udp, o.token, "the datagrams");
  for (const Bytes& d : datagrams) {
    ASSERT_GE(d.size(), kSealOverheadBytes);
    EXPECT_EQ(std::string(d.begin(), d.begin() + 4), "PCSD");
    EXPECT_LE(d.size(), kMaxDatagramBytes + kSealOverheadBytes);
  }
}

// A sealed datagram of `plain` under a key nobody of the session holds.
Bytes forge(std::uint32_t sessionId, const Bytes& plain, std::uint64_t counter) {
  DatagramKey key{};
  key[0] = 0x5A;
  DatagramSealer sealer(key, sessionId);
  EXPECT_TRUE(sealer.skipTo(counter).ok());
  Bytes out;
  EXPECT_TRUE(sealer.seal(plain, out).ok());
  return out;
}

TEST(NetSecure, ForgedAndReplayedDatagramsAreDroppedAndTheVictimIsUnchanged) {
  TestServer server(1.0);  // frozen at t = 1: the victim's mirror must end equal to it
  UdpRelay relay;          // on the victim's path, for the replay
  relay.capture(true);
  client::FieldMirror mirror;
  client::NetClientOptions o = secureClientOptions(server, "victim");
  o.udpAdvertisePort = relay.port();
  client::NetClient victim(mirror, o);
  victim.start();
  relay.setTarget(victim.udpPort());
  ASSERT_TRUE(waitFor(
      [&] { return server.frozen() && mirrorDifference(mirror, server.field()) == 0; }, 30.0));
  const NetServerStats ss = server.net().stats();
  ASSERT_EQ(ss.clients.size(), 1u);
  const std::uint32_t sessionId = ss.clients[0].sessionId;

  // The attack that froze a viewer's bricks before: datagrams with the victim's session id and
  // a version far ahead, for every brick. Now sealed under a wrong key, or not sealed at all.
  std::vector<Bytes> attack;
  const Bytes payload(900, 0xAB);
  for (std::uint32_t brick = 0; brick < 8; ++brick) {
    UpdateHeader h;
    h.updateId = 77 + brick;
    h.cascade = 0;
    h.brick = brick;
    h.version = std::uint64_t(1) << 63;
    h.codec = 1;
    h.totalSize = std::uint32_t(payload.size());
    const FragmentRef fragment{h, 0, payload};
    const Bytes plain = encodeDatagram(sessionId, 1000 + brick, h.version, std::span(&fragment, 1));
    for (std::uint64_t counter = 1; counter < 40; ++counter)
      attack.push_back(forge(sessionId, plain, counter * 1000));
    attack.push_back(plain);  // the old, unsealed form
  }
  const client::NetClientStats before = victim.stats();
  // Sent through the relay: they reach the victim from the address and port its datagrams
  // come from, as an attacker on the path (or one spoofing the server's address) would send
  // them. Only the seal can tell them apart.
  asio::io_context io;
  udp::socket attacker(io, udp::endpoint(udp::v4(), 0));
  const udp::endpoint target(asio::ip::make_address("127.0.0.1"), relay.port());
  // Paced, so that none is lost in the relay's socket buffer: every one must be refused.
  std::size_t attackBytes = 0, sent = 0;
  auto send = [&](const Bytes& d) {
    attacker.send_to(asio::buffer(d), target);
    attackBytes += d.size();
    if (++sent % 16 == 0) sleepFor(0.005);
  };
  for (const Bytes& d : attack) send(d);
  // And the victim's own datagrams again, exactly as they came: replays.
  const auto seen = relay.captured();
  const std::size_t replays = std::min<std::size_t>(seen.size(), 50);
  for (std::size_t i = 0; i < replays; ++i) send(seen[i]);
  std::printf("sent %zu forged datagrams (%zu bytes) and %zu replays\n", attack.size(), attackBytes,
              replays);
  ASSERT_GT(replays, 10u);

  ASSERT_TRUE(waitFor(
      [&] {
        const auto s = victim.stats();
        return s.unsealedRefused + s.badDatagrams >=
               before.unsealedRefused + before.badDatagrams + attack.size() + replays;
      },
      10.0))
      << "refused " << victim.stats().unsealedRefused - before.unsealedRefused << " unsealed, "
      << victim.stats().badDatagrams - before.badDatagrams << " bad, "
      << victim.stats().foreignDatagrams - before.foreignDatagrams << " foreign, of "
      << attack.size() + replays << "; datagrams "
      << victim.stats().udpDatagrams - before.udpDatagrams << "; relay delivered "
      << relay.stats().delivered << ", overflowed " << relay.stats().overflow;
  sleepFor(0.5);
  // Nothing of it landed: the mirror is still the server's field, the session the first one,
  // and the server was never told of the forged versions.
  EXPECT_EQ(mirrorDifference(mirror, server.field()), 0);
  const client::NetClientStats after = victim.stats();
  EXPECT_TRUE(after.connected);
  EXPECT_EQ(after.sessions, 1u);
  EXPECT_EQ(after.bricksApplied, before.bricksApplied) << "a forged or replayed update applied";
  EXPECT_LT(server.net().stats().resends, 50u);
}

TEST(NetSecure, StrangersGetNoMoreBytesThanTheySent) {
  TestServer server(-1.0);
  client::FieldMirror mirror;
  client::NetClient good(mirror, secureClientOptions(server, "good"));
  good.start();
  ASSERT_TRUE(waitFor([&] { return good.stats().synced; }, 20.0));
  asio::io_context io;

  // UDP to the server's datagram port: never answered.
  udp::socket stranger(io, udp::endpoint(udp::v4(), 0));
  const udp::endpoint serverUdp(asio::ip::make_address("127.0.0.1"), server.net().udpPort());
  std::size_t sent = 0;
  for (int i = 0; i < 200; ++i) {
    Bytes junk(1200, std::uint8_t(i));
    stranger.send_to(asio::buffer(junk), serverUdp);
    sent += junk.size();
  }
  // Plain bytes to the session port (no TLS): whatever comes back, at most what was sent.
  tcp::socket plain(io);
  plain.connect({asio::ip::make_address("127.0.0.1"), server.port()});
  Bytes hello = helloFrame(kToken);
  asio::write(plain, asio::buffer(hello));
  std::size_t tcpBack = 0;
  {
    // Until the server closes it: a failed TLS handshake, or the Hello timeout (5 s) where
    // the bytes look like the start of a longer record.
    std::array<std::uint8_t, 4096> buffer{};
    const double start = steadySeconds();
    while (steadySeconds() - start < 10.0) {
      pollfd p{plain.native_handle(), POLLIN, 0};
      if (::poll(&p, 1, 50) <= 0) continue;
      boost::system::error_code ec;
      const std::size_t n = plain.read_some(asio::buffer(buffer), ec);
      tcpBack += n;
      if (ec || n == 0) break;
    }
  }
  std::size_t udpBack = 0;
  stranger.non_blocking(true);
  for (;;) {
    std::array<std::uint8_t, 2048> buffer{};
    boost::system::error_code ec;
    const std::size_t n = stranger.receive(asio::buffer(buffer), 0, ec);
    if (ec) break;
    udpBack += n;
  }
  std::printf("UDP stranger: sent %zu bytes, got %zu; plain TCP stranger: sent %zu, got %zu\n",
              sent, udpBack, hello.size(), tcpBack);
  EXPECT_EQ(udpBack, 0u);
  EXPECT_LE(tcpBack, hello.size());
  EXPECT_TRUE(waitFor(
      [&] {
        const NetServerStats s = server.net().stats();
        return s.disconnectsBy(DisconnectCause::TlsHandshake) +
                   s.disconnectsBy(DisconnectCause::HelloTimeout) >=
               1;
      },
      10.0));
  EXPECT_TRUE(good.stats().connected);
  EXPECT_EQ(good.stats().sessions, 1u);
}

// The Reject a raw TLS peer gets for `token`.
std::string rejectFor(const TestServer& server, const std::string& token) {
  RawPeer peer(server.port());
  peer.send(helloFrame(token));
  auto frame = peer.readFrame(5.0);
  if (!frame) return "no answer";
  auto message = decodeMessage(*frame);
  if (!message) return "undecodable answer";
  if (const auto* reject = std::get_if<RejectMsg>(&*message)) return reject->reason;
  return std::string("admitted: ") + sessionMessageName(*message);
}

TEST(NetSecure, WrongExpiredRevokedTamperedOrMisplacedTokensAreRejected) {
  const std::filesystem::path dir = std::filesystem::path(PC_BUILD_DIR) / "test-net-secure";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string revoked = (dir / "revoked.txt").string();
  const std::int64_t now = unixSeconds();
  const std::string good = issueTestToken("good");
  const std::string expired = issueTestToken("late", 60, 120);
  const std::string early =
      issueToken(testKeys().signing,
                 newTokenClaims("early", "*", TokenRole::Viewer, 1, now + 3600, 3600))
          .value();
  const std::string otherScene =
      issueToken(testKeys().signing,
                 newTokenClaims("elsewhere", "sponza", TokenRole::Viewer, 1, now, 3600))
          .value();
  const std::string stranger =
      issueToken(keyPairFromSeed({99}).signing,
                 newTokenClaims("stranger", "*", TokenRole::Viewer, 1, now, 3600))
          .value();
  std::string tampered = good;
  tampered[tampered.size() / 2] = tampered[tampered.size() / 2] == 'A' ? 'B' : 'A';
  const std::string toRevoke = issueTestToken("revoked");
  std::ofstream(revoked) << "# revoked tokens\n"
                         << tokenIdHex(parseTokenUnverified(toRevoke)->id) << "\n";

  NetServerOptions options;
  options.revocationFile = revoked;
  options.handshakesPerSecondPerAddress = 0;  // one address tries many tokens in a row
  TestServer server(-1.0, options);
  client::FieldMirror mirror;
  client::NetClient client(mirror, secureClientOptions(server, "watcher"));
  client.start();
  ASSERT_TRUE(waitFor([&] { return client.stats().synced; }, 20.0));

  EXPECT_EQ(rejectFor(server, expired), "authentication failed: expired");
  EXPECT_EQ(rejectFor(server, early), "authentication failed: not_yet_valid");
  EXPECT_EQ(rejectFor(server, otherScene), "authentication failed: wrong_scene");
  EXPECT_EQ(rejectFor(server, stranger), "authentication failed: bad_signature");
  const std::string t = rejectFor(server, tampered);
  EXPECT_TRUE(t == "authentication failed: bad_signature" ||
              t == "authentication failed: malformed")
      << t;
  EXPECT_EQ(rejectFor(server, toRevoke), "authentication failed: revoked");
  // Long enough that the Reject's reason fits in what the Hello brought (no amplification).
  EXPECT_EQ(rejectFor(server, std::string(300, 'x')), "authentication failed: malformed");
  EXPECT_EQ(rejectFor(server, good), "admitted: Welcome");

  // Revoked while the server runs: the list is read again when it changes.
  std::ofstream(revoked, std::ios::app) << tokenIdHex(parseTokenUnverified(good)->id) << "\n";
  ASSERT_TRUE(
      waitFor([&] { return rejectFor(server, good) == "authentication failed: revoked"; }, 5.0));

  // The server's figures are a snapshot it refreshes as it polls.
  ASSERT_TRUE(waitFor(
      [&] { return server.net().stats().tokenRejects[std::size_t(TokenError::Revoked)] >= 2; },
      5.0));
  const NetServerStats s = server.net().stats();
  EXPECT_EQ(s.tokenRejects[std::size_t(TokenError::Expired)], 1u);
  EXPECT_EQ(s.tokenRejects[std::size_t(TokenError::NotYetValid)], 1u);
  EXPECT_EQ(s.tokenRejects[std::size_t(TokenError::WrongScene)], 1u);
  EXPECT_GE(s.tokenRejects[std::size_t(TokenError::Revoked)], 2u);
  EXPECT_GE(s.tokenRejects[std::size_t(TokenError::BadSignature)], 1u);
  // The watcher streamed through all of it.
  EXPECT_TRUE(client.stats().connected);
  EXPECT_EQ(client.stats().sessions, 1u);
}

TEST(NetSecure, ClientRefusesAServerWhoseCertificateIsNotThePinned) {
  TestServer server(-1.0);
  client::FieldMirror mirror;
  client::NetClientOptions o = secureClientOptions(server, "careful");
  // Another server's fingerprint: the handshake fails, the token is never sent.
  o.serverFingerprint = "sha256:" + std::string(64, 'a');
  client::NetClient client(mirror, o);
  client.start();
  ASSERT_TRUE(waitFor([&] { return !client.stats().lastError.empty(); }, 10.0));
  EXPECT_NE(client.stats().lastError.find("TLS handshake"), std::string::npos)
      << client.stats().lastError;
  sleepFor(0.5);
  EXPECT_EQ(client.stats().sessions, 0u);
  EXPECT_EQ(server.net().stats().sessions, 0u);
  EXPECT_GE(server.net().stats().disconnectsBy(DisconnectCause::TlsHandshake), 1u);
}

}  // namespace
}  // namespace pc::nettest
