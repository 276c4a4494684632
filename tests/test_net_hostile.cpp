// Hostile clients against a real server on loopback, one test per abuse: each asserts that the
// abuser is disconnected, that the disconnect is counted under its cause (and only that
// cause), and that a well-behaved NetClient connected throughout keeps receiving in its first
// session. Plus the client's side: a hostile server's SessionInfo cannot make it allocate more
// than its cap. (A wrong token is covered by test_net's BadTokenGetsOnlyAReject.)
#include <gtest/gtest.h>

#include <cstring>

#include "protocol/client_session.h"
#include "test_net_hostile_support.h"

namespace pc::nettest {
namespace {

// A raw peer past the handshake (datagrams over TCP, which it need not read).
std::unique_ptr<RawPeer> joinedPeer(std::uint16_t port, int receiveBuffer = 0) {
  auto peer = std::make_unique<RawPeer>(port, receiveBuffer);
  peer->send(helloFrame(kToken));
  auto welcome = peer->readFrame();
  EXPECT_TRUE(welcome.has_value());
  if (welcome) {
    auto m = decodeMessage(*welcome);
    EXPECT_TRUE(m.ok() && std::holds_alternative<WelcomeMsg>(*m));
  }
  return peer;
}

std::vector<std::uint8_t> concat(const std::vector<std::uint8_t>& frame, int times) {
  std::vector<std::uint8_t> out;
  out.reserve(frame.size() * std::size_t(times));
  for (int i = 0; i < times; ++i) out.insert(out.end(), frame.begin(), frame.end());
  return out;
}

TEST(NetHostile, ClientOverTheCapGetsARejectNamingIt) {
  NetServerOptions o;
  o.maxClients = 1;  // the good client holds the only place
  HostileFixture f(o);
  RawPeer extra(f.port());
  extra.send(helloFrame(kToken));
  auto frame = extra.readFrame();
  ASSERT_TRUE(frame.has_value());
  auto message = decodeMessage(*frame);
  ASSERT_TRUE(message.ok());
  ASSERT_TRUE(std::holds_alternative<RejectMsg>(*message));
  const std::string reason = std::get<RejectMsg>(*message).reason;
  std::printf("reject reason: %s\n", reason.c_str());
  EXPECT_NE(reason.find("server full"), std::string::npos);
  EXPECT_TRUE(extra.closedByServer());
  f.expectOnlyCause(DisconnectCause::Rejected, 1);
  const NetServerStats s = f.stats();
  EXPECT_EQ(s.rejectsBy(RejectCause::ServerFull), 1u);
  EXPECT_EQ(s.rejectsBy(RejectCause::Auth), 0u);
  EXPECT_EQ(s.sessions, 1u);
  f.expectGoodClientUnaffected();
}

TEST(NetHostile, ConnectionsThatNeverSayHelloAreCapped) {
  NetServerOptions o;
  o.maxPendingConnections = 3;
  HostileFixture f(o);
  // Three silent connections take every pending place; the fourth is closed at once.
  std::vector<std::unique_ptr<RawPeer>> silent;
  for (int i = 0; i < 3; ++i) silent.push_back(std::make_unique<RawPeer>(f.port()));
  ASSERT_TRUE(waitFor([&] { return f.stats().connections == 4; }, 5.0));
  RawPeer fourth(f.port(), 0, nullptr, /*tls=*/false);  // closed before any TLS handshake
  EXPECT_TRUE(fourth.closedByServer(5.0));
  f.expectOnlyCause(DisconnectCause::TooManyPending, 1);
  f.expectGoodClientUnaffected();
}

TEST(NetHostile, FloodingClientIsDisconnected) {
  NetServerOptions o;
  o.maxMessagesPerSecond = 300;
  HostileFixture f(o);
  auto flooder = joinedPeer(f.port());
  // 3,000 poses in one burst: ten times the rate allowed, far past the one-second burst.
  ViewerPoseMsg pose;
  pose.position = glm::vec3(1.0f);
  flooder->send(concat(encodeMessage(pose), 3000));
  EXPECT_TRUE(flooder->closedByServer());
  f.expectOnlyCause(DisconnectCause::Flood, 1);
  EXPECT_EQ(f.stats().rejectedMessages[std::size_t(DisconnectCause::Flood)], 1u);
  f.expectGoodClientUnaffected();
}

TEST(NetHostile, FloodOfBytesIsDisconnected) {
  NetServerOptions o;
  o.maxMessageBytes = 64 << 10;
  o.maxReceiveBytesPerSecond = 128 << 10;
  o.maxMessagesPerSecond = 1e6;  // only the byte rate is under test
  HostileFixture f(o);
  auto flooder = joinedPeer(f.port());
  // Valid acks, one range per brick of the first cascade (version 0: holds nothing), 2 MiB of
  // them in a burst: sixteen times the byte rate allowed.
  const gpu::CascadeDesc c = builtinInfo().cascades[0];
  const std::uint32_t bricks =
      std::uint32_t((c.counts.x + 3) / 4 * ((c.counts.y + 3) / 4) * ((c.counts.z + 3) / 4));
  AckMsg ack;
  for (std::uint32_t b = 0; b < bricks; ++b) ack.ranges.push_back({0, b, 1, 0});
  const std::vector<std::uint8_t> frame = encodeMessage(ack);
  ASSERT_LT(frame.size(), std::size_t(64 << 10));
  flooder->send(concat(frame, int((2u << 20) / frame.size()) + 1));
  EXPECT_TRUE(flooder->closedByServer());
  f.expectOnlyCause(DisconnectCause::Flood, 1);
  f.expectGoodClientUnaffected();
}

TEST(NetHostile, MalformedMessageIsDisconnected) {
  HostileFixture f;
  auto peer = joinedPeer(f.port());
  // A frame of the right length and identifier whose body is garbage.
  AckMsg ack;
  ack.ranges.push_back({0, 0, 1, 1});
  std::vector<std::uint8_t> bad = encodeMessage(ack);
  for (std::size_t i = 12; i < bad.size(); ++i) bad[i] ^= 0x5A;
  peer->send(bad);
  EXPECT_TRUE(peer->closedByServer());
  f.expectOnlyCause(DisconnectCause::Malformed, 1);
  EXPECT_EQ(f.stats().rejectedMessages[std::size_t(DisconnectCause::Malformed)], 1u);
  f.expectGoodClientUnaffected();
}

TEST(NetHostile, OversizedFrameIsRefusedBeforeItsBodyArrives) {
  NetServerOptions o;
  o.maxMessageBytes = 64 << 10;
  HostileFixture f(o);
  // Past the handshake: a prefix announcing 1 MiB and nothing after it. The server must close
  // on the prefix alone (it never waits for, or allocates, the body).
  auto peer = joinedPeer(f.port());
  const std::uint32_t announced = 1u << 20;
  std::vector<std::uint8_t> prefix(4);
  std::memcpy(prefix.data(), &announced, 4);
  peer->send(prefix);
  EXPECT_TRUE(peer->closedByServer(5.0));
  // Before the Hello the cap is 4 KiB: a 5 KiB prefix is refused the same way.
  RawPeer early(f.port());
  const std::uint32_t five = 5u << 10;
  std::memcpy(prefix.data(), &five, 4);
  early.send(prefix);
  EXPECT_TRUE(early.closedByServer(5.0));
  f.expectOnlyCause(DisconnectCause::Oversized, 2);
  f.expectGoodClientUnaffected();
}

TEST(NetHostile, ClientThatNeverReadsIsDisconnected) {
  NetServerOptions o;
  o.writeStallSeconds = 1.0;
  o.maxWriteQueueBytes = 1u << 20;
  // Sent at the ceiling (4 MB/s), not at congestion control's start rate of 1 Mbit/s, which
  // a client that never acks never raises: the kernel's send buffer fills in a second.
  o.sender.congestionControl = false;
  HostileFixture f(o);
  // A tiny receive window, datagrams over TCP, and no reads: the server's writes stall.
  RawPeer sloth(f.port(), 4096);
  sloth.send(helloFrame(kToken, false));
  f.expectOnlyCause(DisconnectCause::NotReading, 1);
  f.expectGoodClientUnaffected();
}

TEST(NetHostile, ClientThatNeverSpeaksIsDisconnected) {
  NetServerOptions o;
  o.helloTimeout = 0.5;
  o.silenceTimeout = 1.0;  // the good client acks far more often than this
  HostileFixture f(o);
  // Connected, nothing sent: no Hello in time.
  RawPeer mute(f.port());
  EXPECT_TRUE(mute.closedByServer(5.0));
  // Past the handshake, then silent (no acks, no poses).
  auto silent = joinedPeer(f.port());
  EXPECT_TRUE(silent->closedByServer(5.0));
  // The counts reach stats() with the next poll.
  EXPECT_TRUE(waitFor([&] { return f.stats().disconnected >= 2; }, 5.0));
  const NetServerStats s = f.stats();
  EXPECT_EQ(s.disconnectsBy(DisconnectCause::HelloTimeout), 1u);
  EXPECT_EQ(s.disconnectsBy(DisconnectCause::Silent), 1u);
  EXPECT_EQ(s.disconnected, 2u);
  f.expectGoodClientUnaffected();
}

TEST(NetHostile, MessagesOnlyTheServerSendsAreRefused) {
  HostileFixture f;
  // A client posing as the server: scene state, session info, a Welcome, and a datagram frame.
  SceneStateMsg state;
  state.animationTime = 1.0;
  SessionInfoMsg info;
  std::vector<std::vector<std::uint8_t>> frames = {encodeMessage(state), encodeMessage(info),
                                                   encodeMessage(WelcomeMsg{kProtocolVersion, 1})};
  std::vector<std::uint8_t> datagramBytes(40, 0);
  std::memcpy(datagramBytes.data() + 4, "PCDG", 4);  // identifier at the datagram's offset 4
  frames.push_back(datagramFrame(datagramBytes));
  for (const auto& frame : frames) {
    auto peer = joinedPeer(f.port());
    peer->send(frame);
    EXPECT_TRUE(peer->closedByServer());
  }
  f.expectOnlyCause(DisconnectCause::WrongDirection, 4);
  f.expectGoodClientUnaffected();
}

TEST(NetHostile, MessagesOutOfOrderAreRefused) {
  HostileFixture f;
  // An ack before any Hello.
  RawPeer first(f.port());
  AckMsg ack;
  first.send(encodeMessage(ack));
  EXPECT_TRUE(first.closedByServer());
  // A second Hello (a client trying to become another session on the same connection).
  auto twice = joinedPeer(f.port());
  twice->send(helloFrame(kToken));
  EXPECT_TRUE(twice->closedByServer());
  f.expectOnlyCause(DisconnectCause::Protocol, 2);
  f.expectGoodClientUnaffected();
}

TEST(NetHostile, AcksAndRepairsBeyondTheFieldAreRefused) {
  HostileFixture f;
  // Ranges outside the field, an ack covering the field many times over (work a client could
  // multiply at will), a repair request naming more bricks than the field holds, and fragment
  // gaps of a brick outside the field.
  AckMsg outside;
  outside.ranges.push_back({0, 1u << 30, 5, 1});
  AckMsg repeated;
  for (int i = 0; i < 64; ++i) repeated.ranges.push_back({0, 0, 64, 1});
  std::size_t fieldBricks = 0;
  for (const gpu::CascadeDesc& c : builtinInfo().cascades)
    fieldBricks +=
        std::size_t((c.counts.x + 3) / 4 * ((c.counts.y + 3) / 4) * ((c.counts.z + 3) / 4));
  RepairRequestMsg repair;  // within the frame cap (16 bytes a brick), over the field
  repair.bricks.assign(fieldBricks + 1, BrickRefMsg{0, 0, 0});
  AckMsg gap;  // fragments missing from an update of a brick the field does not have
  gap.gaps.push_back(FragmentGapMsg{1, 0, std::uint32_t(fieldBricks) + 7, 2, 0, 4, {1, 2}});
  for (const auto& frame : {encodeMessage(outside), encodeMessage(repeated), encodeMessage(repair),
                            encodeMessage(gap)}) {
    auto peer = joinedPeer(f.port());
    peer->send(frame);
    EXPECT_TRUE(peer->closedByServer());
  }
  f.expectOnlyCause(DisconnectCause::Invalid, 4);
  f.expectGoodClientUnaffected();
}

TEST(NetHostileServer, HugeFieldLayoutIsRefusedBeforeAllocating) {
  // One cascade of 253 x 253 x 61 probes: 4M slots, within what mirrorField accepts, so only
  // the memory cap stands between this message and about 40 GiB of allocations.
  SessionInfoMsg info = builtinInfo();
  info.cascades.resize(1);
  info.cascades[0].counts = glm::ivec3(253, 253, 61);
  info.cascades[0].scroll = glm::ivec3(0);
  const std::uint64_t needed = mirrorMemoryBytes(info);
  EXPECT_GT(needed, std::uint64_t(30) << 30);
  FakeServer fake(info);
  client::FieldMirror mirror;
  client::NetClient client(mirror, goodOptions(fake.port()));
  client.start();
  ASSERT_TRUE(waitFor([&] { return !client.stats().lastError.empty(); }, 10.0));
  const client::NetClientStats s = client.stats();
  std::printf("client error: %s\n", s.lastError.c_str());
  EXPECT_NE(s.lastError.find("mirror memory"), std::string::npos);
  EXPECT_NE(s.lastError.find(std::to_string((needed + (1u << 20) - 1) >> 20) + " MiB"),
            std::string::npos);
  EXPECT_NE(s.lastError.find("1024 MiB"), std::string::npos);  // the default cap
  EXPECT_EQ(s.sessions, 0u);
  EXPECT_EQ(s.layoutResets, 0u);
  EXPECT_FALSE(mirror.present());
}

TEST(NetHostileServer, MirrorCapIsExact) {
  const SessionInfoMsg info = builtinInfo();
  const std::uint64_t needed = mirrorMemoryBytes(info);
  std::printf("built-in field: %.1f MiB of mirror memory\n", double(needed) / (1 << 20));
  FakeServer fake(info);
  {
    // One byte under what the layout needs: refused.
    client::FieldMirror mirror;
    auto o = goodOptions(fake.port());
    o.maxMirrorBytes = needed - 1;
    client::NetClient client(mirror, o);
    client.start();
    ASSERT_TRUE(waitFor([&] { return !client.stats().lastError.empty(); }, 10.0));
    EXPECT_NE(client.stats().lastError.find("mirror memory"), std::string::npos);
    EXPECT_EQ(client.stats().sessions, 0u);
  }
  {
    // Exactly enough: the session starts and the mirror takes the layout.
    client::FieldMirror mirror;
    auto o = goodOptions(fake.port());
    o.maxMirrorBytes = needed;
    client::NetClient client(mirror, o);
    client.start();
    ASSERT_TRUE(waitFor([&] { return client.stats().sessions >= 1; }, 10.0));
    EXPECT_TRUE(mirror.present());
  }
}

}  // namespace
}  // namespace pc::nettest
