// The load generator against a real probecast-server process on loopback (the CI load test):
// 100 protocol-only clients for 10 s, none may starve or see an error; the latency percentiles
// are printed, never asserted. Also the publish time that SceneState carries for the latency,
// and the brick comparisons that the server's senders share.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>

#include "common/series_csv.h"
#include "loadgen/proc_stats.h"
#include "loadgen/server_load.h"
#include "loadgen/server_process.h"
#include "protocol/session_messages.h"
#include "protocol/stream_sender.h"
#include "test_protocol_support.h"

namespace pc {
namespace {

TEST(LoadgenProtocol, SceneStateCarriesFieldVersionAndPublishTime) {
  SceneStateMsg state;
  state.animationTime = 2.5;
  state.fieldVersion = 1234;
  state.publishTime = 98765.4321;
  auto decoded = decodeMessage(encodeMessage(state));
  ASSERT_TRUE(decoded.ok()) << decoded.error().message;
  const auto& back = std::get<SceneStateMsg>(*decoded);
  EXPECT_EQ(back.fieldVersion, 1234u);
  EXPECT_EQ(back.publishTime, 98765.4321);

  // A state from a server that states neither reads as "not stated".
  SceneStateMsg old;
  old.animationTime = 1.0;
  auto plain = decodeMessage(encodeMessage(old));
  ASSERT_TRUE(plain.ok());
  EXPECT_EQ(std::get<SceneStateMsg>(*plain).fieldVersion, 0u);

  state.publishTime = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(decodeMessage(encodeMessage(state)).ok());
}

// The senders of one server share one comparison per (brick, version, reference): the same
// answer as comparing directly, computed once however many clients ask.
TEST(LoadgenFanOut, SendersShareBrickComparisons) {
  Field f = test::makeSyntheticLayout();
  std::mt19937 rng(11);
  test::evolveField(f, rng, 1.0f, 0.0f);
  FieldPublisher publisher(f);
  ASSERT_TRUE(publisher.publish(f, 0.0).ok());
  const std::uint64_t v1 = f.brickVersions[0][0];
  test::evolveField(f, rng, 1.0f, 0.3f);
  ASSERT_TRUE(publisher.publish(f, 0.1).ok());
  const std::uint64_t v2 = f.brickVersions[0][0];
  ASSERT_NE(v1, v2);

  BrickChangeCache cache;
  const BrickChange direct = brickChange(*publisher.find(0, 0, v2), *publisher.find(0, 0, v1));
  for (int client = 0; client < 100; ++client) {
    auto c = cache.get(publisher, 0, 0, v2, v1);
    ASSERT_TRUE(c.has_value());
    EXPECT_EQ(c->irradiance, direct.irradiance);
    EXPECT_EQ(c->irradianceMean, direct.irradianceMean);
    EXPECT_EQ(c->depth, direct.depth);
    EXPECT_EQ(c->occlusion, direct.occlusion);
    EXPECT_EQ(c->offset, direct.offset);
    EXPECT_EQ(c->states, direct.states);
  }
  EXPECT_EQ(cache.computed(), 1u);
  EXPECT_EQ(cache.hits(), 99u);
  EXPECT_GT(direct.irradiance, 0.0f);
  // A version the publisher never had: no comparison (the sender treats the brick as new).
  EXPECT_FALSE(cache.get(publisher, 0, 0, v2, v2 + 1000).has_value());
}

TEST(LoadgenFanOut, ThreadCpuIsReadByName) {
  // This process's threads are in /proc/self/task; the main thread carries the executable's
  // name, and the per-thread times add up to at most the process's.
  auto s = load::readProcStats(getpid());
  ASSERT_TRUE(s.ok()) << s.error().message;
  EXPECT_FALSE(s->threadCpuSeconds.empty());
  double sum = 0;
  for (const auto& [name, seconds] : s->threadCpuSeconds) sum += seconds;
  EXPECT_LE(sum, s->cpuSeconds + 0.05);
  EXPECT_EQ(s->threadCpu("no-such-thread"), 0.0);
}

// A log that cannot be opened is named as such: the spawn reported it as its own error, which
// read as though the server's executable were missing.
TEST(LoadgenServerProcess, AnUnwritableLogIsNamedNotTheExecutable) {
  load::ServerProcessOptions sp;
  sp.executable = std::string(PC_BUILD_DIR) + "/bin/probecast-server";
  sp.logPath = std::string(PC_BUILD_DIR) + "/no-such-folder/server.log";
  auto server = load::ServerProcess::start(sp);
  ASSERT_FALSE(server.ok());
  EXPECT_NE(server.error().message.find("cannot open the server's log " + sp.logPath),
            std::string::npos)
      << server.error().message;
  EXPECT_EQ(server.error().message.find("cannot start"), std::string::npos)
      << server.error().message;
}

TEST(Loadgen, HundredClientsForTenSecondsAgainstRealServer) {
  load::ServerLoadOptions o;
  o.serverExecutable = std::string(PC_BUILD_DIR) + "/bin/probecast-server";
  o.serverLog = std::string(PC_BUILD_DIR) + "/test_loadgen_server.log";
  // Few rays: CI has two cores for the server and all the clients. 1 Mbit/s per client; the
  // built-in field is about 0.45 MB, so a client needs about 3.6 s of its link to hold every
  // brick, and 100 clients joining over 1 s hold every brick about 5 s after the first
  // connect (docs/BENCHMARKS.md, "Many clients": with one version of a brick in flight, an
  // unfinished self-contained brick is no longer restarted with each newer version). The
  // server's tracing threads run at nice 10, so that serving comes first on shared cores.
  o.serverArgs = {"--rays",       "32",     "--warmup",      "4",   "--rate",           "10",
                  "--rate-limit", "125000", "--max-clients", "150", "--stats-interval", "0"};
  o.load.clients = 100;
  o.load.rampSeconds = 1.0;
  // Starved here means what versions say (no datagram, or behind the newest version, for
  // 2 s). The held field's bounds (40 dB, changes under 1 s old) are not met at 1 Mbit/s with
  // the built-in field changing 10 times a second: its changes need more than 2 Mbit/s at
  // full precision (measured on two cores: p5 39.2 dB, p95 age 5.4 s at 1 Mbit/s; 39.6 dB
  // and 3.3 s at 2 Mbit/s); they are checked where the rate carries them (NetLinks tests).
  o.load.minHeldPsnr = 0;
  o.load.maxChangeAge = 1e9;
  o.idleSeconds = 1.0;
  o.warmupSeconds = 1.0;
  o.seconds = 10.0;
  o.joinLimit = 30.0;
  o.fieldNice = 10;
  const std::string seriesPath = std::string(PC_BUILD_DIR) + "/test_loadgen_series.csv";
  o.load.seriesPath = seriesPath;
  auto result =
      load::runServerLoad(o, [](const std::string& line) { std::printf("%s\n", line.c_str()); });
  ASSERT_TRUE(result.ok()) << result.error().message;
  const load::LoadReport& r = result->report;
  std::printf("%s", load::reportTable(r).c_str());
  std::printf(
      "joined in %.1f s; server CPU %.1f ms/s (idle %.1f), network thread %.1f ms/s = "
      "%.3f ms per client per s; loadgen %.1f ms/s; server RSS %.1f -> %.1f MB\n",
      result->joinSeconds, result->serverCpuMsPerS, result->serverIdleCpuMsPerS,
      result->netCpuMsPerS, result->cpuMsPerClientS, result->loadgenCpuMsPerS, result->rssWarmMb,
      result->rssEndMb);

  EXPECT_TRUE(result->allSynced) << "not every client held every brick within the join limit";
  EXPECT_EQ(r.errors, 0u);
  for (const std::string& e : r.errorSamples) ADD_FAILURE() << "error: " << e;
  EXPECT_EQ(r.starvedClients, 0);
  for (const load::ClientReport& c : r.perClient) {
    EXPECT_FALSE(c.starved) << "client " << c.index << ": " << c.starvedWhy;
    EXPECT_GT(c.datagrams, 0u) << "client " << c.index;
    EXPECT_GT(c.bytesUp, 0u) << "client " << c.index << " sent no acks or poses";
  }
  // The field moves (the built-in scene's light and box animate), so updates arrive, and each
  // one is matched with the publish time its SceneState carried.
  EXPECT_GT(r.latencyMs.count, 0u);
  EXPECT_TRUE(result->serverExit.empty()) << result->serverExit;

  // The series (--series): a row a second of the whole run, whose figures follow the run:
  // all clients in a session by the end, data received, latency measured in some second.
  auto series = readSeries(seriesPath);
  ASSERT_TRUE(series.ok()) << series.error().message;
  EXPECT_EQ(series->columns, load::kSeriesColumns);
  ASSERT_GE(series->rows.size(), std::size_t(o.seconds));
  const std::vector<double> time = series->values("time_s");
  for (std::size_t i = 0; i < time.size(); ++i) EXPECT_EQ(time[i], double(i + 1));
  const std::vector<double> clients = series->values("clients");
  EXPECT_EQ(clients.back(), 100.0);
  double kbitMax = 0, latencyRows = 0, errors = 0;
  for (std::size_t i = 0; i < series->rows.size(); ++i) {
    kbitMax = std::max(kbitMax, series->values("kbit_s_total")[i]);
    latencyRows += std::isnan(series->values("latency_p95_ms")[i]) ? 0 : 1;
    errors += series->values("errors")[i];
    const double gap = series->values("gap_max_ms")[i];
    EXPECT_TRUE(std::isnan(gap) || gap >= 0.0) << "row " << i;
  }
  EXPECT_GT(kbitMax, 0.0);
  EXPECT_GT(latencyRows, 0.0);
  EXPECT_EQ(errors, 0.0);
}

}  // namespace
}  // namespace pc
