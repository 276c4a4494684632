// The stream over an in-memory link with faults: loss up to 50% with bursts, duplication,
// reordering, corruption and delay, while the server's field changes. Once the faults stop the
// receiver must hold the server's field exactly as the codec quantizes it within 1 s of
// simulated time, and every queue and buffer must stay within its cap.
#include <gtest/gtest.h>
#include <malloc.h>

#include <algorithm>
#include <cstdio>
#include <memory>
#include <random>
#include <vector>

#include "protocol/stream_sender.h"
#include "protocol/stream_simulation.h"
#include "server/bake.h"
#include "server/tracer.h"
#include "test_protocol_support.h"
#include "test_tracer_support.h"

namespace {

using namespace pc;

FaultProfile harsh(double loss) {
  FaultProfile p;
  p.loss = loss;
  p.burstStart = 0.02;
  p.burstLength = 10;
  p.duplicate = 0.1;
  p.reorder = 0.2;
  p.reorderDelay = 0.06;
  p.corrupt = 0.05;
  p.delay = 0.03;
  p.jitter = 0.02;
  return p;
}

// The harsh profile's faults include a step of 20 ms in the path's delay with 20 ms of jitter
// and bursts of loss, which the delay-based congestion control reads as a standing queue with
// congestion loss, and it cuts the rate for faults it cannot relieve. These tests measure the
// loss recovery, so they run without it; test_rate_control.cpp measures the controller.
constexpr bool kHarshWithoutRateControl = false;

StreamSimulationOptions baseOptions(std::uint64_t seed) {
  StreamSimulationOptions o;
  o.seed = seed;
  o.warmupSeconds = 0.5;
  o.faultSeconds = 3.0;
  o.settleLimitSeconds = 3.0;
  o.calm.delay = 0.01;
  o.viewer = glm::vec3(0.0f, 1.0f, 0.0f);
  return o;
}

// Caps: every buffer the protocol holds is bounded by its configuration, whatever arrived.
void expectBounded(const StreamSimulationResult& r, const StreamSimulationOptions& o) {
  EXPECT_LE(r.maxDatagramBytes, kMaxDatagramBytes);
  EXPECT_LE(r.maxReassemblyUpdates, o.receiver.reassembly.maxUpdates);
  EXPECT_LE(r.maxReassemblyBytes, o.receiver.reassembly.maxBytes);
  EXPECT_LE(r.maxLinkInFlight, o.faults.queueLimit);
  EXPECT_LE(r.maxCacheBytes, o.publisher.maxCacheBytes + 2 * maxEncodedBrickBytes());
  EXPECT_LE(r.maxHistoryBytes, o.publisher.maxHistoryBytes + 32 * brick_layout::kCodes * 2);
  EXPECT_LE(r.maxDatagramsPerPoll, o.sender.maxDatagramsPerPoll);
  // Session messages do not pile up: acks are rate-limited.
  EXPECT_LE(r.maxControlInFlight, 64u);
}

void report(const char* name, const StreamSimulationResult& r) {
  std::printf(
      "%s: converged %d in %.3f s; sent %llu datagrams (%llu updates, %llu residual, %llu "
      "resends, %llu skipped); link lost %llu dup %llu corrupt %llu; receiver applied %llu, "
      "stale %llu, no base %llu, rejected %llu datagrams\n",
      name, int(r.converged), r.convergeSeconds, (unsigned long long)r.sender.datagrams,
      (unsigned long long)r.sender.updates, (unsigned long long)r.sender.residualUpdates,
      (unsigned long long)r.sender.resends, (unsigned long long)r.sender.skipped,
      (unsigned long long)r.link.lost, (unsigned long long)r.link.duplicated,
      (unsigned long long)r.link.corrupted, (unsigned long long)r.receiver.applied,
      (unsigned long long)r.receiver.stale, (unsigned long long)r.receiver.missingBase,
      (unsigned long long)r.receiver.rejectedDatagrams);
}

FieldAdvance syntheticAdvance(std::uint64_t seed, float share) {
  auto rng = std::make_shared<std::mt19937>(unsigned(seed));
  return [rng, share](Field& f, double t) { test::evolveField(f, *rng, share, float(t)); };
}

TEST(ProtocolStream, CalmLinkDeliversEverythingWithResiduals) {
  Field server = test::makeSyntheticLayout();
  StreamSimulationOptions o = baseOptions(1);
  o.faultSeconds = 1.0;  // "faults" that are none
  o.faults = o.calm;
  auto r = runStreamSimulation(server, syntheticAdvance(1, 0.3f), o);
  report("calm", r);
  ASSERT_TRUE(r.converged);
  EXPECT_LE(r.convergeSeconds, 1.0);
  EXPECT_EQ(test::differingBricks(r.mirror, test::quantizedCopy(server)), 0);
  EXPECT_GT(r.sender.residualUpdates, 0u);
  EXPECT_EQ(r.receiver.rejectedDatagrams, 0u);
  EXPECT_EQ(r.receiver.decodeErrors, 0u);
  // One version in flight per brick: on a link that loses nothing, no residual ever names a
  // base the client has already replaced, so nothing needs a repair.
  EXPECT_EQ(r.receiver.missingBase, 0u);
  EXPECT_EQ(r.sender.reasons.repair, 0u);
  // Every update sent has exactly one reason.
  const auto& why = r.sender.reasons;
  EXPECT_EQ(why.first + why.irradiance + why.irradianceMean + why.depth + why.occlusion +
                why.offset + why.state + why.settled + why.refresh + why.repair + why.timeout,
            r.sender.updates);
  EXPECT_GT(why.first, 0u);
  expectBounded(r, o);
}

class ProtocolFaults : public ::testing::TestWithParam<double> {};

TEST_P(ProtocolFaults, ConvergesWithinOneSecondAfterFaultsStop) {
  const double loss = GetParam();
  for (std::uint64_t seed : {11u, 12u, 13u}) {
    Field server = test::makeSyntheticLayout();
    StreamSimulationOptions o = baseOptions(seed);
    o.faults = harsh(loss);
    o.sender.congestionControl = kHarshWithoutRateControl;
    auto r = runStreamSimulation(server, syntheticAdvance(seed, 0.3f), o);
    char name[64];
    std::snprintf(name, sizeof name, "loss %.0f%% seed %llu", loss * 100, (unsigned long long)seed);
    report(name, r);
    ASSERT_TRUE(r.converged) << name;
    EXPECT_LE(r.convergeSeconds, 1.0) << name;
    // Exactly what the codec makes of the server's field: within the stated bounds.
    EXPECT_EQ(test::differingBricks(r.mirror, test::quantizedCopy(server)), 0) << name;
    EXPECT_EQ(r.receiver.decodeErrors, 0u) << name;  // corruption never gets past the CRC
    if (loss > 0) {
      EXPECT_GT(r.link.lost, 0u);
    }
    EXPECT_GT(r.link.corrupted, 0u);
    EXPECT_GT(r.receiver.rejectedDatagrams, 0u);
    expectBounded(r, o);
  }
}

INSTANTIATE_TEST_SUITE_P(Loss, ProtocolFaults, ::testing::Values(0.0, 0.1, 0.3, 0.5));

TEST(ProtocolStream, FieldThatKeepsChangingStaysCloseBehind) {
  // No freeze: the field changes throughout. After the faults the receiver must catch up to
  // versions at most a few updates old (a moving target is never matched exactly).
  Field server = test::makeSyntheticLayout();
  StreamSimulationOptions o = baseOptions(21);
  o.faults = harsh(0.3);
  o.sender.congestionControl = kHarshWithoutRateControl;
  o.freezeAfterFaults = false;
  o.settleLimitSeconds = 1.0;
  auto r = runStreamSimulation(server, syntheticAdvance(21, 0.2f), o);
  report("moving", r);
  const Field& m = r.mirror;
  int behind = 0, bricks = 0;
  for (int k = 0; k < server.cascadeCount(); ++k) {
    for (std::size_t b = 0; b < server.brickVersions[k].size(); ++b) {
      ++bricks;
      // Within 0.5 s of updates (15 at 30 Hz) of the server's version.
      behind += m.brickVersions[k][b] + 15 < server.brickVersions[k][b];
    }
  }
  EXPECT_EQ(behind, 0) << "of " << bricks;
  expectBounded(r, o);
}

class LargeBricksUnderLoss : public ::testing::TestWithParam<double> {};

TEST_P(LargeBricksUnderLoss, ArriveWhileEveryBrickChangesEveryUpdate) {
  // Bricks that do not compress (tens of fragments each), every one changing every update, and
  // 20% or 50% of the datagrams lost from the start. A send arrives whole with probability
  // (1 - loss)^n, under 1e-5 for these bricks, so the receiver only ever holds them because it
  // completes them from the fragments of several sends: the fragments its acks report missing
  // (selective repair), and lost updates resent whole as they were. Without the reports (the
  // second run) it takes far longer.
  const double loss = GetParam();
  auto run = [&](bool reportGaps, Field& server) {
    auto rng = std::make_shared<std::mt19937>(61u);
    test::evolveNoisyField(server, *rng, 0.0f);
    StreamSimulationOptions o = baseOptions(61);
    o.warmupSeconds = 0.0;
    o.faultSeconds = 5.0;
    o.faults.loss = loss;
    o.faults.delay = 0.01;
    o.settleLimitSeconds = 3.0;
    o.receiver.reportGaps = reportGaps;
    // The repairs are what is measured, not the congestion control's start: it starts at the
    // ceiling, as on a link known to carry it.
    o.sender.rateControl.startRate = o.sender.bytesPerSecond;
    auto r = runStreamSimulation(
        server, [rng](Field& f, double t) { test::evolveNoisyField(f, *rng, float(t)); }, o);
    expectBounded(r, o);
    return r;
  };
  Field server = test::makeSyntheticLayout(), wholeOnly = test::makeSyntheticLayout();
  auto r = run(true, server);
  auto whole = run(false, wholeOnly);
  report(loss < 0.3 ? "large bricks, 20% loss" : "large bricks, 50% loss", r);
  FieldPublisher sizes(server);
  ASSERT_TRUE(sizes.publish(server, 0.0).ok());
  const std::size_t fragments =
      fragmentCount(sizes.encoded(0, 0, server.version, 0)->header.totalSize);
  std::printf(
      "a self-contained brick: %zu fragments; every brick held after %.2f s (%llu "
      "fragments repaired), %.2f s with whole resends alone\n",
      fragments, r.heldEverySeconds, (unsigned long long)r.sender.repairedFragments,
      whole.heldEverySeconds);
  EXPECT_GE(fragments, 40u);
  ASSERT_GE(r.heldEverySeconds, 0.0) << "some brick never arrived while the field changed";
  EXPECT_GT(r.sender.repairedFragments, 0u);
  EXPECT_LE(r.heldEverySeconds, loss < 0.3 ? 0.6 : 1.2);
  EXPECT_TRUE(whole.heldEverySeconds < 0 || whole.heldEverySeconds > 2.0 * r.heldEverySeconds)
      << whole.heldEverySeconds;
  ASSERT_TRUE(r.converged);
  EXPECT_EQ(test::differingBricks(r.mirror, test::quantizedCopy(server)), 0);
}

INSTANTIATE_TEST_SUITE_P(Loss, LargeBricksUnderLoss, ::testing::Values(0.2, 0.5));

TEST(ProtocolStream, EveryBrickArrivesWhileNearBricksKeepChanging) {
  // Every brick changes every update and the link carries a fraction of the changes, as with a
  // fast tracer. Bricks near the viewer go first, but a brick the client lacks goes before a
  // newer version of one it holds: the client comes to hold every brick at about the rate the
  // link carries their first versions, instead of spending the link on the near bricks.
  Field server = test::makeSyntheticLayout();
  auto rng = std::make_shared<std::mt19937>(71u);
  test::evolveNoisyField(server, *rng, 0.0f);
  StreamSimulationOptions o = baseOptions(71);
  o.viewer = glm::vec3(-2.0f, 0.0f, -2.0f);  // a corner of the fine cascade
  o.warmupSeconds = 0.0;
  o.faultSeconds = 6.0;
  o.faults.delay = 0.02;
  o.sender.bytesPerSecond = 300e3;
  o.sender.burstBytes = 32e3;
  o.settleLimitSeconds = 8.0;
  auto r = runStreamSimulation(
      server, [rng](Field& f, double t) { test::evolveNoisyField(f, *rng, float(t)); }, o);
  report("near bricks changing", r);
  FieldPublisher sizes(server);
  ASSERT_TRUE(sizes.publish(server, 0.0).ok());
  std::size_t firstBytes = 0;
  for (int k = 0; k < server.cascadeCount(); ++k)
    for (int b = 0; b < sizes.brickCount(k); ++b)
      firstBytes += sizes.encoded(k, b, server.version, 0)->payload.size();
  const double linkSeconds = double(firstBytes) / o.sender.bytesPerSecond;
  std::printf("every brick's first version: %.2f s of the link; every brick held after %.2f s\n",
              linkSeconds, r.heldEverySeconds);
  ASSERT_GE(r.heldEverySeconds, 0.0) << "some brick never arrived while the field changed";
  EXPECT_LE(r.heldEverySeconds, 1.5 * linkSeconds + 0.5);
  expectBounded(r, o);
}

TEST(ProtocolStream, TightRateLimitStillConverges) {
  // A client on a slow link: a rate limit of about a third of what the changes need. It gets
  // the newest state, not a backlog, and converges once the field stops changing.
  Field server = test::makeSyntheticLayout();
  StreamSimulationOptions o = baseOptions(31);
  o.faults = harsh(0.1);
  o.sender.congestionControl = kHarshWithoutRateControl;
  o.sender.bytesPerSecond = 150e3;
  o.sender.burstBytes = 32e3;
  o.settleLimitSeconds = 5.0;
  auto r = runStreamSimulation(server, syntheticAdvance(31, 0.5f), o);
  report("slow link", r);
  ASSERT_TRUE(r.converged);
  EXPECT_EQ(test::differingBricks(r.mirror, test::quantizedCopy(server)), 0);
  // The link never held more than about a second of data: nothing queued up behind it.
  EXPECT_LE(double(r.maxLinkInFlight) * 1000.0, 1.5 * o.sender.bytesPerSecond);
  expectBounded(r, o);
}

TEST(ProtocolStream, SmallChangesWaitThenSettle) {
  // Changes far below the perceptual threshold are held back while the field keeps moving,
  // then sent once it has been still for the settle time: the receiver still converges.
  Field server = test::makeSyntheticLayout();
  StreamSimulationOptions o = baseOptions(51);
  o.faults = harsh(0.2);
  o.sender.congestionControl = kHarshWithoutRateControl;
  o.sender.irradianceThreshold = 0.05f;
  o.sender.depthThreshold = 0.05f;
  o.sender.occlusionThreshold = 0.1f;
  o.sender.refreshInterval = 2.0;
  auto rng = std::make_shared<std::mt19937>(51u);
  // Slow drift: a phase step of 0.01 per update changes e by about 0.003.
  auto advance = [rng](Field& f, double t) { test::evolveField(f, *rng, 0.3f, float(t) * 0.3f); };
  auto r = runStreamSimulation(server, advance, o);
  report("small changes", r);
  EXPECT_GT(r.sender.skipped, 0u);
  ASSERT_TRUE(r.converged);
  EXPECT_LE(r.convergeSeconds, 1.0);
  EXPECT_EQ(test::differingBricks(r.mirror, test::quantizedCopy(server)), 0);
  expectBounded(r, o);
}

TEST(ProtocolStream, TracedFieldOfTheBuiltinScene) {
  // A real field: the built-in room, baked briefly, then updated by the Embree tracer as the
  // light moves, so changes have the tracer's noise and its brick versioning.
  Scene scene = builtinScene();
  FieldSettings settings;
  settings.raysPerProbe = 32;
  Field server = Field::create(defaultVolumes(scene, 6), settings);
  server.sceneHash = scene.hash;
  auto tracer = makeEmbreeTracer(scene);
  ASSERT_TRUE(tracer.ok()) << tracer.error().message;
  BakeOptions bake;
  bake.updates = 6;
  bakeOrFail(server, **tracer, bake);
  std::uint32_t seed = 1000;
  auto advance = [&](Field& f, double t) {
    setStateOrFail(**tracer, evaluateScene(scene, t));
    UpdateRequest req;
    req.rotationSeed = seed++;
    req.probes = allProbes(f);
    req.changeThreshold = 1e-4f;
    updateOrFail(**tracer, f, req);
  };
  StreamSimulationOptions o = baseOptions(41);
  o.faults = harsh(0.3);
  o.sender.congestionControl = kHarshWithoutRateControl;
  o.faultSeconds = 1.5;
  o.tickInterval = 0.1;  // keep the tracer's share of the test time small
  auto r = runStreamSimulation(server, advance, o);
  report("traced", r);
  ASSERT_TRUE(r.converged);
  EXPECT_LE(r.convergeSeconds, 1.0);
  EXPECT_EQ(test::differingBricks(r.mirror, test::quantizedCopy(server)), 0);
  expectBounded(r, o);
}

TEST(ProtocolStream, PublisherKeepsSentVersionsAsResidualBases) {
  Field f = test::makeSyntheticLayout();
  std::mt19937 rng(7);
  test::evolveField(f, rng, 1.0f, 0.0f);
  PublisherOptions o;
  o.historyVersions = 2;
  o.sentVersions = 1;
  FieldPublisher publisher(f, o);
  ASSERT_TRUE(publisher.publish(f, 0.0).ok());
  const std::uint64_t sent = f.brickVersions[0][0];
  ASSERT_TRUE(publisher.encoded(0, 0, sent, 0));
  std::uint64_t unsent = 0;
  for (int i = 1; i <= 6; ++i) {
    test::evolveField(f, rng, 1.0f, 0.1f * float(i));
    ASSERT_TRUE(publisher.publish(f, 0.1 * i).ok());
    if (i == 1) unsent = f.brickVersions[0][0];
  }
  // The version a client was sent (and may acknowledge) stays as a base; others age out.
  EXPECT_TRUE(publisher.find(0, 0, sent));
  EXPECT_FALSE(publisher.find(0, 0, unsent));
  auto residual = publisher.encoded(0, 0, f.brickVersions[0][0], sent);
  ASSERT_TRUE(residual);
  EXPECT_EQ(residual->header.baseVersion, sent);
}

// The publisher's memory is bounded by the field, not by how long it runs or what clients do:
// after many versions, with clients that each hold back their acks by a different number of
// versions (one never acknowledges past the first), the history and the encode cache stay
// within bricks x versions kept, and the process heap stops growing.
TEST(ProtocolStream, PublisherMemoryStaysWithinTheFieldsBound) {
  Field f = test::makeSyntheticLayout();
  std::mt19937 rng(11);
  test::evolveField(f, rng, 1.0f, 0.0f);
  // The 4 newest versions and 2 more that were sent (the defaults keep 16 sent ones: the same
  // arithmetic, with bounds four times these).
  PublisherOptions o;
  o.historyVersions = 4;
  o.sentVersions = 2;
  FieldPublisher publisher(f, o);
  std::size_t bricks = 0;
  for (int k = 0; k < publisher.cascadeCount(); ++k) bricks += std::size_t(publisher.brickCount(k));
  ASSERT_EQ(bricks, 12u);
  const std::size_t kept = std::size_t(o.historyVersions + o.sentVersions);
  const std::size_t brickBytes = brick_layout::kCodes * sizeof(std::uint16_t);
  // The stated bounds (FieldPublisher::historyBoundBytes, cacheBoundBytes); for these 12
  // bricks under 6 MB and 8 MB, far below the 256 MiB and 64 MiB caps.
  EXPECT_EQ(publisher.historyBoundBytes(), bricks * (kept - 1) * brickBytes);
  EXPECT_EQ(publisher.cacheBoundBytes(), (bricks * kept + 1) * maxEncodedBrickBytes());
  EXPECT_LT(publisher.historyBoundBytes(), 6000000u);
  EXPECT_LT(publisher.cacheBoundBytes(), 8000000u);

  SenderOptions so;
  so.bytesPerSecond = 1e9;
  so.burstBytes = 1e9;
  so.selfContainedInterval = 1e9;  // residuals on whatever each client acknowledged
  BrickChangeCache changes;
  // Versions each client's acks lag behind the newest; the last one acks only version 1.
  const std::vector<int> lags = {0, 1, 2, 3, 5, 8, 1000000};
  std::vector<std::unique_ptr<StreamSender>> senders;
  for (std::size_t c = 0; c < lags.size(); ++c) {
    senders.push_back(
        std::make_unique<StreamSender>(publisher, std::uint32_t(c + 1), so, &changes));
  }
  std::vector<std::uint64_t> published;
  std::size_t heapAfterWarmup = 0;
  const int rounds = 150, warmup = 50;
  for (int round = 0; round < rounds; ++round) {
    if (round > 0) test::evolveField(f, rng, 1.0f, 0.05f * float(round));
    const double now = 0.5 * round;
    ASSERT_TRUE(publisher.publish(f, now).ok());
    published.push_back(f.version);
    for (std::size_t c = 0; c < senders.size(); ++c) {
      const std::size_t lag = std::min(std::size_t(lags[c]), published.size() - 1);
      AckMsg ack;
      ack.fieldVersion = published[published.size() - 1 - lag];
      for (int k = 0; k < publisher.cascadeCount(); ++k) {
        ack.ranges.push_back(AckRange{k, 0, std::uint32_t(publisher.brickCount(k)),
                                      published[published.size() - 1 - lag]});
      }
      ASSERT_TRUE(senders[c]->onMessage(SessionMessage{ack}, now + 0.1).ok());
      EXPECT_FALSE(senders[c]->poll(now + 0.3).empty());
    }
    ASSERT_LE(publisher.historyBytes(), publisher.historyBoundBytes()) << "round " << round;
    ASSERT_LE(publisher.cache().bytes(), publisher.cacheBoundBytes()) << "round " << round;
    ASSERT_LE(publisher.cache().entries(), bricks * kept) << "round " << round;
    if (round + 1 == warmup) heapAfterWarmup = mallinfo2().uordblks;
  }
  // Residuals on many bases were encoded (the cache saw more than its bound's worth).
  EXPECT_GT(publisher.encodes(), bricks * kept * 4);
  // An encoded payload holds no more heap than its bytes (compressing needs a buffer of
  // maxEncodedBrickBytes; a payload that kept it would cost ~20x its size in the cache).
  auto update = publisher.encoded(0, 0, publisher.current(0, 0).version, 0);
  ASSERT_TRUE(update);
  EXPECT_EQ(update->payload.capacity(), update->payload.size());
  // The heap after 100 more versions: flat to within 2 MB (the encode cache alone would grow
  // by about 7 MB per version if it kept what can no longer be sent at that size).
  const double growth = double(mallinfo2().uordblks) - double(heapAfterWarmup);
  std::printf(
      "publisher memory: history %zu B (bound %zu), encode cache %zu B in %zu entries "
      "(bound %zu), %llu encodes; heap growth over the last %d versions %.0f B\n",
      publisher.historyBytes(), publisher.historyBoundBytes(), publisher.cache().bytes(),
      publisher.cache().entries(), publisher.cacheBoundBytes(),
      (unsigned long long)publisher.encodes(), rounds - warmup, growth);
  EXPECT_LT(growth, 2e6);
}

}  // namespace

namespace {

// Clients that acknowledge versions a second apart at 10 updates/s hold bases about ten
// versions back, every one of which was sent to someone: the defaults keep them, so the next
// update of each is a residual rather than a self-contained brick.
TEST(ProtocolStream, DefaultsKeepBasesTenSentVersionsBack) {
  Field f = test::makeSyntheticLayout();
  std::mt19937 rng(12);
  test::evolveField(f, rng, 1.0f, 0.0f);
  FieldPublisher publisher(f);
  ASSERT_TRUE(publisher.publish(f, 0.0).ok());
  const std::uint64_t first = publisher.current(0, 0).version;
  ASSERT_TRUE(publisher.encoded(0, 0, first, 0));  // sent to a client, which holds it
  for (int round = 1; round <= 12; ++round) {
    test::evolveField(f, rng, 1.0f, 0.1f * float(round));
    ASSERT_TRUE(publisher.publish(f, 0.1 * round).ok());
    // Every version goes to some other client.
    ASSERT_TRUE(publisher.encoded(0, 0, publisher.current(0, 0).version, 0));
  }
  const std::uint64_t now = publisher.current(0, 0).version;
  ASSERT_GE(now, first + 12);
  EXPECT_TRUE(publisher.find(0, 0, first)) << "the base 12 sent versions back left the history";
  auto residual = publisher.encoded(0, 0, now, first);
  ASSERT_TRUE(residual);
  EXPECT_EQ(residual->header.baseVersion, first);
}

}  // namespace
