// probecast-client's per-second series (--series, or beside --summary): one CSV row (common/
// series_csv.h) about every second of a network run, for probecast-report and for watching a
// client over time rather than only its summary at the end; and the run's totals of the same
// figures for the JSON summary.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "common/series_csv.h"
#include "field_mirror.h"
#include "net_client.h"

namespace pc::client {

// time_s: seconds since the run began; connected, synced: 0 or 1 at the row's end;
// bytes_received: TCP and UDP since the run began; kbit_s: received over the row's interval;
// bricks_applied: in the interval; bricks_held, bricks_total: this session's;
// latency_p50_ms, latency_p95_ms: from the server publishing a field version to its bricks
// arriving (update_latency.h); staleness_mean_ms, staleness_max_ms: the age of the newest
// brick the mirror holds; version_lag_max: the server's newest field version less the newest
// one the client holds a brick of, the most in the interval (for a field that changes every
// update: how many updates the client is behind); frame_ms_mean,
// frame_ms_max: time between frames; fps; server_field_version; bad_datagrams: in the
// interval. Figures without samples in the interval (no frame while connected) are empty.
inline const std::vector<std::string> kClientSeriesColumns = {"time_s",
                                                              "connected",
                                                              "synced",
                                                              "bytes_received",
                                                              "kbit_s",
                                                              "bricks_applied",
                                                              "bricks_held",
                                                              "bricks_total",
                                                              "latency_p50_ms",
                                                              "latency_p95_ms",
                                                              "staleness_mean_ms",
                                                              "staleness_max_ms",
                                                              "version_lag_max",
                                                              "frame_ms_mean",
                                                              "frame_ms_max",
                                                              "fps",
                                                              "server_field_version",
                                                              "bad_datagrams"};

// The whole run's figures (for the JSON summary); zeros without samples.
struct ClientSeriesTotals {
  std::uint64_t latencySamples = 0;
  double latencyP50Ms = 0, latencyP95Ms = 0, latencyMaxMs = 0;
  double versionLagMean = 0, versionLagMax = 0;
  double frameMsMean = 0, frameMsP95 = 0, frameMsMax = 0;
};

class ClientSeries {
 public:
  // `path` empty: no file, only the totals.
  static Result<std::unique_ptr<ClientSeries>> create(const std::string& path, double start);
  // One frame: its stats, the mirror's age and the update latencies (ms) measured since the
  // previous frame (NetClient::takeLatencySamples). A row is written once a second has
  // passed since the last (a frame slower than a second gives one row per frame).
  Status frame(double now, const NetClientStats& stats, const FieldAge& age,
               std::span<const float> latencyMs);
  ClientSeriesTotals totals() const;

 private:
  explicit ClientSeries(double start) : start_(start), rowStart_(start), lastFrame_(start) {}
  std::unique_ptr<SeriesWriter> writer_;
  double start_, rowStart_, lastFrame_;
  // The row's samples, and the run's.
  std::uint64_t bytesBefore_ = 0, appliedBefore_ = 0, badBefore_ = 0;
  int frames_ = 0, staleFrames_ = 0;
  double staleSum_ = 0, staleMax_ = 0, lagMax_ = -1, frameSum_ = 0, frameMax_ = 0;
  std::vector<float> latencyMs_, allLatencyMs_, allFrameMs_;
  double lagSum_ = 0, lagMaxAll_ = 0;
  std::uint64_t lagFrames_ = 0;
};

}  // namespace pc::client
