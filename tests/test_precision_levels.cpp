// Precision levels: the quality ladder's coarser versions (protocol/brick_precision.h). A client
// whose link cannot carry every change is sent versions rounded to fewer bits; it must hold
// exactly what the sender believes it holds (residuals build on it), say which level it holds,
// and come back to the codec's own precision once the rate allows.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <memory>
#include <random>
#include <vector>

#include "protocol/brick_precision.h"
#include "protocol/datagram.h"
#include "protocol/field_publisher.h"
#include "protocol/session_messages.h"
#include "protocol/stream_receiver.h"
#include "protocol/stream_simulation.h"
#include "test_protocol_support.h"

namespace {

using namespace pc;
using namespace pc::brick_layout;

// Codes in every section's range, with zeros among them.
QuantizedBrick randomBrick(std::uint32_t seed) {
  std::mt19937 rng(seed);
  QuantizedBrick q;
  q.codes.resize(kCodes);
  auto in = [&](std::uint32_t lo, std::uint32_t hi) {
    return std::uint16_t(std::uniform_int_distribution<std::uint32_t>(lo, hi)(rng));
  };
  for (std::size_t i = 0; i < kCodes; ++i) {
    if (i < kDepth)
      q.codes[i] = in(0, 9) == 0 ? 0 : in(128, 4095);
    else if (i < kOcclusion)
      q.codes[i] = in(0, 65535);
    else if (i < kOffset)
      q.codes[i] = in(0, 255);
    else if (i < kState)
      q.codes[i] = in(0, 65535);
    else
      q.codes[i] = in(0, 2);
  }
  // The tops of each range, where rounding up would leave it.
  q.codes[kIrradiance] = 4095;
  q.codes[kDepth] = 65535;
  q.codes[kOcclusion] = 255;
  return q;
}

TEST(PrecisionLevels, CoarseCodesStayWithinHalfAStepAndKeepOffsetsAndStates) {
  const QuantizedBrick q = randomBrick(7);
  EXPECT_EQ(coarsenBrick(q, 0), q);
  for (int level = 1; level <= kMaxPrecision + 1; ++level) {
    const QuantizedBrick c = coarsenBrick(q, level);
    ASSERT_EQ(c.codes.size(), q.codes.size());
    EXPECT_EQ(coarsenBrick(c, level), c) << "level " << level << " is not idempotent";
    const int clamped = std::min(level, kMaxPrecision);
    const struct {
      std::size_t begin, end;
      int bits;
      std::uint32_t max;
    } sections[] = {{kDepth, kOcclusion, droppedDepthBits(clamped), 65535},
                    {kOcclusion, kOffset, droppedOcclusionBits(clamped), 255}};
    std::size_t changed = 0;
    for (const auto& s : sections) {
      ASSERT_GT(s.bits, 0);
      const std::uint32_t step = 1u << s.bits;
      for (std::size_t i = s.begin; i < s.end; ++i) {
        const int d = std::abs(int(c.codes[i]) - int(q.codes[i]));
        // Half a step, or (at the top of the range, rounded down) less than a step.
        EXPECT_LE(d, int(q.codes[i] > s.max - step ? step - 1 : step / 2)) << "code " << i;
        EXPECT_LE(c.codes[i], s.max);
        if (q.codes[i] == 0) {
          EXPECT_EQ(c.codes[i], 0) << "zero moved at " << i;
        }
        if (c.codes[i] != 0) {
          EXPECT_EQ(c.codes[i] % step, 0u) << "code " << i;
        }
        changed += d != 0;
      }
    }
    EXPECT_GT(changed, (kOffset - kDepth) / 4) << "level " << level << " rounded almost nothing";
    // Irradiance: a step of at most 2^(L-8) in the gamma-encoded e, so an error of at most half
    // that, wherever the value lies; codes whose step would be finer than the codec's stay.
    const float bound = std::ldexp(1.0f, clamped - 9);
    std::size_t rounded = 0, exact = 0;
    for (std::size_t i = kIrradiance; i < kDepth; ++i) {
      const float e = dequantizeIrradiance(q.codes[i]);
      const float err = std::abs(dequantizeIrradiance(c.codes[i]) - e);
      EXPECT_LE(err, bound * 1.0001f) << "code " << q.codes[i] << " at level " << clamped;
      if (q.codes[i] == 0) {
        EXPECT_EQ(c.codes[i], 0);
      }
      rounded += c.codes[i] != q.codes[i];
      // Where one mantissa step of the codec is already coarser than the level's, untouched.
      if (std::ldexp(e, -7) > 2.0f * bound) {
        EXPECT_EQ(c.codes[i], q.codes[i]);
        ++exact;
      }
    }
    EXPECT_GT(rounded, 0u);
    EXPECT_GT(exact, 0u);
    for (std::size_t i = kOffset; i < kCodes; ++i) ASSERT_EQ(c.codes[i], q.codes[i]);
  }
}

UpdateHeader header(std::uint64_t version, std::uint64_t base, int precision, int basePrecision) {
  UpdateHeader u;
  u.updateId = 99;
  u.brick = 3;
  u.version = version;
  u.baseVersion = base;
  u.codec = kCodecQuantZstd;
  u.totalSize = 16;
  u.precision = std::uint8_t(precision);
  u.basePrecision = std::uint8_t(basePrecision);
  return u;
}

Result<Datagram> roundTrip(const UpdateHeader& u) {
  const std::vector<std::uint8_t> data(u.totalSize, 7);
  const FragmentRef f{u, 0, data};
  return decodeDatagram(encodeDatagram(1, 1, u.version, std::span(&f, 1)));
}

TEST(PrecisionLevels, DatagramsCarryLevelsAndRefuseWhatNoSenderMakes) {
  // A coarse residual, and a refinement of a version held coarser (its own version as base).
  for (const UpdateHeader& u : {header(9, 5, 2, 1), header(9, 9, 0, 3), header(9, 0, 4, 0)}) {
    auto d = roundTrip(u);
    ASSERT_TRUE(d.ok()) << d.error().message;
    ASSERT_EQ(d->fragments.size(), 1u);
    EXPECT_TRUE(d->fragments[0].update.sameUpdate(u));
  }
  // Beyond the coarsest level; a "refinement" that is not finer; a self-contained update
  // naming its own version.
  for (const UpdateHeader& u : {header(9, 5, kMaxPrecision + 1, 0), header(9, 5, 0, 200),
                                header(9, 9, 2, 2), header(9, 9, 3, 1)}) {
    auto d = roundTrip(u);
    EXPECT_FALSE(d.ok()) << "accepted precision " << int(u.precision) << " on "
                         << int(u.basePrecision) << ", version " << u.version << " on "
                         << u.baseVersion;
  }
}

TEST(PrecisionLevels, AcksAndRepairRequestsSayWhichLevelIsHeld) {
  AckMsg ack;
  ack.full = true;
  ack.ranges = {AckRange{0, 0, 4, 12}, AckRange{1, 2, 1, 15}};
  ack.precisions = {BrickPrecisionMsg{0, 1, 3}, BrickPrecisionMsg{1, 2, 4}};
  auto m = decodeMessage(encodeMessage(ack));
  ASSERT_TRUE(m.ok()) << m.error().message;
  const auto& back = std::get<AckMsg>(*m);
  ASSERT_EQ(back.precisions.size(), 2u);
  EXPECT_EQ(back.precisions[1].cascade, 1);
  EXPECT_EQ(back.precisions[1].brick, 2u);
  EXPECT_EQ(back.precisions[1].precision, 4);

  RepairRequestMsg repair;
  repair.bricks = {BrickRefMsg{0, 1, 12, 0}, BrickRefMsg{0, 2, 12, 2}};
  auto r = decodeMessage(encodeMessage(repair));
  ASSERT_TRUE(r.ok()) << r.error().message;
  const auto& rb = std::get<RepairRequestMsg>(*r);
  ASSERT_EQ(rb.bricks.size(), 2u);
  EXPECT_EQ(rb.bricks[0].havePrecision, 0);
  EXPECT_EQ(rb.bricks[1].havePrecision, 2);

  ack.precisions[0].precision = kMaxPrecision + 1;
  EXPECT_FALSE(decodeMessage(encodeMessage(ack)).ok());
  // More levels than bricks listed.
  ack.precisions.assign(6, BrickPrecisionMsg{0, 0, 1});
  EXPECT_FALSE(decodeMessage(encodeMessage(ack)).ok());
  repair.bricks[1].havePrecision = 9;
  EXPECT_FALSE(decodeMessage(encodeMessage(repair)).ok());
}

// Keeps what the receiver decoded last: the codes it holds.
class RecordingDecoder final : public BrickDecoder {
 public:
  Result<std::shared_ptr<const QuantizedBrick>> decode(
      const UpdateHeader&, std::span<const std::uint8_t> payload,
      const std::shared_ptr<const QuantizedBrick>& base) override {
    auto q = decodeBrick(payload, base.get());
    if (!q) return q.error();
    last = std::make_shared<const QuantizedBrick>(std::move(q).value());
    return last;
  }
  std::shared_ptr<const QuantizedBrick> last;
};

// Every fragment of an update, one datagram each.
std::vector<std::vector<std::uint8_t>> datagramsOf(const EncodedUpdate& u, std::uint32_t session,
                                                   std::uint32_t& sequence) {
  std::vector<std::vector<std::uint8_t>> out;
  for (std::uint16_t i = 0; i < fragmentCount(u.header.totalSize); ++i) {
    const std::size_t begin = std::size_t(i) * kFragmentBytes;
    const FragmentRef f{
        u.header, i,
        std::span(u.payload).subspan(begin, std::min(kFragmentBytes, u.payload.size() - begin))};
    out.push_back(encodeDatagram(session, sequence++, u.header.version, std::span(&f, 1)));
  }
  return out;
}

TEST(PrecisionLevels, ReceiverHoldsTheCoarseLevelRefinesItAndSaysSo) {
  Field server = test::makeSyntheticLayout();
  std::mt19937 rng(3);
  test::evolveField(server, rng, 1.0f, 0.0f);
  FieldPublisher publisher(server);
  ASSERT_TRUE(publisher.publish(server, 0.0).ok());
  RecordingDecoder decoder;
  ReceiverOptions ro;
  ro.decoder = &decoder;
  ro.reportArrivals = false;
  auto rx = StreamReceiver::create(publisher.sessionInfo(), 77, ro);
  ASSERT_TRUE(rx.ok()) << rx.error().message;
  const int k = 0, b = 0;
  const std::uint64_t v1 = publisher.current(k, b).version;
  ASSERT_NE(v1, 0u);
  std::uint32_t sequence = 1;
  auto deliver = [&](const EncodedUpdate& u, double now) {
    Status last;
    for (const auto& d : datagramsOf(u, 77, sequence)) last = rx->onDatagram(d, now);
    return last.ok();
  };

  auto coarse = publisher.encoded(k, b, v1, 0, 3, 0);
  ASSERT_TRUE(coarse);
  ASSERT_TRUE(deliver(*coarse, 0.1));
  EXPECT_EQ(rx->brickVersion(k, b), v1);
  EXPECT_EQ(rx->brickPrecision(k, b), 3);
  EXPECT_EQ(*decoder.last, coarsenBrick(*publisher.find(k, b, v1), 3));
  // Its acks name the level.
  bool named = false;
  for (const auto& frame : rx->poll(0.2)) {
    auto m = decodeMessage(frame);
    ASSERT_TRUE(m.ok());
    if (const auto* ack = std::get_if<AckMsg>(&*m)) {
      for (const auto& p : ack->precisions)
        named |= p.cascade == k && p.brick == 0 && p.precision == 3;
    }
  }
  EXPECT_TRUE(named);

  // A newer version built on the exact codes of v1, which this client does not hold: refused,
  // and the repair request says the level it holds.
  std::mt19937 rng2(4);
  test::evolveField(server, rng2, 1.0f, 0.5f);
  ASSERT_TRUE(publisher.publish(server, 0.3).ok());
  const std::uint64_t v2 = publisher.current(k, b).version;
  ASSERT_GT(v2, v1);
  auto wrongBase = publisher.encoded(k, b, v2, v1, 0, 0);
  ASSERT_TRUE(wrongBase);
  ASSERT_TRUE(deliver(*wrongBase, 0.35));
  EXPECT_EQ(rx->brickVersion(k, b), v1);
  EXPECT_EQ(rx->stats().missingBase, 1u);
  bool asked = false;
  for (const auto& frame : rx->poll(0.6)) {
    auto m = decodeMessage(frame);
    ASSERT_TRUE(m.ok());
    if (const auto* repair = std::get_if<RepairRequestMsg>(&*m)) {
      for (const auto& r : repair->bricks)
        asked |= r.brick == 0 && r.haveVersion == v1 && r.havePrecision == 3;
    }
  }
  EXPECT_TRUE(asked);

  // A refinement of v1 on the coarse codes it holds: the exact codes.
  auto refine = publisher.encoded(k, b, v1, v1, 0, 3);
  ASSERT_TRUE(refine);
  ASSERT_TRUE(deliver(*refine, 0.7));
  EXPECT_EQ(rx->brickPrecision(k, b), 0);
  EXPECT_EQ(*decoder.last, *publisher.find(k, b, v1));
  // The coarse update again (reordered, late): stale, changes nothing.
  const std::uint64_t applied = rx->stats().applied;
  ASSERT_TRUE(deliver(*coarse, 0.8));
  EXPECT_EQ(rx->stats().applied, applied);
  EXPECT_EQ(rx->brickPrecision(k, b), 0);
  // Now v2 on the exact v1 applies.
  ASSERT_TRUE(deliver(*wrongBase, 0.9));
  EXPECT_EQ(rx->brickVersion(k, b), v2);
  EXPECT_EQ(*decoder.last, *publisher.find(k, b, v2));
}

// A link that carries about a third of what the field's changes need: with precision levels
// the client's oldest change stays younger than without them, the held field stays close, and
// once the field stops changing the client converges to the exact field (refined to level 0).
TEST(PrecisionLevels, ShortLinkHoldsACoarseButCurrentFieldThenTheExactOne) {
  auto run = [](int maxPrecision) {
    Field server = test::makeSyntheticLayout();
    StreamSimulationOptions o;
    o.seed = 5;
    o.warmupSeconds = 1.0;
    o.faultSeconds = 6.0;  // the "fault" is the short link alone
    // Refining every brick from the coarsest level takes several seconds of this link.
    o.settleLimitSeconds = 15.0;
    o.calm.delay = 0.01;
    o.faults.delay = 0.01;
    o.tickInterval = 0.1;
    o.sender.congestionControl = false;
    o.sender.bytesPerSecond = 60e3;
    o.sender.burstBytes = 8e3;
    o.sender.maxPrecision = maxPrecision;
    auto rng = std::make_shared<std::mt19937>(5u);
    auto advance = [rng](Field& f, double t) { test::evolveWithRayNoise(f, *rng, float(t)); };
    auto r = runStreamSimulation(server, advance, o);
    EXPECT_TRUE(r.converged) << "precision " << maxPrecision;
    EXPECT_EQ(test::differingBricks(r.mirror, test::quantizedCopy(server)), 0);
    return r;
  };
  const StreamSimulationResult exact = run(0);
  const StreamSimulationResult coarse = run(kMaxPrecision);
  const double ageExact = test::percentile(exact.heldAges, 0.95);
  const double ageCoarse = test::percentile(coarse.heldAges, 0.95);
  const double psnrExact = test::percentile(exact.heldPsnrs, 0.05);
  const double psnrCoarse = test::percentile(coarse.heldPsnrs, 0.05);
  std::printf(
      "short link: oldest change p95 %.2f s exact, %.2f s with levels; held PSNR p5 %.1f / "
      "%.1f dB; %llu of %llu updates coarse, %llu refinements; converged after %.2f / %.2f s\n",
      ageExact, ageCoarse, psnrExact, psnrCoarse, (unsigned long long)coarse.sender.coarseUpdates,
      (unsigned long long)coarse.sender.updates, (unsigned long long)coarse.sender.reasons.refine,
      exact.convergeSeconds, coarse.convergeSeconds);
  EXPECT_EQ(exact.sender.coarseUpdates, 0u);
  EXPECT_GT(coarse.sender.coarseUpdates, 0u);
  EXPECT_GT(coarse.sender.reasons.refine, 0u);
  EXPECT_LT(ageCoarse, ageExact);
}

}  // namespace
