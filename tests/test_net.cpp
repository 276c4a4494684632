// Server and client over real sockets on loopback: the in-process server (field thread and
// network thread as probecast-server runs them) and NetClient feeding a FieldMirror, without a
// renderer (test_net_restart covers the real headless client). Convergence means the mirror
// equals the server's frozen field through the codec's quantization, brick for brick.
#include <gtest/gtest.h>

#include <cmath>

#include "test_net_support.h"

namespace pc::nettest {
namespace {

client::NetClientOptions clientOptions(const TestServer& server) {
  client::NetClientOptions o;
  o.host = "127.0.0.1";
  o.port = server.port();
  o.serverFingerprint = server.fingerprint();
  o.token = kToken;
  o.name = "test";
  return o;
}

// Waits for the frozen server and the converged mirror; prints how long convergence took.
void expectConverges(TestServer& server, const client::FieldMirror& mirror, double limit,
                     const char* what) {
  const double start = steadySeconds();
  ASSERT_TRUE(waitFor([&] { return server.frozen(); }, 30.0)) << "the server never froze";
  int differing = -1;
  const bool converged = waitFor(
      [&] {
        differing = mirrorDifference(mirror, server.field());
        return differing == 0;
      },
      limit);
  std::printf("%s: converged %.2f s after the freeze (%d bricks differing at the end)\n", what,
              steadySeconds() - start, differing);
  EXPECT_TRUE(converged) << differing << " bricks still differ";
}

TEST(Net, ClientMirrorConvergesToServerFieldOverUdp) {
  TestServer server(1.0);
  client::FieldMirror mirror;
  client::NetClient client(mirror, clientOptions(server));
  client.start();
  expectConverges(server, mirror, 15.0, "udp");
  const client::NetClientStats s = client.stats();
  EXPECT_TRUE(s.synced);
  EXPECT_EQ(s.sessions, 1u);
  EXPECT_GT(s.udpDatagrams, 0u);
  EXPECT_EQ(s.tcpDatagrams, 0u);
  EXPECT_GE(s.lastResyncSeconds, 0.0);
  std::printf("udp: %.1f kB over UDP, %.1f kB over TCP, synced %.3f s after connecting\n",
              s.udpBytes / 1e3, s.tcpBytes / 1e3, s.lastResyncSeconds);
  // The client's clock follows the server's frozen animation clock. It learns that the clock
  // stopped from the second scene state at the frozen time (the first still shows it moving),
  // so it may run on for one tick after the freeze; then it stays at the freeze time.
  ASSERT_TRUE(client.animationTime().has_value());
  const auto clockAtFreeze = [&] { return std::abs(*client.animationTime() - 1.0) < 1e-3; };
  EXPECT_TRUE(waitFor(clockAtFreeze, 5.0)) << "clock at " << *client.animationTime();
  sleepFor(0.3);
  EXPECT_NEAR(*client.animationTime(), 1.0, 1e-3) << "the clock ran on past the frozen server's";
}

// Datagram sessions polled, sealed and sent by several threads at once (NetWorkers), while
// the field thread keeps publishing until the freeze: every client's mirror ends brick for
// brick equal to the server's field, so no thread's datagrams were lost to another's, sealed
// with another session's key or built from a half-published brick.
TEST(Net, SeveralSendThreadsServeEveryClientExactly) {
  NetServerOptions net;
  net.sendThreads = 4;
  // All clients hold the test's one token, from one address.
  net.maxSessionsPerClient = 0;
  net.handshakesPerSecondPerAddress = 0;
  TestServer server(1.0, net);
  constexpr int kClients = 8;
  std::vector<std::unique_ptr<client::FieldMirror>> mirrors;
  std::vector<std::unique_ptr<client::NetClient>> clients;
  for (int i = 0; i < kClients; ++i) {
    mirrors.push_back(std::make_unique<client::FieldMirror>());
    client::NetClientOptions o = clientOptions(server);
    o.name = "test-" + std::to_string(i);
    clients.push_back(std::make_unique<client::NetClient>(*mirrors.back(), o));
    clients.back()->start();
  }
  for (int i = 0; i < kClients; ++i) {
    SCOPED_TRACE("client " + std::to_string(i));
    expectConverges(server, *mirrors[std::size_t(i)], 20.0, "several send threads");
    const client::NetClientStats s = clients[std::size_t(i)]->stats();
    EXPECT_TRUE(s.synced);
    EXPECT_GT(s.udpDatagrams, 0u);
    EXPECT_EQ(s.tcpDatagrams, 0u);
  }
}

TEST(Net, ClientMirrorConvergesInTcpOnlyMode) {
  TestServer server(1.0);
  client::FieldMirror mirror;
  auto o = clientOptions(server);
  o.tcpOnly = true;
  client::NetClient client(mirror, o);
  client.start();
  expectConverges(server, mirror, 15.0, "tcp-only");
  const client::NetClientStats s = client.stats();
  EXPECT_GT(s.tcpDatagrams, 0u);
  EXPECT_EQ(s.udpDatagrams, 0u);
}

TEST(Net, ConvergesThroughFaultyUdpRelayOnceFaultsStop) {
  // Faults while the field still moves (3 s), then a calm link and a frozen field.
  TestServer server(3.0);
  UdpRelay relay;
  FaultProfile faults;
  faults.loss = 0.3;
  faults.burstStart = 0.02;
  faults.duplicate = 0.1;
  faults.reorder = 0.2;
  faults.corrupt = 0.05;
  faults.delay = 0.01;
  faults.jitter = 0.01;
  relay.setProfile(faults);
  client::FieldMirror mirror;
  auto o = clientOptions(server);
  o.udpAdvertisePort = relay.port();  // the server sends to the relay
  client::NetClient client(mirror, o);
  client.start();
  relay.setTarget(client.udpPort());  // which passes datagrams on to the client

  ASSERT_TRUE(waitFor([&] { return server.frozen(); }, 30.0));
  FaultProfile calm;
  calm.delay = 0.005;
  relay.setProfile(calm);
  const LinkStats during = relay.stats();
  std::printf(
      "relay during faults: %llu datagrams, %llu lost, %llu duplicated, %llu reordered, "
      "%llu corrupted\n",
      (unsigned long long)during.sent, (unsigned long long)during.lost,
      (unsigned long long)during.duplicated, (unsigned long long)during.reordered,
      (unsigned long long)during.corrupted);
  EXPECT_GT(during.lost, 0u);
  EXPECT_GT(during.corrupted, 0u);
  expectConverges(server, mirror, 15.0, "faulty relay");
  const client::NetClientStats s = client.stats();
  // Corrupted datagrams fail the seal's authentication, duplicates its replay window.
  EXPECT_GT(s.unsealedRefused, 0u) << "corrupted datagrams should have been refused";
  EXPECT_EQ(s.sessions, 1u) << "faults on the datagram path never end the session";
}

TEST(Net, BadTokenGetsOnlyAReject) {
  TestServer server(0.5);
  RawPeer peer(server.port());
  peer.send(helloFrame("wrong-token"));
  auto frame = peer.readFrame();
  ASSERT_TRUE(frame.has_value());
  auto message = decodeMessage(*frame);
  ASSERT_TRUE(message.ok());
  ASSERT_TRUE(std::holds_alternative<RejectMsg>(*message));
  std::printf("reject reason: %s\n", std::get<RejectMsg>(*message).reason.c_str());
  // Nothing follows the Reject: the stream ends.
  EXPECT_FALSE(peer.readFrame(3.0).has_value());

  // A NetClient with the wrong token never gets a brick and keeps being rejected.
  client::FieldMirror mirror;
  auto o = clientOptions(server);
  o.token = "also-wrong";
  client::NetClient client(mirror, o);
  client.start();
  ASSERT_TRUE(waitFor([&] { return client.stats().rejects >= 2; }, 10.0));
  const client::NetClientStats s = client.stats();
  EXPECT_EQ(s.sessions, 0u);
  EXPECT_EQ(s.udpDatagrams, 0u);
  EXPECT_EQ(s.bricksApplied, 0u);
  EXPECT_FALSE(mirror.present());
  EXPECT_TRUE(waitFor([&] { return server.net().stats().rejected >= 3; }, 2.0));
}

TEST(Net, MisbehavingClientsAreDisconnectedWhileAnotherKeepsReceiving) {
  TestServer server(-1.0);  // never frozen: the good client keeps getting updates
  client::FieldMirror mirror;
  client::NetClient good(mirror, clientOptions(server));
  good.start();
  ASSERT_TRUE(waitFor([&] { return good.stats().synced; }, 20.0));

  // Garbage instead of a Hello.
  RawPeer garbage(server.port());
  std::vector<std::uint8_t> junk(64, 0xAB);
  junk[0] = 60, junk[1] = junk[2] = junk[3] = 0;
  garbage.send(junk);
  EXPECT_TRUE(garbage.closedByServer());

  // A frame announcing far more than any message may hold.
  RawPeer oversized(server.port());
  oversized.send({0xFF, 0xFF, 0xFF, 0x7F, 1, 2, 3, 4});
  EXPECT_TRUE(oversized.closedByServer());

  // A protocol version nobody speaks: a Reject naming it.
  RawPeer future(server.port());
  future.send(helloFrame(kToken, false, 999));
  auto reject = future.readFrame();
  ASSERT_TRUE(reject.has_value());
  auto rejectMessage = decodeMessage(*reject);
  ASSERT_TRUE(rejectMessage.ok());
  EXPECT_TRUE(std::holds_alternative<RejectMsg>(*rejectMessage));

  // A valid session that then sends a corrupt message (a flipped byte inside an Ack).
  RawPeer corrupt(server.port());
  corrupt.send(helloFrame(kToken));
  auto welcome = corrupt.readFrame();
  ASSERT_TRUE(welcome.has_value());
  ASSERT_TRUE(decodeMessage(*welcome).ok());
  AckMsg ack;
  ack.full = true;
  ack.ranges.push_back({0, 0, 1, 1});
  std::vector<std::uint8_t> bad = encodeMessage(ack);
  for (std::size_t i = 8; i < bad.size(); ++i) bad[i] ^= 0x5A;
  corrupt.send(bad);
  EXPECT_TRUE(corrupt.closedByServer());

  // An authenticated client acknowledging bricks that do not exist.
  RawPeer outOfRange(server.port());
  outOfRange.send(helloFrame(kToken));
  ASSERT_TRUE(outOfRange.readFrame().has_value());
  AckMsg wild;
  wild.ranges.push_back({0, 1u << 30, 5, 1});
  outOfRange.send(encodeMessage(wild));
  EXPECT_TRUE(outOfRange.closedByServer());

  // The good client noticed none of it: still its first session, still receiving.
  const std::uint64_t before = good.stats().udpDatagrams;
  ASSERT_TRUE(waitFor([&] { return good.stats().udpDatagrams > before + 5; }, 5.0));
  const client::NetClientStats s = good.stats();
  EXPECT_TRUE(s.connected);
  EXPECT_EQ(s.sessions, 1u);
  // The server counts a peer as disconnected when it removes the session, which can trail
  // what the peer saw (its socket closed, or a Reject read): wait for the count (it read 4
  // here about once in 40 runs on two busy cores).
  EXPECT_TRUE(waitFor([&] { return server.net().stats().disconnected >= 5u; }, 5.0));
  const NetServerStats ss = server.net().stats();
  EXPECT_EQ(ss.clients.size(), 1u);
  EXPECT_GE(ss.disconnected, 5u);
  (void)ss;
}

TEST(Net, ClientThatNeverReadsIsDisconnected) {
  NetServerOptions o;
  o.writeStallSeconds = 1.0;
  o.maxWriteQueueBytes = 1u << 20;
  TestServer server(-1.0, o);
  // A tiny receive window and no reads: the server's writes stall.
  RawPeer sloth(server.port(), 4096);
  sloth.send(helloFrame(kToken, false));
  ASSERT_TRUE(waitFor([&] { return server.net().stats().disconnected >= 1; }, 20.0));
  EXPECT_EQ(server.net().stats().clients.size(), 0u);
}

}  // namespace
}  // namespace pc::nettest
