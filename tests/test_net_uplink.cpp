// Acks over UDP (protocol version 6, PROTOCOL.md "Acks over UDP") against a real server and
// client over loopback: a client's acks and repair requests leave as sealed datagrams once
// its session's UDP path works, and the server takes them as it takes them from the stream;
// forged, replayed and stray datagrams change nothing; TCP-only sessions keep acking over the
// stream; and acks lost on the way cost a delay, not the session.
#include <gtest/gtest.h>

#include <algorithm>

#include "protocol/datagram_seal.h"
#include "protocol/uplink_datagram.h"
#include "test_net_support.h"

namespace pc::nettest {
namespace {

namespace asio = boost::asio;
using asio::ip::udp;
using Bytes = std::vector<std::uint8_t>;

// The client holds the server's field exactly, once it froze.
bool converged(TestServer& server, const client::FieldMirror& mirror, double limit) {
  return waitFor([&] { return server.frozen() && mirrorDifference(mirror, server.field()) == 0; },
                 limit);
}

// A client of `server` whose acks pass `uplink` on their way to the server's UDP port.
struct AckingClient {
  AckingClient(TestServer& server, UdpRelay& uplink, const std::string& name) {
    uplink.setTarget(server.net().udpPort());
    client::NetClientOptions o = secureClientOptions(server, name);
    o.udpServerPort = uplink.port();
    client = std::make_unique<client::NetClient>(mirror, o);
    client->start();
  }
  client::FieldMirror mirror;
  std::unique_ptr<client::NetClient> client;
};

NetClientInfo onlyClient(TestServer& server) {
  const NetServerStats s = server.net().stats();
  EXPECT_EQ(s.clients.size(), 1u);
  return s.clients.empty() ? NetClientInfo{} : s.clients[0];
}

std::uint64_t dropped(TestServer& server, UplinkDrop cause) {
  return server.net().stats().uplinkDrops[std::size_t(cause)];
}

// Sends each datagram to the server's UDP port, paced so that none is lost in a socket buffer.
void sendTo(std::uint16_t port, const std::vector<Bytes>& datagrams) {
  asio::io_context io;
  udp::socket socket(io, udp::endpoint(udp::v4(), 0));
  const udp::endpoint target(asio::ip::make_address("127.0.0.1"), port);
  std::size_t sent = 0;
  for (const Bytes& d : datagrams) {
    socket.send_to(asio::buffer(d), target);
    if (++sent % 16 == 0) sleepFor(0.005);
  }
}

TEST(NetUplink, AcksTravelAsSealedDatagramsAndTheSessionConverges) {
  TestServer server(1.0);
  UdpRelay uplink;  // on the acks' path, to see them as an observer would
  uplink.capture(true);
  AckingClient acker(server, uplink, "udp-acker");
  client::NetClient& client = *acker.client;
  ASSERT_TRUE(converged(server, acker.mirror, 30.0));
  const NetClientInfo synced = onlyClient(server);
  sleepFor(2.5);  // two full acks and about a hundred changes-only acks more
  const NetClientInfo later = onlyClient(server);
  std::printf("acks over UDP %llu -> %llu, over TCP %llu -> %llu; client sent %llu datagrams\n",
              (unsigned long long)synced.acksUdp, (unsigned long long)later.acksUdp,
              (unsigned long long)synced.acksTcp, (unsigned long long)later.acksTcp,
              (unsigned long long)client.stats().uplinkDatagrams);
  EXPECT_GT(synced.acksUdp, 0u);
  EXPECT_GE(later.acksUdp, synced.acksUdp + 2) << "the full acks go over UDP too";
  EXPECT_EQ(later.acksTcp, synced.acksTcp) << "an ack went over the stream once UDP worked";
  EXPECT_LE(synced.acksTcp, 1u) << "only an ack before the first datagram may take the stream";
  for (std::size_t c = 0; c < kUplinkDropCount; ++c)
    EXPECT_EQ(server.net().stats().uplinkDrops[c], 0u) << uplinkDropName(UplinkDrop(c));
  // On the path: sealed, and nothing of the message in clear.
  const auto seen = uplink.captured();
  ASSERT_GT(seen.size(), 10u);
  for (const Bytes& d : seen) {
    ASSERT_GE(d.size(), kSealOverheadBytes);
    EXPECT_EQ(std::string(d.begin(), d.begin() + 4), "PCSD");
    EXPECT_LE(d.size(), kMaxUplinkDatagramBytes);
    const std::string text(d.begin(), d.end());
    EXPECT_EQ(text.find("PCSM"), std::string::npos) << "a session message in clear";
  }
  EXPECT_TRUE(client.stats().connected);
  EXPECT_EQ(client.stats().sessions, 1u);
}

TEST(NetUplink, ForgedAndReplayedAckDatagramsAreDroppedAndTheVictimIsUnaffected) {
  TestServer server(1.0);
  UdpRelay uplink;  // the victim's acks pass it: what an attacker on the path could copy
  uplink.capture(true);
  AckingClient acker(server, uplink, "victim");
  client::NetClient& victim = *acker.client;
  const client::FieldMirror& mirror = acker.mirror;
  ASSERT_TRUE(converged(server, mirror, 30.0));
  sleepFor(0.5);
  const std::uint32_t sessionId = onlyClient(server).sessionId;
  const client::NetClientStats before = victim.stats();
  const NetClientInfo serverBefore = onlyClient(server);

  // The ack that would hurt: "I hold nothing" (a full ack without ranges) makes the sender
  // send the whole field again. Sealed under a key nobody of the session holds, with the
  // victim's session id and counters far ahead; in the plain form; for an unknown session;
  // and cut short.
  AckMsg nothingHeld;
  nothingHeld.full = true;
  const Bytes frame = encodeMessage(nothingHeld);
  DatagramKey wrongKey{};
  wrongKey[0] = 0x5A;
  UplinkWriter forger(wrongKey, sessionId);
  UplinkWriter plain(std::nullopt, sessionId);
  UplinkWriter stranger(wrongKey, sessionId + 1);
  std::vector<Bytes> forged, inClear, unknown, cut;
  for (int i = 0; i < 40; ++i) {
    forged.push_back(forger.wrap(frame).value());
    inClear.push_back(plain.wrap(frame).value());
    unknown.push_back(stranger.wrap(frame).value());
    cut.push_back(Bytes(forged.back().begin(), forged.back().begin() + 10));
  }
  sendTo(server.net().udpPort(), forged);
  sendTo(server.net().udpPort(), inClear);
  sendTo(server.net().udpPort(), unknown);
  sendTo(server.net().udpPort(), cut);
  // And the victim's own ack datagrams again, exactly as they passed: replays.
  auto seen = uplink.captured();
  seen.resize(std::min<std::size_t>(seen.size(), 60));
  ASSERT_GT(seen.size(), 20u);
  sendTo(server.net().udpPort(), seen);

  ASSERT_TRUE(waitFor(
      [&] {
        return dropped(server, UplinkDrop::Forged) >= forged.size() &&
               dropped(server, UplinkDrop::WrongMode) >= inClear.size() &&
               dropped(server, UplinkDrop::UnknownSession) >= unknown.size() &&
               dropped(server, UplinkDrop::Malformed) >= cut.size() &&
               dropped(server, UplinkDrop::Replayed) + dropped(server, UplinkDrop::TooOld) >=
                   seen.size();
      },
      10.0))
      << "forged " << dropped(server, UplinkDrop::Forged) << ", wrong mode "
      << dropped(server, UplinkDrop::WrongMode) << ", unknown "
      << dropped(server, UplinkDrop::UnknownSession) << ", malformed "
      << dropped(server, UplinkDrop::Malformed) << ", replayed "
      << dropped(server, UplinkDrop::Replayed) << ", too old "
      << dropped(server, UplinkDrop::TooOld);
  EXPECT_EQ(dropped(server, UplinkDrop::Forged), forged.size());
  EXPECT_EQ(dropped(server, UplinkDrop::WrongMode), inClear.size());
  EXPECT_EQ(dropped(server, UplinkDrop::UnknownSession), unknown.size());
  EXPECT_EQ(dropped(server, UplinkDrop::Malformed), cut.size());
  sleepFor(1.5);  // a full ack's time: the forged one would have made the field go out again
  const client::NetClientStats after = victim.stats();
  const NetClientInfo serverAfter = onlyClient(server);
  EXPECT_TRUE(after.connected);
  EXPECT_EQ(after.sessions, 1u);
  EXPECT_EQ(mirrorDifference(mirror, server.field()), 0);
  // Nothing was sent again: the sender never took the forged "nothing held".
  EXPECT_EQ(after.receiver.stale, before.receiver.stale) << "bricks the victim held came again";
  EXPECT_EQ(serverAfter.resends, serverBefore.resends);
  EXPECT_GT(serverAfter.acksUdp, serverBefore.acksUdp) << "the victim's own acks still count";
}

TEST(NetUplink, WithoutAUdpPathAcksStayOnTheStream) {
  // Datagrams framed over TCP: asked by the client, and imposed by a --tcp-only server.
  for (const bool serverTcpOnly : {false, true}) {
    SCOPED_TRACE(serverTcpOnly ? "server --tcp-only" : "client tcpOnly");
    NetServerOptions net;
    net.tcpOnly = serverTcpOnly;
    TestServer server(1.0, net);
    client::FieldMirror mirror;
    client::NetClientOptions o = secureClientOptions(server, "tcp-acker");
    o.tcpOnly = !serverTcpOnly;
    client::NetClient client(mirror, o);
    client.start();
    ASSERT_TRUE(converged(server, mirror, 30.0));
    sleepFor(1.2);
    const NetClientInfo info = onlyClient(server);
    EXPECT_FALSE(info.udp);
    EXPECT_GT(info.acksTcp, 2u);
    EXPECT_EQ(info.acksUdp, 0u);
    EXPECT_EQ(client.stats().uplinkDatagrams, 0u);
  }
}

TEST(NetUplink, LostAckDatagramsCostADelayNotTheSession) {
  TestServer server(2.0);  // changing for two seconds: acks under loss while bricks flow
  UdpRelay uplink(11);
  FaultProfile lossy;
  lossy.loss = 0.3;
  lossy.delay = 0.005;
  uplink.setProfile(lossy);
  AckingClient acker(server, uplink, "lossy-acker");
  client::NetClient& client = *acker.client;
  ASSERT_TRUE(converged(server, acker.mirror, 40.0))
      << "bricks differing: " << mirrorDifference(acker.mirror, server.field());
  const LinkStats link = uplink.stats();
  const NetClientInfo info = onlyClient(server);
  std::printf(
      "uplink: %llu sent, %llu lost; server took %llu acks over UDP, %llu over TCP, "
      "%llu resends; loss share seen %.3f\n",
      (unsigned long long)link.sent, (unsigned long long)link.lost,
      (unsigned long long)info.acksUdp, (unsigned long long)info.acksTcp,
      (unsigned long long)info.resends, info.report.loss);
  EXPECT_GT(link.lost, 5u);
  EXPECT_GT(info.acksUdp, 20u);
  EXPECT_EQ(client.stats().sessions, 1u);
}

TEST(NetUplink, PlainSessionsAckOverUdpFromTheirOwnAddressOnly) {
  NetServerOptions net;
  net.tls.enabled = false;
  TestServer server(1.0, net);
  client::FieldMirror mirror;
  client::NetClientOptions o = secureClientOptions(server, "plain-acker");
  o.tls = false;
  client::NetClient client(mirror, o);
  client.start();
  ASSERT_TRUE(converged(server, mirror, 30.0));
  sleepFor(1.2);
  const NetClientInfo info = onlyClient(server);
  EXPECT_GT(info.acksUdp, 10u);
  // A plain ack from another address (on Linux all of 127/8 is loopback) is not the client's.
  AckMsg nothingHeld;
  nothingHeld.full = true;
  UplinkWriter other(std::nullopt, info.sessionId);
  const Bytes d = other.wrap(encodeMessage(nothingHeld)).value();
  asio::io_context io;
  udp::socket socket(io, udp::endpoint(asio::ip::make_address("127.0.0.2"), 0));
  socket.send_to(asio::buffer(d),
                 udp::endpoint(asio::ip::make_address("127.0.0.1"), server.net().udpPort()));
  ASSERT_TRUE(waitFor([&] { return dropped(server, UplinkDrop::WrongSender) == 1; }, 5.0));
  EXPECT_EQ(client.stats().sessions, 1u);
}

}  // namespace
}  // namespace pc::nettest
