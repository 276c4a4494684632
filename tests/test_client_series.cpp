// probecast-client's per-second series (client/client_series.h): rows a second apart whose
// figures follow what the frames saw (bytes, update latency, staleness, version lag, frame
// times), and the run's totals for the JSON summary; and the update latency it is given
// (client/update_latency.h): publish to arrival, with the server's clock taken onto the
// client's by the smallest offset seen. No renderer or socket: the inputs are made up here.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "client/client_series.h"
#include "client/update_latency.h"

namespace pc::client {
namespace {

TEST(ClientSeries, RowsFollowTheFramesAndTotalsSumThemUp) {
  const std::filesystem::path path = std::filesystem::path(PC_BUILD_DIR) / "test_client_series.csv";
  auto series = ClientSeries::create(path.string(), 0.0);
  ASSERT_TRUE(series.ok()) << series.error().message;
  // 3 s at 10 frames a second, 1250 bytes a frame (100 kbit/s). The server's version is 5
  // from 0.5 s; the client holds a brick of it from 0.8 s, of version 4 before: 1 version
  // behind for frames 5, 6 and 7. One latency of 300 ms is measured in the first second, two
  // (10 and 30 ms) in the third. The newest brick is 40 ms old at every frame.
  NetClientStats stats;
  stats.connected = true;
  stats.bricksTotal = 64;
  FieldAge age;
  age.present = true;
  age.newestSeconds = 0.04;
  for (int i = 1; i <= 30; ++i) {
    const double t = i / 10.0;
    stats.udpBytes += 1250;
    stats.serverFieldVersion = i >= 5 ? 5 : 4;
    stats.heldFieldVersion = i >= 8 ? 5 : 4;
    std::vector<float> latency;
    if (i == 8) latency = {300.0f};
    if (i == 25) latency = {10.0f, 30.0f};
    ASSERT_TRUE((*series)->frame(t, stats, age, latency).ok());
  }
  auto table = readSeries(path);
  ASSERT_TRUE(table.ok()) << table.error().message;
  EXPECT_EQ(table->columns, kClientSeriesColumns);
  ASSERT_EQ(table->rows.size(), 3u);
  EXPECT_EQ(table->values("time_s"), (std::vector<double>{1, 2, 3}));
  EXPECT_EQ(table->values("bytes_received"), (std::vector<double>{12500, 25000, 37500}));
  for (double kbit : table->values("kbit_s")) EXPECT_NEAR(kbit, 100.0, 1e-6);
  EXPECT_NEAR(table->values("latency_p50_ms")[0], 300.0, 1e-3);
  EXPECT_TRUE(std::isnan(table->values("latency_p50_ms")[1]));  // nothing measured then
  EXPECT_NEAR(table->values("latency_p95_ms")[2], 30.0, 1e-3);
  EXPECT_EQ(table->values("version_lag_max"), (std::vector<double>{1, 0, 0}));
  for (double ms : table->values("staleness_max_ms")) EXPECT_NEAR(ms, 40.0, 1e-6);
  for (double ms : table->values("frame_ms_mean")) EXPECT_NEAR(ms, 100.0, 1e-6);
  for (double fps : table->values("fps")) EXPECT_NEAR(fps, 10.0, 1e-6);

  const ClientSeriesTotals totals = (*series)->totals();
  EXPECT_EQ(totals.latencySamples, 3u);
  EXPECT_NEAR(totals.latencyP50Ms, 30.0, 1e-3);
  EXPECT_NEAR(totals.latencyMaxMs, 300.0, 1e-3);
  EXPECT_EQ(totals.versionLagMax, 1.0);
  EXPECT_NEAR(totals.versionLagMean, 3.0 / 30, 1e-9);  // frames 5, 6 and 7 of 30
  EXPECT_NEAR(totals.frameMsP95, 100.0, 1e-3);
}

TEST(ClientSeries, WithoutAFileOnlyTotalsAreKept) {
  auto series = ClientSeries::create("", 0.0);
  ASSERT_TRUE(series.ok());
  NetClientStats stats;
  FieldAge age;
  for (int i = 1; i <= 20; ++i) ASSERT_TRUE((*series)->frame(i * 0.2, stats, age, {}).ok());
  EXPECT_NEAR((*series)->totals().frameMsMean, 200.0, 1e-6);
  EXPECT_EQ((*series)->totals().latencySamples, 0u);
}

TEST(ClientSeries, AnUnwritablePathIsAnError) {
  auto series = ClientSeries::create("/nonexistent-folder/series.csv", 0.0);
  ASSERT_FALSE(series.ok());
  EXPECT_NE(series.error().message.find("/nonexistent-folder/series.csv"), std::string::npos);
}

TEST(UpdateLatency, PublishToArrivalOnTheFastestSceneStatesClock) {
  // The server's clock runs 1000 s behind this one. Scene states take 2 ms (version 11) and
  // 5 ms (version 12) to arrive: the offset is 1000.002 s, and latencies count from there.
  UpdateLatency latency;
  latency.startSession(10);
  latency.published(11, 1.000, 1001.002);
  latency.arrived(11, 1001.052);  // 50 ms after version 11's publish (+ the 2 ms)
  latency.arrived(10, 1001.060);  // the initial sync's version: not an update
  // A brick of 12 that overtook its scene state waits for it.
  latency.arrived(12, 1001.120);
  const std::vector<float> first = latency.take();
  ASSERT_EQ(first.size(), 1u);
  EXPECT_NEAR(first[0], 50.0, 1e-3);
  latency.published(12, 1.100, 1001.105);
  const std::vector<float> later = latency.take();
  ASSERT_EQ(later.size(), 1u);
  EXPECT_NEAR(later[0], 18.0, 1e-3);  // 1001.120 - (1.100 + 1000.002)
  EXPECT_TRUE(latency.take().empty());
  // A new session forgets the old one's versions and clock.
  latency.startSession(50);
  latency.arrived(12, 1002.0);
  latency.published(12, 1.100, 1001.105);
  EXPECT_TRUE(latency.take().empty());
}

TEST(UpdateLatency, ABrickWhoseSceneStateNeverComesIsDropped) {
  UpdateLatency latency;
  latency.startSession(0);
  latency.arrived(7, 10.0);
  latency.published(6, 0.0, 20.0);  // 10 s later: version 7's state did not come in time
  latency.published(7, 0.0, 20.1);  // so its brick is no longer waiting for it
  EXPECT_TRUE(latency.take().empty());
  latency.arrived(8, 20.2);
  latency.published(8, 0.1, 20.2);
  EXPECT_EQ(latency.take().size(), 1u);
}

}  // namespace
}  // namespace pc::client
