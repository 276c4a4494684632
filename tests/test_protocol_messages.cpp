// Session messages and datagrams: round trips, version rules, size limits, and hostile input
// (random bytes, truncations, bit flips) rejected with a message, never a crash. Also the
// reassembly caps and the receiver's and sender's refusal of what does not fit the session.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <random>
#include <string>

#include "protocol/crc32.h"
#include "protocol/datagram.h"
#include "protocol/field_publisher.h"
#include "protocol/session_messages.h"
#include "protocol/stream_receiver.h"
#include "protocol/stream_sender.h"
#include "test_protocol_support.h"

namespace {

using namespace pc;

bool contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

template <typename T>
T roundTrip(const T& m) {
  auto d = decodeMessage(encodeMessage(m));
  EXPECT_TRUE(d.ok()) << d.error().message;
  return std::get<T>(d.value());
}

TEST(ProtocolMessages, RoundTrips) {
  HelloMsg h{kProtocolVersion, "secret", "client-1", true, 4242};
  HelloMsg h2 = roundTrip(h);
  EXPECT_EQ(h2.authToken, "secret");
  EXPECT_EQ(h2.clientName, "client-1");
  EXPECT_EQ(h2.udpPort, 4242);
  EXPECT_TRUE(h2.wantsUdp);
  EXPECT_EQ(roundTrip(WelcomeMsg{kProtocolVersion, 77}).sessionId, 77u);
  EXPECT_EQ(roundTrip(RejectMsg{kProtocolVersion, "full"}).reason, "full");

  Field f = test::makeSyntheticLayout();
  f.desc.cascades[0].scroll = glm::ivec3(1, 2, 3);
  SessionInfoMsg info = roundTrip(sessionInfoFor(f));
  EXPECT_EQ(info.sceneHash, f.sceneHash);
  ASSERT_EQ(info.cascades.size(), 2u);
  EXPECT_EQ(std::memcmp(&info.cascades[0], &f.desc.cascades[0], sizeof(gpu::CascadeDesc)), 0);
  auto mirror = mirrorField(info);
  ASSERT_TRUE(mirror.ok()) << mirror.error().message;
  EXPECT_EQ(std::memcmp(&mirror->desc, &f.desc, sizeof f.desc), 0);
  EXPECT_EQ(mirror->irradiance.texels.size(), f.irradiance.texels.size());

  Scene scene = builtinScene();
  SceneState state = evaluateScene(scene, 1.25);
  SceneStateMsg sm = roundTrip(sceneStateMessage(state));
  SceneState applied = evaluateScene(scene, 0.0);
  ASSERT_TRUE(applySceneState(sm, applied).ok());
  EXPECT_EQ(applied.time, 1.25);
  ASSERT_EQ(applied.lights.size(), state.lights.size());
  for (std::size_t i = 0; i < state.lights.size(); ++i) {
    EXPECT_EQ(applied.lights[i].position, state.lights[i].position);
  }
  EXPECT_EQ(applied.instanceTransforms, state.instanceTransforms);

  ViewerPoseMsg pose{glm::vec3(1, 2, 3), glm::quat(0.5f, 0.5f, 0.5f, 0.5f), 9.5};
  ViewerPoseMsg pose2 = roundTrip(pose);
  EXPECT_EQ(pose2.position, pose.position);
  EXPECT_EQ(pose2.orientation, pose.orientation);

  AckMsg ack{true, 12, {{0, 3, 5, 9}, {1, 0, 2, 11}}};
  AckMsg ack2 = roundTrip(ack);
  ASSERT_EQ(ack2.ranges.size(), 2u);
  EXPECT_EQ(ack2.ranges[1].cascade, 1);
  EXPECT_EQ(ack2.ranges[0].count, 5u);
  EXPECT_EQ(ack2.ranges[1].version, 11u);
  RepairRequestMsg rep{{{1, 2, 3}}};
  EXPECT_EQ(roundTrip(rep).bricks[0].haveVersion, 3u);

  AckMsg gaps{false, 12, {}, {{77, 1, 5, 9, 4, 30, {2, 17, 29}}}};
  AckMsg gaps2 = roundTrip(gaps);
  ASSERT_EQ(gaps2.gaps.size(), 1u);
  const FragmentGapMsg& g = gaps2.gaps[0];
  EXPECT_EQ(g.updateId, 77u);
  EXPECT_EQ(g.cascade, 1);
  EXPECT_EQ(g.brick, 5u);
  EXPECT_EQ(g.version, 9u);
  EXPECT_EQ(g.baseVersion, 4u);
  EXPECT_EQ(g.fragmentCount, 30);
  EXPECT_EQ(g.missing, (std::vector<std::uint16_t>{2, 17, 29}));
  EXPECT_TRUE(roundTrip(ack).gaps.empty());
}

TEST(ProtocolMessages, AckGapsOutsideTheirUpdateAreRefused) {
  auto refused = [](const FragmentGapMsg& gap, const char* what) {
    auto m = decodeMessage(encodeMessage(AckMsg{false, 1, {}, {gap}}));
    ASSERT_FALSE(m.ok()) << what;
    EXPECT_NE(m.error().message.find("fragment"), std::string::npos) << m.error().message;
  };
  refused({1, 0, 0, 2, 0, 30, {30}}, "an index past the count");
  refused({1, 0, 0, 2, 0, 1, {0}}, "an update of one fragment");
  refused({1, 0, 0, 2, 0, 60000, {0}}, "more fragments than a payload can have");
  refused({1, 0, 0, 2, 0, 3, {0, 1, 2, 0}}, "more indices than fragments");
  AckMsg many{
      false, 1, {}, std::vector<FragmentGapMsg>(kMaxFragmentGaps + 1, {1, 0, 0, 2, 0, 3, {0}})};
  EXPECT_FALSE(decodeMessage(encodeMessage(many)).ok());
}

TEST(ProtocolMessages, VersionRules) {
  const KeyPair keys = keyPairFromSeed({5});
  const TokenVerifier verifier({keys.verify});
  const std::int64_t now = 5000;
  auto issued = issueToken(keys.signing,
                           newTokenClaims("c", "scene-a", TokenRole::Viewer, 1, now - 10, 3600));
  ASSERT_TRUE(issued.ok());
  const std::string t = *issued;
  HelloMsg newer{kProtocolVersion + 1, t, "c", true, 0};
  HelloVerdict verdict = checkHello(roundTrip(newer), verifier, "scene-a", now);
  ASSERT_TRUE(verdict.reject.has_value());
  EXPECT_TRUE(verdict.versionMismatch);
  EXPECT_TRUE(
      contains(verdict.reject->reason,
               "protocol version " + std::to_string(kProtocolVersion + 1) + " is not supported"))
      << verdict.reject->reason;
  HelloMsg older{kMinProtocolVersion - 1, t, "c", true, 0};
  verdict = checkHello(older, verifier, "scene-a", now);
  ASSERT_TRUE(verdict.reject.has_value());
  EXPECT_TRUE(contains(verdict.reject->reason, "this server speaks"));
  verdict = checkHello(HelloMsg{kProtocolVersion, t, "c", true, 0}, verifier, "scene-a", now);
  EXPECT_FALSE(verdict.reject.has_value());
  EXPECT_EQ(verdict.claims.client, "c");

  // Each token fault is a Reject naming its cause, counted by the caller from tokenError.
  const std::pair<HelloVerdict, TokenError> faults[] = {
      {checkHello(HelloMsg{kProtocolVersion, "wrong", "c", true, 0}, verifier, "scene-a", now),
       TokenError::Malformed},
      {checkHello(HelloMsg{kProtocolVersion, "", "c", true, 0}, verifier, "scene-a", now),
       TokenError::Malformed},
      {checkHello(HelloMsg{kProtocolVersion, t, "c", true, 0}, verifier, "scene-b", now),
       TokenError::WrongScene},
      {checkHello(HelloMsg{kProtocolVersion, t, "c", true, 0}, verifier, "scene-a", now + 3600),
       TokenError::Expired},
      {checkHello(HelloMsg{kProtocolVersion, t, "c", true, 0},
                  TokenVerifier({keyPairFromSeed({6}).verify}), "scene-a", now),
       TokenError::BadSignature},
  };
  for (const auto& [v, cause] : faults) {
    ASSERT_TRUE(v.reject.has_value());
    ASSERT_TRUE(v.tokenError.has_value());
    EXPECT_EQ(*v.tokenError, cause);
    EXPECT_EQ(v.reject->reason, "authentication failed: " + std::string(tokenErrorName(cause)));
  }

  EXPECT_TRUE(checkServerVersion(kProtocolVersion).ok());
  Status s = checkServerVersion(kProtocolVersion + 7);
  ASSERT_FALSE(s.ok());
  EXPECT_TRUE(contains(s.error().message, "server speaks protocol version")) << s.error().message;
}

TEST(ProtocolMessages, HostileFramesAreRejected) {
  std::mt19937 rng(9);
  Field f = test::makeSyntheticLayout();
  const std::vector<std::vector<std::uint8_t>> valid = {
      encodeMessage(HelloMsg{kProtocolVersion, "secret", "me", true, 1}),
      encodeMessage(sessionInfoFor(f)), encodeMessage(AckMsg{true, 3, {{0, 0, 4, 3}}}),
      encodeMessage(sceneStateMessage(evaluateScene(builtinScene(), 0.5)))};
  for (const auto& frame : valid) {
    for (std::size_t n = 0; n < frame.size(); ++n) {
      auto cut = std::span(frame).first(n);
      EXPECT_FALSE(decodeMessage(cut).ok()) << n;
    }
    for (int i = 0; i < 2000; ++i) {
      auto bytes = frame;
      const int flips = 1 + int(rng() % 4);
      for (int j = 0; j < flips; ++j)
        bytes[rng() % bytes.size()] ^= std::uint8_t(1u << (rng() % 8));
      auto m = decodeMessage(bytes);  // either rejected or a well-formed message
      if (!m.ok()) {
        EXPECT_FALSE(m.error().message.empty());
      }
      if (m.ok()) {
        if (auto* info = std::get_if<SessionInfoMsg>(&*m)) (void)mirrorField(*info);
      }
    }
  }
  for (int i = 0; i < 2000; ++i) {
    std::vector<std::uint8_t> junk(rng() % 600);
    for (auto& x : junk) x = std::uint8_t(rng());
    if (junk.size() >= 4 && i % 2) {
      const std::uint32_t n = std::uint32_t(junk.size() - 4);
      std::memcpy(junk.data(), &n, 4);
    }
    EXPECT_FALSE(decodeMessage(junk).ok());
  }
  // An announced size over the limit is refused from the prefix alone.
  std::uint8_t prefix[4] = {0xFF, 0xFF, 0xFF, 0x7F};
  auto size = messageFrameSize(prefix);
  ASSERT_FALSE(size.ok());
  EXPECT_TRUE(contains(size.error().message, "limit"));
  // A datagram is not a session message.
  EXPECT_FALSE(decodeMessage(encodeDatagram(1, 1, 1, {})).ok());
}

TEST(ProtocolMessages, MirrorFieldRefusesBadLayouts) {
  Field f = test::makeSyntheticLayout();
  auto expectBad = [&](auto&& change, const std::string& part) {
    SessionInfoMsg info = sessionInfoFor(f);
    change(info);
    auto m = mirrorField(roundTrip(info));
    ASSERT_FALSE(m.ok()) << part;
    EXPECT_TRUE(contains(m.error().message, part)) << m.error().message;
  };
  expectBad([](SessionInfoMsg& i) { i.depthTexels = 8; }, "tile layout");
  expectBad([](SessionInfoMsg& i) { i.cascades.clear(); }, "0 cascades");
  expectBad([](SessionInfoMsg& i) { i.cascades[0].counts.x = 0; }, "probe counts");
  expectBad([](SessionInfoMsg& i) { i.cascades[1].firstProbe += 64; }, "first probe");
  expectBad([](SessionInfoMsg& i) { i.cascades[0].spacing = -1.0f; }, "spacing");
  expectBad([](SessionInfoMsg& i) { i.cascades[0].maxRayDistance = std::nanf(""); }, "distances");
  expectBad([](SessionInfoMsg& i) { i.cascades[0].scroll.y = 99; }, "scroll");
  expectBad([](SessionInfoMsg& i) { i.codecs = {7}; }, "codec");
  expectBad([](SessionInfoMsg& i) { i.cascades[0].counts = glm::ivec3(1024); }, "probe slots");
}

TEST(ProtocolDatagrams, Crc32MatchesTheStandardAndTheBytewiseDefinition) {
  const std::string check = "123456789";
  const auto* p = reinterpret_cast<const std::uint8_t*>(check.data());
  EXPECT_EQ(crc32(std::span(p, check.size())), 0xCBF43926u);  // the standard check value
  EXPECT_EQ(crc32({}), 0u);
  // Every length and alignment against the bit-by-bit definition, and chaining.
  std::mt19937 rng(3);
  std::vector<std::uint8_t> bytes(300);
  for (auto& b : bytes) b = std::uint8_t(rng());
  auto bitwise = [](std::span<const std::uint8_t> d) {
    std::uint32_t c = 0xFFFFFFFFu;
    for (std::uint8_t b : d) {
      c ^= b;
      for (int k = 0; k < 8; ++k) c = (c & 1u) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
    }
    return ~c;
  };
  for (std::size_t offset = 0; offset < 9; ++offset) {
    for (std::size_t n = 0; n + offset <= bytes.size(); n += 7) {
      const auto part = std::span(bytes).subspan(offset, n);
      ASSERT_EQ(crc32(part), bitwise(part)) << offset << " " << n;
    }
  }
  const auto all = std::span(bytes);
  EXPECT_EQ(crc32(all.subspan(123), crc32(all.first(123))), crc32(all));
}

TEST(ProtocolDatagrams, SizesAndChecks) {
  // A full fragment fits with room to spare; so do many small ones packed by the overheads.
  std::vector<std::uint8_t> payload(3000, 0xAB);
  UpdateHeader u{0xFFFFFFFFu, 3, 0xFFFFFFFFu, ~0ull, ~0ull - 1, 1, std::uint32_t(payload.size())};
  std::vector<FragmentRef> one{{u, 0, std::span(payload).first(kFragmentBytes)}};
  auto d = encodeDatagram(~0u, ~0u, ~0ull, one);
  EXPECT_LE(d.size() + 0, kDatagramOverheadBytes + kFragmentOverheadBytes + kFragmentBytes);
  EXPECT_LE(d.size(), kMaxDatagramBytes);
  std::vector<FragmentRef> many;
  std::size_t estimate = kDatagramOverheadBytes;
  UpdateHeader small = u;
  small.totalSize = 20;
  while (estimate + kFragmentOverheadBytes + 20 <= kMaxDatagramBytes) {
    many.push_back(FragmentRef{small, 0, std::span(payload).first(20)});
    estimate += kFragmentOverheadBytes + 20;
  }
  auto packed = encodeDatagram(1, 2, 3, many);
  EXPECT_LE(packed.size(), kMaxDatagramBytes);
  auto back = decodeDatagram(packed);
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->fragments.size(), many.size());

  auto decoded = decodeDatagram(d);
  ASSERT_TRUE(decoded.ok()) << decoded.error().message;
  EXPECT_EQ(decoded->fragments[0].update.brick, 0xFFFFFFFFu);
  EXPECT_EQ(decoded->fragments[0].count, 3);

  auto expectBad = [](std::vector<std::uint8_t> bytes, const std::string& part) {
    auto r = decodeDatagram(bytes);
    ASSERT_FALSE(r.ok()) << part;
    EXPECT_TRUE(contains(r.error().message, part)) << r.error().message;
  };
  auto flipped = d;
  flipped[100] ^= 4;
  expectBad(flipped, "checksum");
  expectBad(std::vector<std::uint8_t>(kMaxDatagramBytes + 1, 0), "limit");
  expectBad(std::vector<std::uint8_t>(5, 0), "truncated");
  // Data not matching the announced fragment layout: the last fragment of 3000 bytes holds 952.
  std::vector<FragmentRef> wrong{{u, 2, std::span(payload).first(900)}};
  expectBad(encodeDatagram(1, 1, 1, wrong), "data bytes");
  std::vector<FragmentRef> beyond{{u, 5, std::span(payload).first(10)}};
  expectBad(encodeDatagram(1, 1, 1, beyond), "index");
  UpdateHeader huge = u;
  huge.totalSize = 1u << 30;
  std::vector<FragmentRef> tooBig{{huge, 0, std::span(payload).first(kFragmentBytes)}};
  expectBad(encodeDatagram(1, 1, 1, tooBig), "payload size");
  UpdateHeader backwards = u;
  backwards.baseVersion = backwards.version;
  std::vector<FragmentRef> noOrder{{backwards, 0, std::span(payload).first(kFragmentBytes)}};
  expectBad(encodeDatagram(1, 1, 1, noOrder), "on base");
  // Random bytes with a valid checksum get past the CRC and must stop at the Verifier.
  std::mt19937 rng(4);
  for (int i = 0; i < 3000; ++i) {
    std::vector<std::uint8_t> junk(8 + rng() % 1100);
    for (auto& x : junk) x = std::uint8_t(rng());
    if (i % 2) std::memcpy(junk.data() + 4, "PCDG", 4);
    const std::uint32_t crc = crc32(std::span(junk).first(junk.size() - 4));
    for (int b = 0; b < 4; ++b) junk[junk.size() - 4 + b] = std::uint8_t(crc >> (8 * b));
    (void)decodeDatagram(junk);
  }
}

TEST(ProtocolDatagrams, ReassemblyIsBounded) {
  ReassemblyOptions o;
  o.maxUpdates = 8;
  o.maxBytes = 40000;
  o.timeout = 0.5;
  Reassembler r(o);
  std::vector<std::uint8_t> data(kFragmentBytes, 1);
  // Flood: first fragments of many different payloads, none completing.
  for (std::uint32_t id = 1; id <= 1000; ++id) {
    Fragment f;
    f.update = UpdateHeader{id, 0, id, 2, 0, 1, std::uint32_t(5 * kFragmentBytes)};
    f.index = 0;
    f.count = 5;
    f.data = data;
    EXPECT_FALSE(r.add(std::move(f), 0.001 * id).has_value());
    ASSERT_LE(r.pendingUpdates(), o.maxUpdates);
    ASSERT_LE(r.pendingBytes(), o.maxBytes);
  }
  EXPECT_GT(r.dropped(), 900u);
  r.expire(10.0);
  EXPECT_EQ(r.pendingUpdates(), 0u);
  EXPECT_EQ(r.pendingBytes(), 0u);

  // Fragments out of order and duplicated complete a payload exactly once.
  std::vector<std::uint8_t> payload(2500);
  for (std::size_t i = 0; i < payload.size(); ++i) payload[i] = std::uint8_t(i * 7);
  const UpdateHeader u{42, 1, 3, 5, 0, 1, std::uint32_t(payload.size())};
  auto frag = [&](std::uint16_t i) {
    Fragment f;
    f.update = u;
    f.index = i;
    f.count = 3;
    const std::size_t b = i * kFragmentBytes;
    f.data.assign(payload.begin() + std::ptrdiff_t(b),
                  payload.begin() + std::ptrdiff_t(std::min(payload.size(), b + kFragmentBytes)));
    return f;
  };
  EXPECT_FALSE(r.add(frag(2), 0).has_value());
  EXPECT_FALSE(r.add(frag(2), 0).has_value());
  EXPECT_FALSE(r.add(frag(0), 0).has_value());
  // A fragment with the same id but another header replaces the partial payload.
  Fragment other = frag(1);
  other.update.version = 6;
  EXPECT_FALSE(r.add(std::move(other), 0).has_value());
  EXPECT_EQ(r.pendingUpdates(), 1u);
  EXPECT_FALSE(r.add(frag(0), 0).has_value());
  EXPECT_FALSE(r.add(frag(2), 0).has_value());
  auto done = r.add(frag(1), 0);
  ASSERT_TRUE(done.has_value());
  EXPECT_EQ(done->payload, payload);
  EXPECT_EQ(r.pendingBytes(), 0u);
}

TEST(ProtocolSession, ReceiverRefusesWhatDoesNotFit) {
  Field server = test::makeSyntheticLayout();
  std::mt19937 rng(6);
  test::evolveField(server, rng, 1.0f, 0.0f);
  FieldPublisher pub(server);
  ASSERT_TRUE(pub.publish(server, 0.0).ok());
  auto rx = StreamReceiver::create(pub.sessionInfo(), 7);
  ASSERT_TRUE(rx.ok()) << rx.error().message;
  auto enc = pub.encoded(0, 0, server.brickVersions[0][0], 0);
  ASSERT_TRUE(enc);

  auto send = [&](UpdateHeader h, std::uint32_t session) {
    h.totalSize = std::uint32_t(enc->payload.size());
    std::vector<std::vector<std::uint8_t>> ds;
    for (std::uint16_t i = 0; i < fragmentCount(h.totalSize); ++i) {
      const std::size_t b = std::size_t(i) * kFragmentBytes;
      std::vector<FragmentRef> f{
          {h, i,
           std::span(enc->payload).subspan(b, std::min(kFragmentBytes, enc->payload.size() - b))}};
      ds.push_back(encodeDatagram(session, i, 1, f));
    }
    Status last;
    for (auto& d : ds) {
      Status s = rx->onDatagram(d, 0.1);
      if (!s) last = s;
    }
    return last;
  };
  // Another session's datagrams.
  Status s = send(enc->header, 8);
  ASSERT_FALSE(s.ok());
  EXPECT_TRUE(contains(s.error().message, "session"));
  // A brick outside the field, an unknown codec.
  UpdateHeader h = enc->header;
  h.brick = 999;
  EXPECT_FALSE(send(h, 7).ok());
  h = enc->header;
  h.codec = 9;
  EXPECT_FALSE(send(h, 7).ok());
  EXPECT_EQ(rx->brickVersion(0, 0), 0u);
  // A residual on a base the receiver does not hold: kept out, repair requested.
  h = enc->header;
  h.baseVersion = 1;
  h.version = 5;
  EXPECT_TRUE(send(h, 7).ok());
  EXPECT_EQ(rx->brickVersion(0, 0), 0u);
  bool repair = false;
  for (auto& m : rx->poll(0.2)) {
    auto msg = decodeMessage(m);
    ASSERT_TRUE(msg.ok());
    if (auto* r = std::get_if<RepairRequestMsg>(&*msg)) repair = r->bricks.size() == 1;
  }
  EXPECT_TRUE(repair);
  // The real update applies; a duplicate is harmless.
  EXPECT_TRUE(send(enc->header, 7).ok());
  EXPECT_EQ(rx->brickVersion(0, 0), server.brickVersions[0][0]);
  EXPECT_TRUE(send(enc->header, 7).ok());
  EXPECT_EQ(rx->stats().applied, 1u);
  EXPECT_EQ(rx->takeChangedBricks().size(), 1u);
  // Random datagrams never crash the receiver or change what it holds.
  for (int i = 0; i < 2000; ++i) {
    std::vector<std::uint8_t> junk(rng() % 1300);
    for (auto& x : junk) x = std::uint8_t(rng());
    (void)rx->onDatagram(junk, 0.3);
  }
  EXPECT_EQ(rx->stats().applied, 1u);
}

TEST(ProtocolSession, SenderRefusesBadAcks) {
  Field server = test::makeSyntheticLayout();
  FieldPublisher pub(server);
  StreamSender tx(pub, 1);
  EXPECT_FALSE(tx.onMessage(encodeMessage(AckMsg{false, 0, {{0, 7, 2, 1}}}), 0).ok());  // 8 bricks
  EXPECT_FALSE(tx.onMessage(encodeMessage(AckMsg{false, 0, {{5, 0, 1, 1}}}), 0).ok());
  EXPECT_FALSE(tx.onMessage(encodeMessage(AckMsg{false, 0, {{0, 0xFFFFFFFFu, 2, 1}}}), 0).ok());
  EXPECT_FALSE(tx.onMessage(encodeMessage(RepairRequestMsg{{{0, 100, 0}}}), 0).ok());
  EXPECT_FALSE(tx.onMessage(encodeMessage(HelloMsg{}), 0).ok());
  EXPECT_TRUE(tx.onMessage(encodeMessage(AckMsg{false, 0, {{0, 0, 8, 0}}}), 0).ok());
  EXPECT_EQ(tx.stats().badMessages, 5u);
}

TEST(ProtocolSession, SenderSendsAgainTheFragmentsAClientLacks) {
  // A client that got part of an update names the fragments it lacks in an ack; the sender sends
  // exactly those again, from the same update (same id and bytes), before anything else. A gap
  // of a version no longer in flight, or of an update the sender did not send, is ignored; one
  // outside the field is refused.
  Field server = test::makeSyntheticLayout();
  std::mt19937 rng(9);
  test::evolveNoisyField(server, rng, 0.0f);
  FieldPublisher pub(server);
  ASSERT_TRUE(pub.publish(server, 0.0).ok());
  SenderOptions options;
  options.burstBytes = 64e6;  // every brick in the first poll, and tokens left for the repair
  options.congestionControl = false;  // a fixed bucket: what is measured is the repair
  StreamSender tx(pub, 1, options);
  std::map<std::pair<int, std::uint32_t>, UpdateHeader> sent;  // brick -> its update
  for (const auto& d : tx.poll(0.0)) {
    auto dg = decodeDatagram(d);
    ASSERT_TRUE(dg.ok());
    for (const Fragment& f : dg->fragments) sent[{f.update.cascade, f.update.brick}] = f.update;
  }
  ASSERT_FALSE(sent.empty());
  const UpdateHeader u = sent.begin()->second;
  const std::uint16_t count = fragmentCount(u.totalSize);
  ASSERT_GE(count, 3);
  const std::uint64_t fragmentsBefore = tx.stats().fragments;
  const FragmentGapMsg gap{u.updateId,
                           u.cascade,
                           u.brick,
                           u.version,
                           u.baseVersion,
                           count,
                           {0, std::uint16_t(count - 1)}};
  ASSERT_TRUE(tx.onMessage(AckMsg{false, server.version, {}, {gap}}, 0.01).ok());
  std::vector<std::uint16_t> again;
  for (const auto& d : tx.poll(0.01)) {
    auto dg = decodeDatagram(d);
    ASSERT_TRUE(dg.ok());
    for (const Fragment& f : dg->fragments) {
      EXPECT_TRUE(f.update.sameUpdate(u));
      again.push_back(f.index);
    }
  }
  EXPECT_EQ(again, gap.missing);
  EXPECT_EQ(tx.stats().repairedFragments, 2u);
  EXPECT_EQ(tx.stats().fragments, fragmentsBefore + 2);

  // Stale or foreign gaps: nothing is sent for them.
  FragmentGapMsg otherId = gap, otherVersion = gap;
  otherId.updateId ^= 1u;
  otherVersion.version += 1;
  ASSERT_TRUE(tx.onMessage(AckMsg{false, server.version, {}, {otherId, otherVersion}}, 0.02).ok());
  // Once the update is acknowledged, a late report of its gaps sends nothing either.
  ASSERT_TRUE(
      tx.onMessage(AckMsg{false, server.version, {{u.cascade, u.brick, 1, u.version}}, {gap}}, 0.02)
          .ok());
  EXPECT_TRUE(tx.poll(0.02).empty());
  EXPECT_EQ(tx.stats().repairedFragments, 2u);

  FragmentGapMsg outside = gap;
  outside.brick = 1000;
  EXPECT_FALSE(tx.onMessage(AckMsg{false, server.version, {}, {outside}}, 0.03).ok());
}

// Fragment i of an update of four whole fragments, its bytes all i.
Fragment fragmentOfFour(const UpdateHeader& u, std::uint16_t i) {
  Fragment f;
  f.update = u;
  f.index = i;
  f.count = 4;
  f.data.assign(kFragmentBytes, std::uint8_t(i));
  return f;
}

TEST(ProtocolDatagrams, GapsAreReportedOnceLaterDatagramsOvertakeThem) {
  // Evidence of loss is datagrams three sequence numbers past a partial payload's latest
  // fragment, and 10 ms since it, however long ago it came (a client that reads its socket late
  // has lost nothing).
  ReassemblyOptions o;
  o.gapReorder = 3;
  o.gapQuiet = 0.01;
  o.gapRepeat = 0.05;
  Reassembler r(o);
  const UpdateHeader u{78, 0, 3, 5, 0, 1, std::uint32_t(4 * kFragmentBytes)};
  auto frag = [&](std::uint16_t i) { return fragmentOfFour(u, i); };
  r.add(frag(0), 0.0, 10);
  r.add(frag(2), 0.001, 12);
  EXPECT_TRUE(r.takeGaps(0.5, 14, 8).empty());  // datagram 13 may still be on its way
  auto gaps = r.takeGaps(0.5, 15, 8);
  ASSERT_EQ(gaps.size(), 1u);
  EXPECT_TRUE(gaps[0].update.sameUpdate(u));
  EXPECT_EQ(gaps[0].fragmentCount, 4);
  EXPECT_EQ(gaps[0].missing, (std::vector<std::uint16_t>{1, 3}));
  EXPECT_TRUE(r.takeGaps(0.52, 16, 8).empty());    // reported, no answer yet
  ASSERT_EQ(r.takeGaps(0.551, 16, 8).size(), 1u);  // no answer within gapRepeat: again
  r.add(frag(1), 0.571, 20);                       // an answer, 20 ms after the report
  EXPECT_NEAR(r.repairRoundTrip(), 0.02, 1e-9);
  EXPECT_TRUE(r.takeGaps(0.6, 21, 8).empty());    // the answer's fragments may still be coming
  EXPECT_TRUE(r.takeGaps(0.575, 23, 8).empty());  // overtaken, but within gapQuiet of it
  gaps = r.takeGaps(0.6, 23, 8);                  // overtaken again, fragment 3 still missing
  ASSERT_EQ(gaps.size(), 1u);
  EXPECT_EQ(gaps[0].missing, (std::vector<std::uint16_t>{3}));
  EXPECT_TRUE(r.add(frag(3), 0.62, 24).has_value());
  EXPECT_TRUE(r.takeGaps(1.0, 100, 8).empty());

  // Sequence numbers wrap.
  r.add(frag(0), 2.0, 0xFFFFFFFEu);
  EXPECT_TRUE(r.takeGaps(2.02, 0u, 8).empty());
  EXPECT_EQ(r.takeGaps(2.02, 1u, 8).size(), 1u);
}

TEST(ProtocolSession, ResendTimeoutCoversAcksThatComeLateNowAndThen) {
  // A loaded client acks most updates in 50 ms and every fourth in 400 ms. Twice the smoothed
  // round trip (0.24 s) would send those again although they arrived; with the round trip's
  // deviation (srtt + 4 x rttvar) the timeout stays above the late acks.
  Field server = test::makeSyntheticLayout();
  std::mt19937 rng(5);
  test::evolveField(server, rng, 1.0f, 0.0f);
  FieldPublisher pub(server);
  ASSERT_TRUE(pub.publish(server, 0.0).ok());
  SenderOptions options;
  options.congestionControl = false;  // every poll sends the whole field: the round trips count
  StreamSender tx(pub, 1, options);
  for (int round = 0; round < 64; ++round) {
    const double t = double(round);
    test::evolveField(server, rng, 1.0f, float(t));
    ASSERT_TRUE(pub.publish(server, t).ok());
    ASSERT_FALSE(tx.poll(t).empty());
    const double delay = round % 4 == 3 ? 0.4 : 0.05;
    ASSERT_TRUE(tx.onMessage(AckMsg{false, server.version, {{0, 0, 1, server.brickVersions[0][0]}}},
                             t + delay)
                    .ok());
    if (round >= 32 && round % 4 == 2) {
      EXPECT_GT(tx.resendTimeout(), 0.4) << "round " << round;
    }
  }
  EXPECT_LT(tx.resendTimeout(), 1.0);
}

TEST(ProtocolDatagrams, EncodedUpdateIdsFollowTheirKey) {
  // The same update encoded again (after it left the cache) has the same id, so a receiver
  // completes it from the fragments of both sends; other keys have other ids.
  EncodeCache cache(1 << 20);
  const EncodeKey a{0, 5, 12, 9}, b{0, 5, 12, 0}, c{1, 5, 12, 9}, d{0, 6, 12, 9}, e{0, 5, 13, 9};
  const std::uint32_t id = cache.insert(a, 1, std::vector<std::uint8_t>(10, 1))->header.updateId;
  EXPECT_NE(id, 0u);
  cache.eraseBrickIf(0, 5, [](const EncodeKey&) { return true; });
  EXPECT_EQ(cache.entries(), 0u);
  EXPECT_EQ(cache.insert(a, 1, std::vector<std::uint8_t>(10, 1))->header.updateId, id);
  EXPECT_EQ(updateIdFor(a), id);
  for (const EncodeKey& other : {b, c, d, e}) EXPECT_NE(updateIdFor(other), id);
}

TEST(ProtocolDatagrams, ReassemblyKeepsAPayloadWhileFragmentsKeepComing) {
  // A payload whose fragments come over longer than the timeout, each within it of the last
  // (a lost update resent), completes; one that hears nothing for the timeout is dropped.
  ReassemblyOptions o;
  o.timeout = 0.5;
  Reassembler r(o);
  const UpdateHeader u{77, 0, 2, 4, 0, 1, std::uint32_t(4 * kFragmentBytes)};
  auto frag = [&](std::uint16_t i) { return fragmentOfFour(u, i); };
  for (std::uint16_t i = 0; i < 3; ++i) {
    EXPECT_FALSE(r.add(frag(i), 0.4 * i).has_value());
    r.expire(0.4 * i + 0.3);
    EXPECT_EQ(r.pendingUpdates(), 1u);
  }
  auto done = r.add(frag(3), 1.2);
  ASSERT_TRUE(done.has_value());
  EXPECT_EQ(done->payload[3 * kFragmentBytes], 3);
  EXPECT_FALSE(r.add(frag(0), 2.0).has_value());
  r.expire(2.6);
  EXPECT_EQ(r.pendingUpdates(), 0u);
}

}  // namespace
