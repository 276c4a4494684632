// The client session state machine (protocol/client_session.h) in memory, against the real
// server-side objects (FieldPublisher, StreamSender) and hand-made hostile messages: the
// handshake, a Reject, the memory cap on layouts, malformed frames, timeouts, datagrams before
// the layout, poses, the clock, a lossy link, and a new session after the first.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "protocol/client_session.h"
#include "protocol/datagram.h"
#include "protocol/fault_link.h"
#include "protocol/field_publisher.h"
#include "protocol/net_framing.h"
#include "protocol/stream_sender.h"
#include "test_protocol_support.h"

namespace pc {
namespace {

using Bytes = std::vector<std::uint8_t>;

constexpr double kStep = 0.005;

Bytes concat(std::initializer_list<Bytes> frames) {
  Bytes out;
  for (const Bytes& f : frames) out.insert(out.end(), f.begin(), f.end());
  return out;
}

std::string mib(std::uint64_t bytes) {
  return std::to_string((bytes + (1u << 20) - 1) >> 20) + " MiB";
}

// A server's side of one session, as probecast-server holds it: a publisher of a changing
// synthetic field and the client's StreamSender.
struct InMemoryServer {
  explicit InMemoryServer(std::uint32_t id, int updates = 1)
      : field(test::makeSyntheticLayout()), rng(id), sessionId(id) {
    for (int i = 0; i < updates; ++i) test::evolveField(field, rng, 1.0f, float(i));
    publisher = std::make_unique<FieldPublisher>(field);
    EXPECT_TRUE(publisher->publish(field, 0.0).ok());
    sender = std::make_unique<StreamSender>(*publisher, sessionId);
  }

  // What the server writes after a good Hello: Welcome, SessionInfo, a SceneState.
  Bytes handshake(double animationTime = 1.5) const {
    SceneStateMsg scene;
    scene.animationTime = animationTime;
    scene.fieldVersion = field.version;
    scene.publishTime = 0.0;
    return concat({encodeMessage(WelcomeMsg{kProtocolVersion, sessionId}),
                   encodeMessage(publisher->sessionInfo()), encodeMessage(scene)});
  }

  int bricks() const {
    int n = 0;
    for (const auto& c : field.brickVersions) n += int(c.size());
    return n;
  }

  Field field;
  std::mt19937 rng;
  std::uint32_t sessionId;
  std::unique_ptr<FieldPublisher> publisher;
  std::unique_ptr<StreamSender> sender;
};

// One step of a lossless exchange: the server's datagrams to the session (over UDP, or framed
// into the TCP stream), the session's frames back to the sender. Returns the session's
// frames' messages.
std::vector<SessionMessage> exchange(InMemoryServer& server, ClientSession& session, double t,
                                     bool overTcp = false) {
  for (Bytes& d : server.sender->poll(t)) {
    if (overTcp) {
      EXPECT_TRUE(session.onStreamBytes(datagramFrame(d), t).ok());
    } else {
      (void)session.onDatagram(d, t);
    }
  }
  std::vector<SessionMessage> sent;
  auto frames = session.poll(t);
  EXPECT_TRUE(frames.ok()) << frames.error().message;
  if (!frames) return sent;
  for (const Bytes& f : *frames) {
    EXPECT_TRUE(server.sender->onMessage(f, t).ok());
    auto m = decodeMessage(f);
    EXPECT_TRUE(m.ok());
    if (m) sent.push_back(std::move(m).value());
  }
  return sent;
}

// Connected and past the handshake of `server`, at time t.
void join(ClientSession& session, const InMemoryServer& server, double t) {
  session.connecting(t);
  (void)session.connected(t, 4000);
  ASSERT_TRUE(session.onStreamBytes(server.handshake(), t).ok()) << session.error();
  ASSERT_TRUE(session.streaming());
}

// Runs the exchange until the session holds every brick; returns the time it did.
double syncWith(InMemoryServer& server, ClientSession& session, double t, bool overTcp = false) {
  for (const double end = t + 10.0; t < end && !session.synced(); t += kStep)
    exchange(server, session, t, overTcp);
  EXPECT_TRUE(session.synced()) << session.bricksHeld() << " of " << session.bricksTotal();
  return t;
}

std::vector<SessionEvent::Kind> kinds(const std::vector<SessionEvent>& events) {
  std::vector<SessionEvent::Kind> out;
  for (const SessionEvent& e : events) out.push_back(e.kind);
  return out;
}

TEST(ClientSession, HandshakeThenStreamsUntilEveryBrickIsHeld) {
  const KeyPair keys = keyPairFromSeed({3});
  auto token =
      issueToken(keys.signing, newTokenClaims("test-client", "*", TokenRole::Viewer, 1, 1000, 60));
  ASSERT_TRUE(token.ok());
  ClientSessionOptions o;
  o.token = *token;
  o.name = "test-client";
  ClientSession session(o);
  EXPECT_EQ(session.phase(), SessionPhase::Idle);
  ASSERT_TRUE(session.poll(0.0).ok());
  EXPECT_TRUE(session.poll(0.0)->empty());

  session.connecting(0.0);
  EXPECT_EQ(session.phase(), SessionPhase::Connecting);
  auto hello = decodeMessage(session.connected(0.01, 4242));
  ASSERT_TRUE(hello.ok()) << hello.error().message;
  ASSERT_TRUE(std::holds_alternative<HelloMsg>(*hello));
  const HelloMsg& h = std::get<HelloMsg>(*hello);
  EXPECT_EQ(h.authToken, *token);
  EXPECT_EQ(h.clientName, "test-client");
  EXPECT_TRUE(h.wantsUdp);
  EXPECT_EQ(h.udpPort, 4242);
  const HelloVerdict verdict = checkHello(h, TokenVerifier({keys.verify}), "builtin", 1010);
  EXPECT_FALSE(verdict.reject.has_value()) << "the server's own check takes it";
  EXPECT_EQ(verdict.claims.client, "test-client");
  EXPECT_EQ(session.phase(), SessionPhase::AwaitingWelcome);

  // The handshake in pieces of 1 to 7 bytes: frames are put together across reads.
  InMemoryServer server(7);
  const Bytes bytes = server.handshake(1.5);
  std::vector<SessionEvent> events;
  for (std::size_t i = 0, n = 1; i < bytes.size(); i += n, n = n % 7 + 1) {
    const std::size_t take = std::min(n, bytes.size() - i);
    ASSERT_TRUE(session.onStreamBytes(std::span(bytes).subspan(i, take), 0.02).ok())
        << session.error();
    for (const SessionEvent& e : session.events()) events.push_back(e);
  }
  using K = SessionEvent::Kind;
  EXPECT_EQ(kinds(events), (std::vector<K>{K::Welcomed, K::Layout, K::SceneState}));
  ASSERT_EQ(events.size(), 3u);
  EXPECT_EQ(events[2].scene.animationTime, 1.5);
  EXPECT_EQ(events[2].scene.fieldVersion, server.field.version);
  EXPECT_EQ(session.phase(), SessionPhase::Streaming);
  EXPECT_EQ(session.sessionId(), 7u);
  EXPECT_EQ(session.bricksTotal(), server.bricks());
  EXPECT_EQ(session.bricksHeld(), 0);
  EXPECT_FALSE(session.synced());
  ASSERT_NE(session.receiver(), nullptr);
  EXPECT_EQ(session.info().fieldVersion, server.field.version);
  ASSERT_TRUE(session.clock().at(0.02).has_value());
  EXPECT_DOUBLE_EQ(*session.clock().at(0.02), 1.5);

  bool acked = false;
  double t = 0.02;
  for (; t < 10.0 && !session.synced(); t += kStep) {
    for (const SessionMessage& m : exchange(server, session, t))
      acked |= std::holds_alternative<AckMsg>(m);
  }
  ASSERT_TRUE(session.synced());
  EXPECT_TRUE(acked);
  EXPECT_GT(session.syncSeconds(), 0.0);
  EXPECT_LE(session.syncSeconds(), t);
  EXPECT_EQ(session.bricksHeld(), session.bricksTotal());
  EXPECT_EQ(session.stats().sessions, 1u);
  EXPECT_EQ(session.stats().badDatagrams, 0u);
  EXPECT_GT(session.stats().udpDatagrams, 0u);
  EXPECT_EQ(session.stats().tcpDatagrams, 0u);
  EXPECT_EQ(server.sender->stats().badMessages, 0u);
  EXPECT_EQ(test::differingBricks(session.receiver()->field(), test::quantizedCopy(server.field)),
            0);

  // Every brick changed once since the layout, and each is named once.
  const auto changed = session.takeChangedBricks();
  EXPECT_EQ(int(changed.size()), session.bricksTotal());
  EXPECT_EQ(int(std::set<std::pair<int, int>>(changed.begin(), changed.end()).size()),
            session.bricksTotal());
  EXPECT_TRUE(session.takeChangedBricks().empty());

  // A datagram the session handled is an event of its own.
  const auto heartbeat = server.sender->poll(t + 0.5);
  ASSERT_FALSE(heartbeat.empty());
  EXPECT_TRUE(session.onDatagram(heartbeat.front(), t + 0.5).ok());
  ASSERT_EQ(session.events().size(), 1u);
  EXPECT_EQ(session.events()[0].kind, SessionEvent::Kind::Datagram);
  EXPECT_TRUE(session.events()[0].status.ok());
}

TEST(ClientSession, TcpOnlySessionTakesDatagramsFromTheStream) {
  ClientSession session({});
  session.connecting(0.0);
  auto hello = decodeMessage(session.connected(0.0, 0));
  ASSERT_TRUE(hello.ok());
  EXPECT_FALSE(std::get<HelloMsg>(*hello).wantsUdp);
  EXPECT_EQ(std::get<HelloMsg>(*hello).udpPort, 0);
  InMemoryServer server(9);
  ASSERT_TRUE(session.onStreamBytes(server.handshake(), 0.0).ok());
  syncWith(server, session, 0.0, true);
  EXPECT_GT(session.stats().tcpDatagrams, 0u);
  EXPECT_EQ(session.stats().udpDatagrams, 0u);
  EXPECT_EQ(test::differingBricks(session.receiver()->field(), test::quantizedCopy(server.field)),
            0);
}

TEST(ClientSession, RejectEndsTheSessionWithTheServersReason) {
  ClientSession session({});
  session.connecting(0.0);
  (void)session.connected(0.0, 0);
  Status s = session.onStreamBytes(encodeMessage(RejectMsg{kProtocolVersion, "bad token"}), 0.1);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().message, "rejected: \"bad token\"");
  EXPECT_EQ(session.phase(), SessionPhase::Rejected);
  EXPECT_EQ(session.error(), "rejected: \"bad token\"");
  EXPECT_EQ(session.stats().rejects, 1u);
  EXPECT_EQ(session.receiver(), nullptr);
  // Ended: nothing more is read, and polls send nothing.
  EXPECT_FALSE(session.onStreamBytes(encodeMessage(WelcomeMsg{kProtocolVersion, 1}), 0.2).ok());
  ASSERT_TRUE(session.poll(5.0).ok());
  EXPECT_TRUE(session.poll(5.0)->empty());

  // A reason of megabytes is quoted only in part, its escapes escaped.
  session.connecting(1.0);
  (void)session.connected(1.0, 0);
  s = session.onStreamBytes(
      encodeMessage(RejectMsg{kProtocolVersion, "\x1b[2J" + std::string(100000, 'x')}), 1.0);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().message,
            "rejected: \"\\x1b[2J" + std::string(kMaxQuotedReasonBytes - 7, 'x') + "\"...(" +
                std::to_string(100000 - (kMaxQuotedReasonBytes - 7)) + " more bytes)");
  EXPECT_EQ(session.stats().rejects, 2u);
}

TEST(ClientSession, LayoutOverTheMemoryCapIsRefusedNamingBothSizes) {
  InMemoryServer server(3);
  const SessionInfoMsg info = server.publisher->sessionInfo();
  const std::uint64_t needed = mirrorMemoryBytes(info);
  ASSERT_GT(needed, std::uint64_t(4) << 20);  // several MiB: the sizes below differ
  auto attempt = [&](std::uint64_t cap) {
    ClientSessionOptions o;
    o.maxMirrorBytes = cap;
    auto session = std::make_unique<ClientSession>(o);
    session->connecting(0.0);
    (void)session->connected(0.0, 0);
    Status s = session->onStreamBytes(
        concat({encodeMessage(WelcomeMsg{kProtocolVersion, 3}), encodeMessage(info)}), 0.0);
    return std::make_pair(std::move(session), s);
  };
  {
    // Well under: both sizes are in the error, nothing is laid out.
    const std::uint64_t cap = needed / 2;
    auto [session, s] = attempt(cap);
    ASSERT_FALSE(s.ok());
    std::printf("refused: %s\n", s.error().message.c_str());
    EXPECT_NE(s.error().message.find("mirror memory"), std::string::npos);
    EXPECT_NE(s.error().message.find("needs about " + mib(needed)), std::string::npos);
    EXPECT_NE(s.error().message.find("cap of " + mib(cap)), std::string::npos);
    EXPECT_EQ(session->phase(), SessionPhase::Failed);
    EXPECT_EQ(session->receiver(), nullptr);
    EXPECT_EQ(session->stats().sessions, 0u);
    for (const SessionEvent& e : session->events()) EXPECT_NE(e.kind, SessionEvent::Kind::Layout);
  }
  {
    // One byte under: refused; exactly enough: taken.
    auto [under, s1] = attempt(needed - 1);
    EXPECT_FALSE(s1.ok());
    auto [exact, s2] = attempt(needed);
    EXPECT_TRUE(s2.ok()) << s2.error().message;
    EXPECT_TRUE(exact->streaming());
  }
  {
    // 253 x 253 x 61 probes: 4M slots, which mirrorField accepts; only the cap stands between
    // this layout and about 40 GiB of allocations.
    SessionInfoMsg huge = info;
    huge.cascades.resize(1);
    huge.cascades[0].counts = glm::ivec3(253, 253, 61);
    huge.cascades[0].scroll = glm::ivec3(0);
    const std::uint64_t hugeNeeds = mirrorMemoryBytes(huge);
    EXPECT_GT(hugeNeeds, std::uint64_t(30) << 30);
    ClientSession session({});
    session.connecting(0.0);
    (void)session.connected(0.0, 0);
    Status s = session.onStreamBytes(
        concat({encodeMessage(WelcomeMsg{kProtocolVersion, 3}), encodeMessage(huge)}), 0.0);
    ASSERT_FALSE(s.ok());
    EXPECT_NE(s.error().message.find(mib(hugeNeeds)), std::string::npos) << s.error().message;
    EXPECT_NE(s.error().message.find("cap of 1024 MiB"), std::string::npos) << s.error().message;
    EXPECT_EQ(session.receiver(), nullptr);
  }
}

// A session that has sent its Hello (and, with `welcomed`, had its Welcome), fed `bytes`:
// the error it ended with, or "" when it took them.
std::string refusal(const Bytes& bytes, bool welcomed) {
  ClientSession session({});
  session.connecting(0.0);
  (void)session.connected(0.0, 0);
  if (welcomed) {
    EXPECT_TRUE(session.onStreamBytes(encodeMessage(WelcomeMsg{kProtocolVersion, 5}), 0.0).ok());
  }
  Status s = session.onStreamBytes(bytes, 0.1);
  if (s.ok()) return "";
  EXPECT_EQ(session.phase(), SessionPhase::Failed);
  EXPECT_EQ(session.error(), s.error().message);
  return s.error().message;
}

TEST(ClientSession, MalformedAndHostileFramesAreRefusedWithClearErrors) {
  InMemoryServer server(5);
  const Bytes info = encodeMessage(server.publisher->sessionInfo());
  struct Case {
    const char* what;
    Bytes bytes;
    bool welcomed;
    std::string expected;  // part of the error
  };
  std::vector<Case> cases;

  // A prefix announcing 5 MiB: refused on its 4 bytes, before any body.
  const std::uint32_t big = 5u << 20;
  Bytes prefix(4);
  std::memcpy(prefix.data(), &big, 4);
  cases.push_back({"oversized frame", prefix, false, "bad frame from the server"});

  // The right size, an identifier of neither kind.
  Bytes unknown = {12, 0, 0, 0, 8, 0, 0, 0, 'X', 'X', 'X', 'X', 0, 0, 0, 0};
  cases.push_back({"unknown frame", unknown, false, "unknown frame from the server"});

  // A session message whose root offset points past its end: the Verifier refuses it.
  Bytes corrupt = {16, 0, 0, 0, 0xE8, 0x03, 0, 0, 'P', 'C', 'S', 'M', 0, 0, 0, 0, 0, 0, 0, 0};
  cases.push_back({"corrupt message", corrupt, false, "bad message from the server"});

  // Messages in the wrong direction or order.
  cases.push_back({"ack", encodeMessage(AckMsg{}), true, "Ack from the server: only a client"});
  cases.push_back({"hello", encodeMessage(HelloMsg{}), false, "Hello from the server"});
  cases.push_back({"pose", encodeMessage(ViewerPoseMsg{}), true, "ViewerPose from the server"});
  cases.push_back({"repair", encodeMessage(RepairRequestMsg{}), true, "RepairRequest from"});
  cases.push_back({"info first", info, false, "SessionInfo before Welcome"});
  cases.push_back(
      {"scene first", encodeMessage(SceneStateMsg{}), false, "SceneState before Welcome"});
  cases.push_back(
      {"two welcomes", encodeMessage(WelcomeMsg{kProtocolVersion, 6}), true, "a second Welcome"});
  cases.push_back({"two infos", concat({info, info}), true, "a second SessionInfo"});
  cases.push_back({"future server", encodeMessage(WelcomeMsg{kProtocolVersion + 7, 6}), false,
                   "server speaks protocol version " + std::to_string(kProtocolVersion + 7)});

  // A layout this client cannot build: other layout constants, too many cascades.
  SessionInfoMsg texels = server.publisher->sessionInfo();
  texels.irradianceTexels += 2;
  cases.push_back({"other texels", encodeMessage(texels), true, "session info: "});
  SessionInfoMsg cascades = server.publisher->sessionInfo();
  cascades.cascades.resize(5, cascades.cascades[0]);
  cases.push_back({"five cascades", encodeMessage(cascades), true, "session info: "});

  for (const Case& c : cases) {
    const std::string error = refusal(c.bytes, c.welcomed);
    std::printf("%-15s -> %s\n", c.what, error.c_str());
    EXPECT_NE(error.find(c.expected), std::string::npos)
        << c.what << ": \"" << error << "\" lacks \"" << c.expected << "\"";
  }
  // The good handshake for comparison: taken.
  EXPECT_EQ(refusal(info, true), "");

  // A corrupt datagram (its CRC off) is refused but never ends the session, whichever way
  // it came.
  ClientSession session({});
  join(session, server, 0.0);
  Bytes datagram = server.sender->poll(0.1).front();
  datagram.back() ^= 0xFF;
  EXPECT_FALSE(session.onDatagram(datagram, 0.1).ok());
  ASSERT_EQ(session.events().size(), 1u);
  EXPECT_FALSE(session.events()[0].status.ok());
  EXPECT_TRUE(session.onStreamBytes(datagramFrame(datagram), 0.1).ok()) << session.error();
  ASSERT_EQ(session.events().size(), 1u);
  EXPECT_EQ(session.events()[0].kind, SessionEvent::Kind::Datagram);
  EXPECT_FALSE(session.events()[0].status.ok());
  EXPECT_EQ(session.stats().badDatagrams, 2u);
  EXPECT_TRUE(session.streaming());
}

TEST(ClientSession, TimeoutsEndTheSession) {
  ClientSessionOptions o;
  o.connectTimeout = 2.0;
  o.silenceTimeout = 1.0;
  {
    // No session within the connect timeout, counted from connecting().
    ClientSession session(o);
    session.connecting(10.0);
    EXPECT_TRUE(session.poll(11.9).ok());
    (void)session.connected(11.9, 0);
    EXPECT_TRUE(session.poll(11.95).ok());
    auto r = session.poll(12.05);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.error().message, "no session within 2.000000 s");
    EXPECT_EQ(session.phase(), SessionPhase::Failed);
  }
  {
    // Silence: any bytes from the server count, a datagram as much as a message.
    InMemoryServer server(11);
    ClientSession session(o);
    join(session, server, 0.0);
    EXPECT_TRUE(session.poll(0.9).ok());
    auto datagrams = server.sender->poll(0.9);
    ASSERT_FALSE(datagrams.empty());
    (void)session.onDatagram(datagrams.front(), 0.9);
    EXPECT_TRUE(session.poll(1.85).ok());
    auto r = session.poll(1.95);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.error().message, "server silent for 1.000000 s");
    EXPECT_EQ(session.phase(), SessionPhase::Failed);
    EXPECT_EQ(session.error(), r.error().message);
    session.close();
    EXPECT_EQ(session.phase(), SessionPhase::Idle);
    EXPECT_EQ(session.receiver(), nullptr);
  }
}

// A datagram of the server's, re-encoded with another field version and brick versions.
Bytes forged(const Bytes& real, std::uint64_t fieldVersion, std::uint64_t brickVersion) {
  auto d = decodeDatagram(real);
  EXPECT_TRUE(d.ok());
  if (!d) return {};
  std::vector<FragmentRef> refs;
  for (Fragment& f : d->fragments) {
    f.update.version = brickVersion;
    refs.push_back(FragmentRef{f.update, f.index, f.data});
  }
  return encodeDatagram(d->sessionId, d->sequence, fieldVersion, refs);
}

TEST(ClientSession, VersionsBeyondWhatTheServerAnnouncedAreRefused) {
  InMemoryServer server(17);
  ClientSession session({});
  join(session, server, 0.0);
  const std::uint64_t announced = server.field.version;
  // The sender paces what it packed over several polls: take every datagram of the first
  // choice of bricks (so that whole updates arrive), at most 0.1 s of sending.
  std::vector<Bytes> datagrams;
  for (int i = 0; i < 20; ++i) {
    for (Bytes& d : server.sender->poll(0.01 + 0.005 * i)) datagrams.push_back(std::move(d));
  }
  ASSERT_FALSE(datagrams.empty());
  const Bytes& real = datagrams.front();
  const StreamReceiver& receiver = *session.receiver();

  // A brick version of 2^63 (which would hold the brick against every real update), and a
  // heartbeat's field version beyond the bound: refused, nothing applied.
  constexpr std::uint64_t kFar = std::uint64_t(1) << 63;
  EXPECT_FALSE(session.onDatagram(forged(real, announced, kFar), 0.02).ok());
  EXPECT_FALSE(session.onDatagram(encodeDatagram(server.sessionId, 99, kFar, {}), 0.02).ok());
  EXPECT_FALSE(session
                   .onDatagram(forged(real, announced + kFieldVersionSlack + 1,
                                      announced + kFieldVersionSlack + 1),
                               0.02)
                   .ok());
  EXPECT_EQ(receiver.stats().refusedVersions, 3u);
  EXPECT_EQ(receiver.stats().applied, 0u);
  EXPECT_LE(receiver.serverFieldVersion(), announced) << "a refused datagram announces nothing";

  // Within the slack (a datagram overtaking its SceneState): applied.
  const std::uint64_t ahead = announced + kFieldVersionSlack;
  for (const Bytes& d : datagrams) {
    EXPECT_TRUE(session.onDatagram(forged(d, ahead, ahead), 0.03).ok())
        << receiver.stats().lastError;
  }
  EXPECT_GT(receiver.stats().applied, 0u);
  EXPECT_EQ(receiver.serverFieldVersion(), announced + kFieldVersionSlack);

  // A SceneState over the session moves the bound on; a datagram's own version never does.
  SceneStateMsg later;
  later.fieldVersion = announced + 5000;
  ASSERT_TRUE(session.onStreamBytes(encodeMessage(later), 0.04).ok());
  EXPECT_TRUE(
      session.onDatagram(encodeDatagram(server.sessionId, 100, announced + 5000 + 1000, {}), 0.05)
          .ok());
  EXPECT_EQ(receiver.stats().refusedVersions, 3u);
}

TEST(ClientSession, OnlyTheServersDatagramsCountAsItsLife) {
  ClientSessionOptions o;
  o.silenceTimeout = 1.0;
  InMemoryServer server(19);
  ClientSession session(o);
  join(session, server, 0.0);
  auto datagrams = server.sender->poll(0.01);
  ASSERT_GE(datagrams.size(), 2u);
  // The first accepted datagram fixes the server's port; the same bytes from elsewhere are
  // dropped unread.
  EXPECT_TRUE(session.onDatagram(datagrams[0], 0.5, DatagramSource{true, 5000}).ok());
  EXPECT_FALSE(session.onDatagram(datagrams[1], 0.6, DatagramSource{false, 5000}).ok());
  EXPECT_FALSE(session.onDatagram(datagrams[1], 0.6, DatagramSource{true, 5001}).ok());
  EXPECT_EQ(session.stats().foreignDatagrams, 2u);
  // Junk from the server's address and port, and foreign datagrams, keep nothing alive.
  for (double t = 0.7; t < 1.6; t += 0.1) {
    (void)session.onDatagram(Bytes(100, 0x5A), t, DatagramSource{true, 5000});
    (void)session.onDatagram(datagrams[1], t, DatagramSource{false, 5000});
    (void)session.onDatagram(datagrams[1], t, DatagramSource{true, 5001});
  }
  EXPECT_TRUE(session.poll(1.45).ok());
  auto r = session.poll(1.55);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().message, "server silent for 1.000000 s");
}

TEST(ClientSession, DatagramsBeforeTheLayoutAreKeptForIt) {
  InMemoryServer server(13);
  ClientSession session({});
  session.connecting(0.0);
  (void)session.connected(0.0, 4000);
  // The server sends datagrams as soon as the Hello is in; UDP overtakes the Welcome.
  std::vector<Bytes> datagrams;
  for (double t = 0; datagrams.size() < kMaxEarlyDatagrams + 5 && t < 5.0; t += 0.3)
    for (Bytes& d : server.sender->poll(t)) datagrams.push_back(std::move(d));
  ASSERT_GT(datagrams.size(), kMaxEarlyDatagrams);
  for (const Bytes& d : datagrams) {
    EXPECT_TRUE(session.onDatagram(d, 0.01).ok());
    EXPECT_TRUE(session.events().empty()) << "kept, not handled";
  }
  EXPECT_EQ(session.stats().droppedEarlyDatagrams, datagrams.size() - kMaxEarlyDatagrams);

  ASSERT_TRUE(session.onStreamBytes(server.handshake(), 0.02).ok()) << session.error();
  const auto events = session.events();
  using K = SessionEvent::Kind;
  ASSERT_GE(events.size(), 3u);
  EXPECT_EQ(events[0].kind, K::Welcomed);
  EXPECT_EQ(events[1].kind, K::Layout);
  std::size_t replayed = 0;
  for (std::size_t i = 2; i < events.size(); ++i) {
    if (events[i].kind != K::Datagram) continue;
    EXPECT_TRUE(events[i].status.ok()) << events[i].status.error().message;
    ++replayed;
  }
  EXPECT_EQ(replayed, kMaxEarlyDatagrams);
  EXPECT_GT(session.bricksHeld(), 0) << "the kept datagrams were applied";
  EXPECT_FALSE(session.takeChangedBricks().empty());
}

TEST(ClientSession, PosesGoOutAtTheirCadenceWithTheClocksTime) {
  ClientSessionOptions o;
  o.poseInterval = 0.1;
  ClientSession session(o);
  const glm::vec3 position(1.0f, 2.0f, 3.0f);
  const glm::quat orientation = glm::angleAxis(0.5f, glm::vec3(0, 1, 0));
  session.setViewer(position, orientation);
  auto poses = [&](double t) {
    std::vector<ViewerPoseMsg> out;
    auto frames = session.poll(t);
    EXPECT_TRUE(frames.ok());
    if (!frames) return out;
    for (const Bytes& f : *frames) {
      auto m = decodeMessage(f);
      EXPECT_TRUE(m.ok());
      if (m && std::holds_alternative<ViewerPoseMsg>(*m))
        out.push_back(std::get<ViewerPoseMsg>(*m));
    }
    return out;
  };
  session.connecting(0.0);
  (void)session.connected(0.0, 0);
  EXPECT_FALSE(session.poseDue(0.5));
  EXPECT_TRUE(poses(0.5).empty()) << "no pose before the session has a layout";

  InMemoryServer server(17);
  ASSERT_TRUE(session.onStreamBytes(server.handshake(4.0), 1.0).ok());
  EXPECT_TRUE(session.poseDue(1.0));
  auto first = poses(1.0);
  ASSERT_EQ(first.size(), 1u) << "the first pose goes out as soon as the session streams";
  EXPECT_EQ(first[0].position, position);
  EXPECT_NEAR(first[0].orientation.w, orientation.w, 1e-6);
  EXPECT_DOUBLE_EQ(first[0].time, 4.0);
  EXPECT_TRUE(poses(1.05).empty());
  EXPECT_FALSE(session.poseDue(1.09));
  auto second = poses(1.1);
  ASSERT_EQ(second.size(), 1u);
  // The clock runs on at rate 1 before a second state gives it a rate.
  EXPECT_NEAR(second[0].time, 4.1, 1e-9);
}

TEST(ClientSession, ClockRunsAtTheRateTheServersStatesAdvance) {
  AnimationClock clock;
  EXPECT_FALSE(clock.at(1.0).has_value());
  clock.update(1.0, 10.0);
  EXPECT_DOUBLE_EQ(*clock.at(10.5), 1.5);
  clock.update(1.5, 11.0);  // half speed
  EXPECT_DOUBLE_EQ(*clock.at(12.0), 2.0);
  clock.update(1.5, 12.0);  // stopped: no running past a frozen server
  EXPECT_DOUBLE_EQ(*clock.at(20.0), 1.5);
  clock.update(100.0, 13.0);  // a jump: the rate is clamped
  EXPECT_DOUBLE_EQ(*clock.at(14.0), 102.0);
}

TEST(ClientSession, ConvergesOverALossyLink) {
  // The server's field keeps changing for 3 s over a link that loses, duplicates, reorders,
  // corrupts and delays; then it stops and the link calms. The session's acks and repair
  // requests bring every brick's newest version.
  InMemoryServer server(19);
  ClientSession session({});
  join(session, server, 0.0);
  FaultLink link(19);
  ReliableLink control;
  FaultProfile faults;
  faults.loss = 0.2;
  faults.duplicate = 0.1;
  faults.reorder = 0.2;
  faults.corrupt = 0.05;
  faults.delay = 0.02;
  link.setProfile(faults);
  std::uint64_t repairs = 0;
  double t = kStep;
  for (int tick = 0; t < 8.0; t += kStep) {
    if (t < 3.0 && t >= 0.1 * tick) {
      ++tick;
      test::evolveField(server.field, server.rng, 0.3f, float(tick));
      ASSERT_TRUE(server.publisher->publish(server.field, t).ok());
    }
    if (t >= 3.0) link.setProfile(FaultProfile{});
    for (Bytes& d : server.sender->poll(t)) link.send(std::move(d), t);
    for (Bytes& d : link.receive(t)) (void)session.onDatagram(d, t);
    auto frames = session.poll(t);
    ASSERT_TRUE(frames.ok()) << frames.error().message;
    for (Bytes& f : *frames) {
      auto m = decodeMessage(f);
      ASSERT_TRUE(m.ok());
      repairs += std::holds_alternative<RepairRequestMsg>(*m);
      control.send(std::move(f), t);
    }
    for (Bytes& f : control.receive(t)) ASSERT_TRUE(server.sender->onMessage(f, t).ok());
    if (t > 3.0 &&
        test::differingBricks(session.receiver()->field(), test::quantizedCopy(server.field)) == 0)
      break;
  }
  std::printf("converged at %.2f s: %llu bad datagrams, %llu repair requests\n", t,
              (unsigned long long)session.stats().badDatagrams, (unsigned long long)repairs);
  EXPECT_LT(t, 8.0) << "did not converge";
  EXPECT_TRUE(session.synced());
  EXPECT_TRUE(session.streaming());
  EXPECT_GT(session.stats().badDatagrams, 0u) << "corrupt datagrams are refused";
  // Bricks changed many times over, each named once: a caller applies it once.
  const auto changed = session.takeChangedBricks();
  EXPECT_EQ(int(changed.size()), session.bricksTotal());
  const std::set<std::pair<int, int>> distinct(changed.begin(), changed.end());
  EXPECT_EQ(distinct.size(), changed.size());
  EXPECT_EQ(test::differingBricks(session.receiver()->field(), test::quantizedCopy(server.field)),
            0);
}

TEST(ClientSession, NewSessionResyncsFromNothing) {
  ClientSessionOptions o;
  o.poseInterval = 60.0;  // one pose per session, as it starts
  ClientSession session(o);
  session.setViewer(glm::vec3(1.0f), glm::quat(1.0f, 0.0f, 0.0f, 0.0f));
  InMemoryServer first(21);
  join(session, first, 0.0);
  const double t = syncWith(first, session, 0.0);
  EXPECT_FALSE(session.poseDue(t));
  const Bytes stale = first.sender->poll(t + 1.5).front();  // a heartbeat at least

  // The server goes away; a new one (another session id, a newer field) takes the client.
  session.close();
  EXPECT_EQ(session.phase(), SessionPhase::Idle);
  EXPECT_EQ(session.receiver(), nullptr);
  EXPECT_FALSE(session.synced());
  ASSERT_TRUE(session.clock().at(t + 2.0).has_value()) << "the clock outlives the session";

  InMemoryServer second(22, 3);
  session.connecting(t + 2.0);
  (void)session.connected(t + 2.0, 4000);
  ASSERT_TRUE(session.onStreamBytes(second.handshake(), t + 2.0).ok()) << session.error();
  using K = SessionEvent::Kind;
  EXPECT_EQ(kinds(session.events()), (std::vector<K>{K::Welcomed, K::Layout, K::SceneState}));
  EXPECT_EQ(session.sessionId(), 22u);
  EXPECT_EQ(session.bricksHeld(), 0);
  EXPECT_FALSE(session.synced());
  EXPECT_TRUE(session.poseDue(t + 2.0)) << "the new server learns the viewer at once";

  // A datagram of the old session is refused, naming both sessions.
  Status s = session.onDatagram(stale, t + 2.0);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("session 21, expected 22"), std::string::npos)
      << s.error().message;

  syncWith(second, session, t + 2.0);
  EXPECT_EQ(session.stats().sessions, 2u);
  EXPECT_EQ(session.stats().connectAttempts, 2u);
  EXPECT_EQ(session.stats().badDatagrams, 1u);
  EXPECT_EQ(test::differingBricks(session.receiver()->field(), test::quantizedCopy(second.field)),
            0);
}

}  // namespace
}  // namespace pc
