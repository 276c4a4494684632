// What strangers get from a real server on loopback, and what a client believes: the caps per
// remote address (connections before their Hello, sessions, handshakes per second) and per
// client name, each with a client from another address (127.0.0.2: on Linux all of 127/8 is
// loopback) still joining and a well-behaved client receiving throughout; an unauthenticated
// peer never getting more bytes than it sent; and on the client's side, junk datagrams that
// cannot keep a dead server looking alive and a hostile Reject reason that reaches the log
// bounded and escaped.
#include <gtest/gtest.h>

#include <cmath>

#include "common/log.h"
#include "protocol/datagram.h"
#include "test_net_hostile_support.h"

namespace pc::nettest {
namespace {

constexpr const char* kOtherAddress = "127.0.0.2";

HelloMsg hello(const std::string& token, const std::string& name) {
  HelloMsg h;
  h.authToken = token;
  h.clientName = name;
  h.wantsUdp = false;
  return h;
}

// A peer from `from` that joins (datagrams over TCP) and reads until its first datagram.
void expectJoinsAndReceives(std::uint16_t port, const char* from, const std::string& name) {
  RawPeer peer(port, 0, from);
  peer.send(encodeMessage(hello(issueTestToken(name), name)));
  auto welcome = peer.readFrame(5.0);
  ASSERT_TRUE(welcome.has_value()) << "no Welcome for a client from " << from;
  auto m = decodeMessage(*welcome);
  ASSERT_TRUE(m.ok() && std::holds_alternative<WelcomeMsg>(*m)) << "not a Welcome";
  bool datagram = false;
  for (int i = 0; i < 64 && !datagram; ++i) {
    auto frame = peer.readFrame(5.0);
    ASSERT_TRUE(frame.has_value()) << "the stream stopped";
    datagram = classifyFrame(*frame) == FrameKind::Datagram;
  }
  EXPECT_TRUE(datagram) << "no datagram for the client from " << from;
}

TEST(NetLimits, IdleSocketsFromOneAddressAreCappedAnotherAddressStillJoins) {
  NetServerOptions o;
  o.handshakesPerSecondPerAddress = 0;  // the pending cap alone
  o.helloTimeout = 60;                  // the idle sockets stay for the whole test
  HostileFixture f(o);
  std::vector<std::unique_ptr<RawPeer>> idle;
  // Idle: connected, never a byte sent (not even a TLS handshake).
  for (int i = 0; i < 20; ++i)
    idle.push_back(std::make_unique<RawPeer>(f.port(), 0, nullptr, /*tls=*/false));
  // 8 (the default cap) await their Hello; the other 12 are closed as soon as accepted.
  f.expectOnlyCause(DisconnectCause::AddressLimit, 12);
  EXPECT_EQ(f.stats().connections, 1u + 8u);
  expectJoinsAndReceives(f.port(), kOtherAddress, "other");
  f.expectGoodClientUnaffected();
}

TEST(NetLimits, HandshakeFloodFromOneAddressIsCapped) {
  NetServerOptions o;
  o.maxPendingPerAddress = 0;  // the handshake rate alone: 4 a second, a burst of 8
  o.helloTimeout = 60;
  HostileFixture f(o);
  const std::uint64_t acceptedBefore = f.stats().accepted;
  constexpr int kFlood = 40;
  std::vector<std::unique_ptr<RawPeer>> flood;
  const double start = steadySeconds();
  for (int i = 0; i < kFlood; ++i)
    flood.push_back(std::make_unique<RawPeer>(f.port(), 0, nullptr, /*tls=*/false));
  ASSERT_TRUE(waitFor([&] { return f.stats().accepted >= acceptedBefore + kFlood; }, 10.0));
  const double elapsed = steadySeconds() - start;
  // A refused connection is counted as accepted before its refusal is: on a busy machine the
  // last refusals land a moment after the last accept.
  ASSERT_TRUE(waitFor(
      [&] {
        const NetServerStats now = f.stats();
        return now.connections - 1 + now.disconnectsBy(DisconnectCause::AddressLimit) >=
               std::uint64_t(kFlood);
      },
      5.0));
  const NetServerStats s = f.stats();
  const std::uint64_t refused = s.disconnectsBy(DisconnectCause::AddressLimit);
  const std::uint64_t admitted = s.connections - 1;
  std::printf("%d connections in %.2f s: %llu admitted, %llu refused\n", kFlood, elapsed,
              (unsigned long long)admitted, (unsigned long long)refused);
  EXPECT_EQ(admitted + refused, std::uint64_t(kFlood));
  // The burst, plus what the bucket refilled while the flood lasted.
  EXPECT_LE(double(admitted), 8.0 + std::ceil(4.0 * elapsed));
  EXPECT_GE(refused, 1u);
  expectJoinsAndReceives(f.port(), kOtherAddress, "other");
  f.expectGoodClientUnaffected();
}

TEST(NetLimits, SessionsPerAddressAreCapped) {
  NetServerOptions o;
  o.maxSessionsPerAddress = 3;  // the good client's and two more
  HostileFixture f(o);
  std::vector<std::unique_ptr<RawPeer>> joined;
  for (int i = 0; i < 2; ++i) {
    joined.push_back(std::make_unique<RawPeer>(f.port()));
    joined.back()->send(encodeMessage(hello(kToken, "peer" + std::to_string(i))));
    ASSERT_TRUE(joined.back()->readFrame(5.0).has_value());
  }
  ASSERT_TRUE(waitFor([&] { return f.stats().clients.size() == 3; }, 5.0));
  // The fourth is closed as soon as accepted: nothing is read, nothing sent.
  RawPeer fourth(f.port(), 0, nullptr, /*tls=*/false);  // closed before any TLS handshake
  EXPECT_EQ(fourth.bytesUntilClosed(5.0), std::optional<std::size_t>(0));
  EXPECT_TRUE(
      waitFor([&] { return f.stats().disconnectsBy(DisconnectCause::AddressLimit) == 1; }, 5.0));
  expectJoinsAndReceives(f.port(), kOtherAddress, "other");
}

// Two connections may both be admitted while a place remains; the one whose Hello comes
// second hears why it cannot join, as a Reject, rather than a bare close.
TEST(NetLimits, HelloOverTheAddressCapIsRejectedWithItsCause) {
  NetServerOptions o;
  o.maxSessionsPerAddress = 2;  // the good client's and one more
  HostileFixture f(o);
  auto first = std::make_unique<RawPeer>(f.port());
  RawPeer second(f.port());
  first->send(encodeMessage(hello(kToken, "first")));
  auto welcome = first->readFrame(5.0);
  ASSERT_TRUE(welcome.has_value());
  auto w = decodeMessage(*welcome);
  ASSERT_TRUE(w.ok() && std::holds_alternative<WelcomeMsg>(*w));
  const std::vector<std::uint8_t> helloBytes = encodeMessage(hello(kToken, "second"));
  second.send(helloBytes);
  auto frame = second.readFrame(5.0);
  ASSERT_TRUE(frame.has_value());
  auto m = decodeMessage(*frame);
  ASSERT_TRUE(m.ok() && std::holds_alternative<RejectMsg>(*m));
  const std::string& reason = std::get<RejectMsg>(*m).reason;
  std::printf("reject reason: %s\n", reason.c_str());
  EXPECT_EQ(reason.rfind("address limit: ", 0), 0u);
  EXPECT_LE(frame->size(), helloBytes.size());
  EXPECT_TRUE(waitFor([&] { return f.stats().rejectsBy(RejectCause::AddressLimit) == 1; }, 5.0));
  EXPECT_EQ(f.stats().clients.size(), 2u);
  // The place freed by the first is taken again by a newcomer from the same address.
  first.reset();
  ASSERT_TRUE(waitFor([&] { return f.stats().clients.size() == 1; }, 5.0));
  {
    RawPeer third(f.port());
    third.send(encodeMessage(hello(kToken, "third")));
    auto again = third.readFrame(5.0);
    ASSERT_TRUE(again.has_value());
    auto a = decodeMessage(*again);
    ASSERT_TRUE(a.ok() && std::holds_alternative<WelcomeMsg>(*a));
  }
  // Both the first and the third have left (the statistics are a snapshot: wait for what
  // counts their leaving, not only for the list, which an older snapshot may show short).
  ASSERT_TRUE(waitFor(
      [&] {
        const NetServerStats s = f.stats();
        return s.disconnectsBy(DisconnectCause::ClientClosed) >= 2 && s.clients.size() == 1;
      },
      5.0));
  f.expectGoodClientUnaffected();
}

TEST(NetLimits, SessionsPerTokenAreCapped) {
  HostileFixture f;  // "good" holds one session; the holder of the token "raw" may hold 4
  const std::string raw = issueTestToken("raw");
  std::vector<std::unique_ptr<RawPeer>> joined;
  for (int i = 0; i < 4; ++i) {
    joined.push_back(std::make_unique<RawPeer>(f.port()));
    joined.back()->send(encodeMessage(hello(raw, "raw-" + std::to_string(i))));
    auto welcome = joined.back()->readFrame(5.0);
    ASSERT_TRUE(welcome.has_value());
    auto m = decodeMessage(*welcome);
    ASSERT_TRUE(m.ok() && std::holds_alternative<WelcomeMsg>(*m));
  }
  RawPeer fifth(f.port());
  const std::vector<std::uint8_t> helloBytes = encodeMessage(hello(raw, "raw-4"));
  fifth.send(helloBytes);
  auto frame = fifth.readFrame(5.0);
  ASSERT_TRUE(frame.has_value());
  auto m = decodeMessage(*frame);
  ASSERT_TRUE(m.ok() && std::holds_alternative<RejectMsg>(*m));
  std::printf("reject reason: %s (%zu bytes for a Hello of %zu)\n",
              std::get<RejectMsg>(*m).reason.c_str(), frame->size(), helloBytes.size());
  EXPECT_EQ(std::get<RejectMsg>(*m).reason.rfind("client limit", 0), 0u);
  EXPECT_LE(frame->size(), helloBytes.size());
  EXPECT_EQ(std::get<RejectMsg>(*m).reason, "client limit: cap 4");
  EXPECT_TRUE(waitFor([&] { return f.stats().rejectsBy(RejectCause::ClientLimit) == 1; }, 5.0));
  // Another token is not affected.
  expectJoinsAndReceives(f.port(), nullptr, "someone else");
}

TEST(NetLimits, UnauthenticatedPeerNeverGetsMoreThanItSent) {
  NetServerOptions o;
  o.maxClients = 1;  // the good client holds the only place
  HostileFixture f(o);
  struct Case {
    const char* what;
    std::vector<std::uint8_t> bytes;
  };
  HelloMsg oldVersion = hello(kToken, "");
  oldVersion.protocolVersion = 0;
  const std::vector<Case> cases = {
      {"a short Hello with a wrong token", encodeMessage(hello("x", ""))},
      {"a Hello of an unsupported version", encodeMessage(oldVersion)},
      {"a short Hello to a full server", encodeMessage(hello(kToken, ""))},
      {"a long Hello to a full server", encodeMessage(hello(kToken, std::string(60, 'n')))},
      {"a frame prefix alone", {4, 0, 0, 0}},
  };
  bool anyReject = false;
  for (const Case& c : cases) {
    RawPeer peer(f.port());
    peer.send(c.bytes);
    const auto got = peer.bytesUntilClosed(10.0);
    ASSERT_TRUE(got.has_value()) << c.what << ": not closed";
    std::printf("%s: sent %zu bytes, got %zu\n", c.what, c.bytes.size(), *got);
    EXPECT_LE(*got, c.bytes.size()) << c.what;
    anyReject |= *got > 0;
  }
  EXPECT_TRUE(anyReject) << "a Hello long enough still gets its Reject";
  f.expectGoodClientUnaffected();
}

TEST(NetLimits, AClientSteersTheSchedulerWithOneViewerInsideTheField) {
  HostileFixture f;  // the good client sends no poses: the viewer set is empty
  auto peer = std::make_unique<RawPeer>(f.port());
  peer->send(encodeMessage(hello(issueTestToken("steer"), "steer")));
  ASSERT_TRUE(peer->readFrame(5.0).has_value());
  ViewerPoseMsg pose;
  const auto viewers = [&] { return f.server().hub().viewers(); };
  // Poses inside the field: each replaces the session's one viewer.
  for (float x : {-0.5f, 0.0f, 0.5f}) {
    pose.position = glm::vec3(x, 0.5f, 0.0f);
    peer->send(encodeMessage(pose));
  }
  ASSERT_TRUE(waitFor(
      [&] { return viewers().size() == 1 && viewers()[0] == glm::vec3(0.5f, 0.5f, 0.0f); }, 5.0));
  const auto received = [&] {
    for (const NetClientInfo& c : f.stats().clients)
      if (c.name == "steer") return c.messagesReceived;
    return std::uint64_t(0);
  };
  const std::uint64_t before = received();
  // Far outside the field, and just past its bounds grown by half their largest side (a pose
  // that is not finite does not even decode): ignored, the viewer stays where it was.
  for (glm::vec3 p :
       {glm::vec3(1e6f, 0.0f, 0.0f), glm::vec3(0.0f, -50.0f, 0.0f), glm::vec3(0.0f, 0.5f, 1.9f)}) {
    pose.position = p;
    peer->send(encodeMessage(pose));
  }
  ASSERT_TRUE(waitFor([&] { return received() >= before + 3; }, 5.0));
  ASSERT_EQ(viewers().size(), 1u);
  EXPECT_EQ(viewers()[0], glm::vec3(0.5f, 0.5f, 0.0f));
  // Its viewer leaves with the session.
  peer.reset();
  EXPECT_TRUE(waitFor([&] { return viewers().empty(); }, 5.0));
  f.expectGoodClientUnaffected();
}

TEST(NetHostileServer, JunkDatagramsDoNotKeepADeadServerAlive) {
  // The fake server answers the handshake (session 7), then never sends anything again.
  FakeServer fake(builtinInfo());
  client::FieldMirror mirror;
  auto o = goodOptions(fake.port());
  o.silenceTimeout = 1.0;
  client::NetClient client(mirror, o);
  client.start();
  ASSERT_TRUE(waitFor([&] { return client.stats().sessions >= 1; }, 10.0));
  // Meanwhile strangers send datagrams to the client's port: junk from the server's address
  // (another port), and well-formed heartbeats of the session from another address.
  namespace asio = boost::asio;
  asio::io_context io;
  asio::ip::udp::socket local(io, {asio::ip::make_address("127.0.0.1"), 0});
  asio::ip::udp::socket other(io, {asio::ip::make_address(kOtherAddress), 0});
  const asio::ip::udp::endpoint to(asio::ip::make_address("127.0.0.1"), client.udpPort());
  const std::vector<std::uint8_t> junk(200, 0x5A);
  std::uint32_t sequence = 0;
  const bool silent = waitFor(
      [&] {
        boost::system::error_code ec;
        local.send_to(asio::buffer(junk), to, 0, ec);
        other.send_to(asio::buffer(encodeDatagram(7, sequence++, 0, {})), to, 0, ec);
        return client.stats().lastError.find("silent") != std::string::npos;
      },
      10.0);
  const client::NetClientStats s = client.stats();
  std::printf("after %u heartbeats from elsewhere: %s; %llu foreign, %llu bad datagrams\n",
              sequence, s.lastError.c_str(), (unsigned long long)s.foreignDatagrams,
              (unsigned long long)s.badDatagrams);
  EXPECT_TRUE(silent) << "the junk kept the dead server looking alive";
  EXPECT_GT(s.foreignDatagrams, 0u);
}

TEST(NetHostileServer, HostileRejectReasonIsLoggedBoundedAndEscaped) {
  // A reason of nearly 4 MiB of terminal escapes and forged log lines.
  std::string reason;
  while (reason.size() < (4u << 20) - 4096) reason += "\x1b[2J\r\n[fake] [error] line \xff ";
  reason.resize((4u << 20) - 4096);
  FakeServer fake([&reason](int) { return encodeMessage(RejectMsg{kProtocolVersion, reason}); });
  testing::internal::CaptureStderr();
  {
    client::FieldMirror mirror;
    auto o = goodOptions(fake.port());
    o.backoffMax = 0.05;
    client::NetClient client(mirror, o);
    client.start();
    waitFor([&] { return fake.connections() >= 10; }, 20.0);
  }
  const std::string log = testing::internal::GetCapturedStderr();
  std::printf("%d Rejects of %zu bytes: %zu bytes of log:\n%s", fake.connections(), reason.size(),
              log.size(), log.c_str());
  EXPECT_GE(fake.connections(), 10);
  EXPECT_LT(log.size(), 2000u);
  EXPECT_EQ(log.find('\x1b'), std::string::npos);
  EXPECT_EQ(log.find('\r'), std::string::npos);
  EXPECT_EQ(log.find("\n[fake]"), std::string::npos) << "a forged line";
  EXPECT_NE(log.find("\\x1b[2J\\r\\n[fake]"), std::string::npos);
  EXPECT_NE(log.find("more bytes)"), std::string::npos);
}

TEST(NetHostileServer, ChangingRejectReasonsDoNotFloodTheLog) {
  // Every attempt gets another reason, so none repeats the one before.
  FakeServer fake([](int n) {
    return encodeMessage(RejectMsg{kProtocolVersion, "reason " + std::to_string(n)});
  });
  testing::internal::CaptureStderr();
  std::uint64_t suppressed = 0;
  {
    client::FieldMirror mirror;
    auto o = goodOptions(fake.port());
    o.backoffMax = 0.02;
    client::NetClient client(mirror, o);
    client.start();
    waitFor([&] { return fake.connections() >= 30; }, 20.0);
    suppressed = client.stats().suppressedLogLines;
  }
  const std::string log = testing::internal::GetCapturedStderr();
  std::size_t lines = 0;
  for (std::size_t at = log.find("rejected"); at != std::string::npos;
       at = log.find("rejected", at + 1))
    ++lines;
  std::printf("%d attempts: %zu lines logged, %llu left out\n", fake.connections(), lines,
              (unsigned long long)suppressed);
  EXPECT_GE(fake.connections(), 30);
  EXPECT_LE(lines, 5u);  // the budget: 5 lines every 10 s
  EXPECT_GT(suppressed, 0u);
}

}  // namespace
}  // namespace pc::nettest
