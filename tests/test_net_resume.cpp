// Resuming a session on another endpoint of the same field (protocol version 7, PROTOCOL.md
// "Resuming a session"): the Resume message's form and its checks, what a sender makes of a
// claim, and clients moving between servers over loopback sockets, which must be sent only
// what their mirror lacks, and everything where the field is another.
#include <gtest/gtest.h>

#include <random>

#include "net/tls_certificate.h"
#include "protocol/client_session.h"
#include "protocol/resume_state.h"
#include "protocol/stream_sender.h"
#include "test_net_support.h"

namespace pc::nettest {
namespace {

using test::evolveField;
using test::makeSyntheticLayout;

// Two cascades of 7 and 3 bricks, versions spread as a field's are after a while of updates.
HeldBricks sampleHeld() {
  HeldBricks held(2);
  std::mt19937_64 rng(3);
  for (int b = 0; b < 7; ++b) held[0].push_back(HeldBrick{(1ull << 40) + rng() % 500, 0});
  for (int b = 0; b < 3; ++b) held[1].push_back(HeldBrick{rng() % 90, 0});
  held[0][2].precision = 3;
  held[1][1] = HeldBrick{};  // nothing
  return held;
}

std::vector<std::size_t> sizesOf(const HeldBricks& held) {
  std::vector<std::size_t> sizes;
  for (const auto& c : held) sizes.push_back(c.size());
  return sizes;
}

ResumeMsg decoded(const ResumeMsg& m) {
  auto message = decodeMessage(encodeMessage(m));
  EXPECT_TRUE(message.ok()) << (message ? "" : message.error().message);
  return message ? std::get<ResumeMsg>(*message) : ResumeMsg{};
}

TEST(ResumeState, RoundTripsEveryBricksVersionAndPrecision) {
  const HeldBricks held = sampleHeld();
  const ResumeMsg m = decoded(resumeMessage(0xabc, 77, held));
  EXPECT_EQ(m.sceneHash, 0xabcu);
  EXPECT_EQ(m.fieldEpoch, 77u);
  EXPECT_EQ(m.brickCount, 10u);
  auto back = heldBricksOf(m, sizesOf(held));
  ASSERT_TRUE(back.ok()) << back.error().message;
  for (std::size_t k = 0; k < held.size(); ++k) {
    for (std::size_t b = 0; b < held[k].size(); ++b) {
      EXPECT_EQ((*back)[k][b].version, held[k][b].version) << k << "." << b;
      EXPECT_EQ((*back)[k][b].precision, held[k][b].precision) << k << "." << b;
    }
  }
}

TEST(ResumeState, IsCompactForALargeField) {
  // 60,000 bricks (near the largest layout) at versions within a few thousand of each other:
  // an Ack lists such a field in 24-byte runs of one version each.
  HeldBricks held(1);
  std::mt19937_64 rng(5);
  for (int b = 0; b < 60000; ++b) held[0].push_back(HeldBrick{100000 + rng() % 4000, 0});
  const std::vector<std::uint8_t> frame = encodeMessage(resumeMessage(1, 2, held));
  std::printf("Resume of 60,000 bricks: %zu bytes\n", frame.size());
  EXPECT_LT(frame.size(), 60000u * 3) << "bytes per brick: " << double(frame.size()) / 60000;
  auto back = heldBricksOf(decoded(resumeMessage(1, 2, held)), sizesOf(held));
  ASSERT_TRUE(back.ok());
  EXPECT_EQ((*back)[0][59999].version, held[0][59999].version);
}

TEST(ResumeState, RefusesHostileClaims) {
  const HeldBricks held = sampleHeld();
  const ResumeMsg good = resumeMessage(1, 2, held);

  // Another brick count than the field's.
  auto wrongCount = heldBricksOf(good, {7, 4});
  ASSERT_FALSE(wrongCount.ok());
  EXPECT_NE(wrongCount.error().message.find("claims 10 bricks; the field has 11"),
            std::string::npos);

  // Versions that are no zstd frame, or one of another size than 8 bytes per brick.
  ResumeMsg junk = good;
  junk.versions.assign(40, 0x5a);
  EXPECT_FALSE(heldBricksOf(junk, sizesOf(held)).ok());
  ResumeMsg longer = good;
  longer.brickCount = 11;
  HeldBricks more = held;
  more[1].push_back(HeldBrick{1, 0});
  longer.versions = resumeMessage(1, 2, more).versions;
  longer.brickCount = 10;
  auto tooLong = heldBricksOf(longer, sizesOf(held));
  ASSERT_FALSE(tooLong.ok());
  EXPECT_NE(tooLong.error().message.find("announce 88 bytes, expected 80"), std::string::npos);

  // A precision of a brick outside the field.
  ResumeMsg outside = good;
  outside.precisions.push_back(BrickPrecisionMsg{1, 3, 1});
  EXPECT_FALSE(heldBricksOf(outside, sizesOf(held)).ok());

  // Refused before anything reads it: too many bricks, more version bytes than any such
  // field compresses to, a precision level past the coarsest.
  ResumeMsg huge = good;
  huge.brickCount = kMaxResumeBricks + 1;
  EXPECT_FALSE(decodeMessage(encodeMessage(huge)).ok());
  ResumeMsg padded = good;
  padded.versions.resize(4096);
  EXPECT_FALSE(decodeMessage(encodeMessage(padded)).ok());
  ResumeMsg coarse = good;
  coarse.precisions.push_back(BrickPrecisionMsg{0, 0, kMaxPrecision + 1});
  EXPECT_FALSE(decodeMessage(encodeMessage(coarse)).ok());
}

// A publisher of the synthetic field at two versions: every brick at version 1, then a share
// of them at version 2.
struct TwoVersions {
  Field field = makeSyntheticLayout();
  HeldBricks atFirst;
  int changed = 0, total = 0;
  std::unique_ptr<FieldPublisher> publisher;

  explicit TwoVersions(std::uint64_t epoch) {
    PublisherOptions options;
    options.epoch = epoch;
    publisher = std::make_unique<FieldPublisher>(field, options);
    std::mt19937 rng(11);
    evolveField(field, rng, 1.0f, 0.0f);
    EXPECT_TRUE(publisher->publish(field, 0.0).ok());
    for (const auto& c : field.brickVersions) {
      atFirst.emplace_back();
      for (std::uint64_t v : c) atFirst.back().push_back(HeldBrick{v, 0});
      total += int(c.size());
    }
    changed = evolveField(field, rng, 0.3f, 1.0f);
    EXPECT_TRUE(publisher->publish(field, 0.5).ok());
  }
  // A sender that sends all it wants in one poll (no congestion control, a large bucket).
  std::unique_ptr<StreamSender> sender(std::uint32_t session) const {
    SenderOptions o;
    o.congestionControl = false;
    o.burstBytes = 4e6;
    return std::make_unique<StreamSender>(*publisher, session, o);
  }
  ResumeMsg claim(const HeldBricks& held, std::uint64_t epoch) const {
    return resumeMessage(field.sceneHash, epoch, held);
  }
};

TEST(ResumeSender, WaitsForTheClaimThenSendsOnlyNewerVersionsAsResiduals) {
  TwoVersions f(42);
  ASSERT_GT(f.changed, 0);
  ASSERT_LT(f.changed, f.total);
  auto owned = f.sender(1);
  StreamSender& sender = *owned;
  sender.awaitResume(1.0);
  const auto waiting = sender.poll(0.5);
  EXPECT_EQ(sender.stats().updates, 0u) << "bricks sent before the claim arrived";
  EXPECT_EQ(waiting.size(), 1u);  // a heartbeat
  ASSERT_TRUE(sender.onMessage(f.claim(f.atFirst, 42), 0.6).ok());
  (void)sender.poll(0.6);
  EXPECT_EQ(sender.stats().resumedBricks, std::uint64_t(f.total));
  EXPECT_EQ(sender.stats().updates, std::uint64_t(f.changed));
  EXPECT_EQ(sender.stats().residualUpdates, std::uint64_t(f.changed));
  // A second claim is a broken client's.
  EXPECT_FALSE(sender.onMessage(f.claim(f.atFirst, 42), 0.7).ok());
}

TEST(ResumeSender, RefusesVersionsAheadAndClaimsOfAnotherField) {
  TwoVersions f(42);
  // One brick claimed past the newest version: held as nothing, sent whole.
  HeldBricks ahead = f.atFirst;
  ahead[0][0].version = f.field.version + 5;
  auto owned = f.sender(1);
  StreamSender& sender = *owned;
  ASSERT_TRUE(sender.onMessage(f.claim(ahead, 42), 0.6).ok());
  (void)sender.poll(0.6);
  EXPECT_EQ(sender.stats().resumeRefusedBricks, 1u);
  EXPECT_EQ(sender.stats().resumedBricks, std::uint64_t(f.total - 1));
  EXPECT_GE(sender.stats().reasons.first, 1u);
  EXPECT_EQ(sender.stats().updates - sender.stats().residualUpdates, 1u);

  // Another run's epoch, or another scene: the whole field, self-contained.
  for (const ResumeMsg& other : {f.claim(f.atFirst, 43), resumeMessage(0x1234, 42, f.atFirst)}) {
    auto fresh = f.sender(2);
    ASSERT_TRUE(fresh->onMessage(other, 0.6).ok());
    (void)fresh->poll(0.6);
    EXPECT_EQ(fresh->stats().resumeMismatches, 1u);
    EXPECT_EQ(fresh->stats().resumedBricks, 0u);
    EXPECT_EQ(fresh->stats().updates, std::uint64_t(f.total));
    EXPECT_EQ(fresh->stats().residualUpdates, 0u);
  }

  // The right field with another brick count: refused, nothing taken.
  HeldBricks shorter = f.atFirst;
  shorter[1].pop_back();
  auto third = f.sender(3);
  EXPECT_FALSE(third->onMessage(f.claim(shorter, 42), 0.6).ok());
  EXPECT_EQ(third->stats().resumedBricks, 0u);
}

// One session of `client` with a server speaking `version` whose field is `f`'s: the
// handshake, then what the sender sends until the client holds every brick. The frames the
// client sends first are returned.
std::vector<SessionMessage> runSession(ClientSession& client, const TwoVersions& f,
                                       std::uint32_t version, std::uint32_t id, double& now,
                                       std::uint64_t& heldEpoch) {
  client.connecting(now);
  auto hello = decodeMessage(client.connected(now, 0));
  EXPECT_TRUE(hello.ok());
  heldEpoch = hello ? std::get<HelloMsg>(*hello).heldEpoch : 0;
  SessionInfoMsg info = f.publisher->sessionInfo();
  if (version < kResumeVersion) info.fieldEpoch = 0;  // an older server states none
  for (const SessionMessage& m : {SessionMessage(WelcomeMsg{version, id}), SessionMessage(info)})
    EXPECT_TRUE(client.onStreamBytes(encodeMessage(m), now).ok());
  std::vector<SessionMessage> first;
  auto frames = client.poll(now);
  EXPECT_TRUE(frames.ok());
  for (const auto& frame : *frames) first.push_back(decodeMessage(frame).value());
  auto sender = f.sender(id);
  for (int i = 0; i < 20 && !client.synced(); ++i, now += 0.05) {
    for (const auto& d : sender->poll(now)) (void)client.onDatagram(d, now);
  }
  EXPECT_TRUE(client.synced());
  client.close();
  return first;
}

TEST(ResumeClient, ResumesFromTheSessionBeforeAndNotWithAnOlderServer) {
  TwoVersions f(42);
  ClientSession client(ClientSessionOptions{});
  double now = 0;
  std::uint64_t heldEpoch = 0;
  runSession(client, f, kProtocolVersion, 1, now, heldEpoch);
  EXPECT_EQ(heldEpoch, 0u);  // a new client holds nothing
  EXPECT_EQ(client.stats().resumes, 0u);

  // The next session names the field it holds, resumes and says so first.
  const auto first = runSession(client, f, kProtocolVersion, 2, now, heldEpoch);
  EXPECT_EQ(heldEpoch, 42u);
  EXPECT_EQ(client.stats().resumes, 1u);
  ASSERT_FALSE(first.empty());
  const auto* resume = std::get_if<ResumeMsg>(&first.front());
  ASSERT_NE(resume, nullptr) << "first frame: " << sessionMessageName(first.front());
  EXPECT_EQ(resume->brickCount, std::uint32_t(f.total));
  EXPECT_EQ(resume->fieldEpoch, 42u);

  // A version 6 server knows no Resume: none is sent, and the session starts from nothing.
  const auto older = runSession(client, f, kResumeVersion - 1, 3, now, heldEpoch);
  for (const SessionMessage& m : older)
    EXPECT_FALSE(std::holds_alternative<ResumeMsg>(m)) << "a Resume to a version 6 server";
  EXPECT_EQ(client.stats().resumes, 1u);
}

// Servers of one field (one hub, hence one epoch and the same versions) or of two, over
// loopback with TLS, all presenting one certificate so that a client pins it once.
class Endpoints {
 public:
  explicit Endpoints(int hubs) {
    auto dev = net::makeDevCertificate();
    EXPECT_TRUE(dev.ok());
    cert_ = std::make_shared<const net::DevCertificate>(std::move(dev).value());
    std::mt19937 rng(21);
    for (int h = 0; h < hubs; ++h) {
      fields_.push_back(makeSyntheticLayout());
      evolveField(fields_.back(), rng, 1.0f, float(h) * 2.0f);
      hubs_.push_back(std::make_unique<FieldHub>(fields_.back()));
      EXPECT_TRUE(hubs_.back()->publish(fields_.back(), SceneStateMsg{}, steadySeconds()).ok());
    }
  }
  // A server of hub `h`.
  NetServer& serve(int h) {
    NetServerOptions o;
    o.port = 0;
    o.bindAddress = "127.0.0.1";
    o.tokenKeys = {testKeys().verify};
    o.tls.devSelfSigned = true;
    o.tls.devCertificate = cert_;
    auto s = NetServer::create(*hubs_[h], o);
    if (!s) ADD_FAILURE() << s.error().message;
    servers_.push_back(std::move(s).value());
    servers_.back()->start();
    return *servers_.back();
  }
  // Changes a share of hub h's bricks (a new version of each).
  int evolve(int h, float share, std::uint32_t seed) {
    std::mt19937 rng(seed);
    const int n = evolveField(fields_[h], rng, share, 5.0f);
    EXPECT_TRUE(hubs_[h]->publish(fields_[h], SceneStateMsg{}, steadySeconds()).ok());
    return n;
  }
  const Field& field(int h) const { return fields_[h]; }
  std::uint64_t epoch(int h) { return hubs_[h]->publisher().sessionInfo().fieldEpoch; }

  // A client of `first` that moves on to `next` (if any) when `first` goes.
  static client::NetClientOptions client(const NetServer& first, const std::string& name,
                                         const NetServer* next = nullptr) {
    client::NetClientOptions o = secureClientOptions(first.port(), first.tlsFingerprint(), name);
    if (next) o.alternates = {{"127.0.0.1", next->port()}};
    return o;
  }

 private:
  std::shared_ptr<const net::DevCertificate> cert_;
  std::vector<Field> fields_;
  std::vector<std::unique_ptr<FieldHub>> hubs_;
  std::vector<std::unique_ptr<NetServer>> servers_;
};

// The server's view of its client `name`: bytes sent and bricks not current, once the client
// holds every brick's current version.
std::optional<NetClientInfo> currentClient(const NetServer& server, const std::string& name) {
  for (const NetClientInfo& c : server.stats().clients) {
    if (c.name == name && c.pendingBricks == 0 && c.report.pendingBricks == 0 &&
        c.report.fieldVersion != 0)
      return c;
  }
  return std::nullopt;
}

TEST(NetResume, AClientMovingToAnotherServerOfTheFieldIsSentOnlyWhatIsNewer) {
  Endpoints e(1);
  NetServer& first = e.serve(0);
  NetServer& second = e.serve(0);
  client::FieldMirror mirror;
  client::NetClient mover(mirror, Endpoints::client(first, "mover", &second));
  mover.start();
  // Synced means every brick held, the first ones at the coarse sync level: wait for the
  // refinement too, so that what the client resumes from is the exact field.
  ASSERT_TRUE(waitFor(
      [&] { return mover.stats().synced && mirrorDifference(mirror, e.field(0)) == 0; }, 10.0));
  first.stop();  // its session ends: the client moves on to the second server
  const int changed = e.evolve(0, 0.2f, 4);
  ASSERT_GT(changed, 0);
  std::optional<NetClientInfo> moved;
  ASSERT_TRUE(waitFor(
      [&] {
        moved = currentClient(second, "mover");
        return moved && mirrorDifference(mirror, e.field(0)) == 0;
      },
      10.0));
  const NetServerStats s = second.stats();
  EXPECT_EQ(s.resumes, 1u);
  EXPECT_EQ(s.resumedBricks, 12u);  // every brick the mirror held, none refused
  EXPECT_EQ(s.resumeRefusedBricks, 0u);

  // A new client of the same server, for comparison: the whole field.
  client::FieldMirror freshMirror;
  client::NetClient fresh(freshMirror, Endpoints::client(second, "fresh"));
  fresh.start();
  std::optional<NetClientInfo> joined;
  ASSERT_TRUE(waitFor(
      [&] {
        joined = currentClient(second, "fresh");
        return joined && mirrorDifference(freshMirror, e.field(0)) == 0;
      },
      10.0));
  const double ratio = double(moved->bytesSent) / double(joined->bytesSent);
  std::printf("resumed: %llu bytes (%d of 12 bricks changed), fresh: %llu bytes, ratio %.3f\n",
              static_cast<unsigned long long>(moved->bytesSent), changed,
              static_cast<unsigned long long>(joined->bytesSent), ratio);
  EXPECT_LT(ratio, 0.25);
  fresh.stop();
  mover.stop();
}

TEST(NetResume, AMirrorOfAnotherFieldIsResyncedWhole) {
  Endpoints e(2);
  ASSERT_NE(e.epoch(0), e.epoch(1));
  NetServer& first = e.serve(0);
  NetServer& other = e.serve(1);
  client::FieldMirror mirror;
  client::NetClient mover(mirror, Endpoints::client(first, "mover", &other));
  mover.start();
  ASSERT_TRUE(waitFor(
      [&] { return mover.stats().synced && mirrorDifference(mirror, e.field(0)) == 0; }, 10.0));
  first.stop();
  ASSERT_TRUE(waitFor(
      [&] { return currentClient(other, "mover") && mirrorDifference(mirror, e.field(1)) == 0; },
      10.0));
  const NetServerStats s = other.stats();
  EXPECT_EQ(s.resumes, 0u);
  EXPECT_EQ(s.resumedBricks, 0u);
  mover.stop();
}

}  // namespace
}  // namespace pc::nettest
