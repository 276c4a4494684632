// The quality ladder of StreamSender: a client whose link is short of what the field's changes
// need is sent coarser versions, and comes back to full quality once its link has room, even
// while the field keeps changing. The sender's own held-field measures (HeldFieldReport) over
// a whole stream in memory (runStreamSimulation), behind a bottleneck with congestion control.
#include <gtest/gtest.h>

#include <cstdio>
#include <memory>
#include <random>
#include <vector>

#include "protocol/stream_simulation.h"
#include "protocol/stream_tuning.h"
#include "test_protocol_support.h"

namespace {

using namespace pc;

struct LadderRun {
  StreamSimulationResult result;
  double shortPsnrP5 = 0, shortAgeP95 = 0;  // fault phase: the short link
  double widePsnrP5 = 0, wideAgeP95 = 0;    // the last 2 s of the wide link
  int wideLevel = 0;                        // the highest level over the last 2 s
};

// 1 s on a wide link, `shortSeconds` on a link of `shortRate` bytes/s, then 10 s on a wide link
// again; the field's light moves at 10 updates/s all along (it never stops changing). The
// server's stream tuning (dead zone and thresholds of StreamTuning's default T).
LadderRun runLadder(double shortRate, double shortSeconds, const SenderOptions& sender = {}) {
  Field server = test::makeSyntheticLayout();
  StreamSimulationOptions o;
  o.seed = 11;
  o.warmupSeconds = 1.0;
  o.faultSeconds = shortSeconds;
  o.settleLimitSeconds = 10.0;
  o.freezeAfterFaults = false;
  o.tickInterval = 0.1;
  o.calm.delay = 0.01;
  o.calm.rate = 2e6;
  o.calm.queueBytes = 200'000;
  o.faults.delay = 0.01;
  o.faults.rate = shortRate;
  o.faults.queueBytes = std::size_t(shortRate * 0.1);  // a 100 ms drop-tail queue
  o.controlDelayDuringFaults = 0.01;
  o.sender = sender;
  applyStreamTuning(StreamTuning{}, o.publisher, o.sender);
  auto rng = std::make_shared<std::mt19937>(11u);
  auto advance = [rng](Field& f, double t) { test::evolveWithRayNoise(f, *rng, float(t)); };
  LadderRun run;
  run.result = runStreamSimulation(server, advance, o);
  const StreamSimulationResult& r = run.result;
  run.shortPsnrP5 = test::percentile(r.heldPsnrs, 0.05);
  run.shortAgeP95 = test::percentile(r.heldAges, 0.95);
  // The last 2 s (8 samples) of the wide link.
  const std::size_t n = r.settleHeldPsnrs.size(), from = n > 8 ? n - 8 : 0;
  std::vector<double> psnrs(r.settleHeldPsnrs.begin() + std::ptrdiff_t(from),
                            r.settleHeldPsnrs.end());
  std::vector<double> ages(r.settleHeldAges.begin() + std::ptrdiff_t(from), r.settleHeldAges.end());
  run.widePsnrP5 = test::percentile(psnrs, 0.05);
  run.wideAgeP95 = test::percentile(ages, 0.95);
  for (std::size_t i = from; i < r.settleQualityLevels.size(); ++i)
    run.wideLevel = std::max(run.wideLevel, r.settleQualityLevels[i]);
  std::vector<double> levels(r.qualityLevels.begin(), r.qualityLevels.end());
  std::printf(
      "short link %.0f kB/s: held p5 %.1f dB, oldest change p95 %.2f s, level p50 %.0f, "
      "%.0f kB/s sent; wide again: held p5 %.1f dB, p95 %.2f s, level <= %d\n",
      shortRate / 1e3, run.shortPsnrP5, run.shortAgeP95, test::percentile(levels, 0.5),
      double(r.faultBytes) / shortSeconds / 1e3, run.widePsnrP5, run.wideAgeP95, run.wideLevel);
  return run;
}

// The field never stops changing, and what the sender holds back below its thresholds waits
// up to the age bound's lead: the oldest change the client lacks is always past half the age
// bound. A ladder that comes down only while changes are young never comes down then; it must
// come down because the rate has room.
// (Before: the level stayed at 4 over the whole wide phase, the held field at 32.1 dB p5.)
// The link also narrows while the sender has little to send (the field was held): the
// controller must cut its rate to what arrives, not 15% at a time from a rate far above the
// link (before: 422 kB/s sent into this 40 kB/s link, on average over its 4 s).
TEST(QualityLadder, ComesBackToFullQualityOnceTheLinkHasRoomWhileTheFieldMoves) {
  const double shortRate = 40e3, shortSeconds = 4.0;
  const LadderRun run = runLadder(shortRate, shortSeconds);
  EXPECT_GT(run.result.sender.coarseUpdates, 0u) << "the short link never raised the level";
  EXPECT_LT(double(run.result.faultBytes) / shortSeconds, 1.5 * shortRate);
  EXPECT_EQ(run.wideLevel, 0);
  EXPECT_LE(run.wideAgeP95, 1.0);
  EXPECT_GE(run.widePsnrP5, 38.0);
}

}  // namespace
