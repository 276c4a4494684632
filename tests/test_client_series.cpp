// probecast-client's per-second series (client/client_series.h): rows a second apart whose
// figures follow what the frames saw (bytes, the latency of announced versions, staleness,
// version lag, frame times), and the run's totals for the JSON summary. No renderer: the
// frames' stats are made up here.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "client/client_series.h"

namespace pc::client {
namespace {

TEST(ClientSeries, RowsFollowTheFramesAndTotalsSumThemUp) {
  const std::filesystem::path path = std::filesystem::path(PC_BUILD_DIR) / "test_client_series.csv";
  auto series = ClientSeries::create(path.string(), 0.0);
  ASSERT_TRUE(series.ok()) << series.error().message;
  // 3 s at 10 frames a second, 1250 bytes a frame (100 kbit/s). The server announces version
  // 5 at 0.5 s; the mirror holds it from 0.8 s (a latency of 300 ms), and is 5 versions behind
  // until then. The newest brick is 40 ms old at every frame.
  NetClientStats stats;
  stats.connected = true;
  stats.bricksTotal = 64;
  FieldAge age;
  age.present = true;
  age.newestSeconds = 0.04;
  for (int i = 1; i <= 30; ++i) {
    const double t = i / 10.0;
    stats.udpBytes += 1250;
    stats.serverFieldVersion = i >= 5 ? 5 : 0;
    age.version = i >= 8 ? 5 : 0;
    ASSERT_TRUE((*series)->frame(t, stats, age).ok());
  }
  auto table = readSeries(path);
  ASSERT_TRUE(table.ok()) << table.error().message;
  EXPECT_EQ(table->columns, kClientSeriesColumns);
  ASSERT_EQ(table->rows.size(), 3u);
  EXPECT_EQ(table->values("time_s"), (std::vector<double>{1, 2, 3}));
  EXPECT_EQ(table->values("bytes_received"), (std::vector<double>{12500, 25000, 37500}));
  for (double kbit : table->values("kbit_s")) EXPECT_NEAR(kbit, 100.0, 1e-6);
  EXPECT_NEAR(table->values("latency_p50_ms")[0], 300.0, 1e-3);
  EXPECT_TRUE(std::isnan(table->values("latency_p50_ms")[1]));  // nothing announced then
  EXPECT_EQ(table->values("version_lag_max"), (std::vector<double>{5, 0, 0}));
  for (double ms : table->values("staleness_max_ms")) EXPECT_NEAR(ms, 40.0, 1e-6);
  for (double ms : table->values("frame_ms_mean")) EXPECT_NEAR(ms, 100.0, 1e-6);
  for (double fps : table->values("fps")) EXPECT_NEAR(fps, 10.0, 1e-6);

  const ClientSeriesTotals totals = (*series)->totals();
  EXPECT_EQ(totals.latencySamples, 1u);
  EXPECT_NEAR(totals.latencyP95Ms, 300.0, 1e-3);
  EXPECT_EQ(totals.versionLagMax, 5.0);
  EXPECT_NEAR(totals.versionLagMean, 5.0 * 3 / 30, 1e-9);  // frames 5, 6 and 7 of 30
  EXPECT_NEAR(totals.frameMsP95, 100.0, 1e-3);
}

TEST(ClientSeries, WithoutAFileOnlyTotalsAreKept) {
  auto series = ClientSeries::create("", 0.0);
  ASSERT_TRUE(series.ok());
  NetClientStats stats;
  FieldAge age;
  for (int i = 1; i <= 20; ++i) ASSERT_TRUE((*series)->frame(i * 0.2, stats, age).ok());
  EXPECT_NEAR((*series)->totals().frameMsMean, 200.0, 1e-6);
  EXPECT_EQ((*series)->totals().latencySamples, 0u);
}

TEST(ClientSeries, AnUnwritablePathIsAnError) {
  auto series = ClientSeries::create("/nonexistent-folder/series.csv", 0.0);
  ASSERT_FALSE(series.ok());
  EXPECT_NE(series.error().message.find("/nonexistent-folder/series.csv"), std::string::npos);
}

}  // namespace
}  // namespace pc::client
