#include "client_series.h"

#include <algorithm>
#include <limits>

namespace pc::client {

namespace {

// The q-quantile (nearest rank) of `v` (reordered); NaN when empty.
double quantile(std::vector<float>& v, double q) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  const auto k = std::size_t(q * double(v.size() - 1) + 0.5);
  std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(k), v.end());
  return v[k];
}

}  // namespace

Result<std::unique_ptr<ClientSeries>> ClientSeries::create(const std::string& path, double start) {
  std::unique_ptr<ClientSeries> s(new ClientSeries(start));
  if (path.empty()) return s;
  auto writer = SeriesWriter::create(path, kClientSeriesColumns);
  if (!writer) return writer.error();
  s->writer_ = std::move(writer).value();
  return s;
}

Status ClientSeries::frame(double now, const NetClientStats& stats, const FieldAge& age,
                           std::span<const float> latencyMs) {
  ++frames_;
  const double frameMs = (now - lastFrame_) * 1e3;
  lastFrame_ = now;
  frameSum_ += frameMs;
  frameMax_ = std::max(frameMax_, frameMs);
  allFrameMs_.push_back(float(frameMs));
  latencyMs_.insert(latencyMs_.end(), latencyMs.begin(), latencyMs.end());
  allLatencyMs_.insert(allLatencyMs_.end(), latencyMs.begin(), latencyMs.end());
  if (stats.connected && age.present) {
    staleSum_ += age.newestSeconds;
    staleMax_ = std::max(staleMax_, age.newestSeconds);
    ++staleFrames_;
  }
  if (stats.connected && stats.heldFieldVersion > 0) {
    const double lag = stats.serverFieldVersion > stats.heldFieldVersion
                           ? double(stats.serverFieldVersion - stats.heldFieldVersion)
                           : 0.0;
    lagMax_ = std::max(lagMax_, lag);
    lagSum_ += lag;
    lagMaxAll_ = std::max(lagMaxAll_, lag);
    ++lagFrames_;
  }
  const double seconds = now - rowStart_;
  if (!writer_ || seconds < 1.0) return Status::success();
  const double none = std::numeric_limits<double>::quiet_NaN();
  const std::uint64_t bytes = stats.tcpBytes + stats.udpBytes;
  const std::vector<double> row = {
      now - start_,
      stats.connected ? 1.0 : 0.0,
      stats.synced ? 1.0 : 0.0,
      double(bytes),
      double(bytes - std::min(bytes, bytesBefore_)) * 8 / 1e3 / seconds,
      double(stats.bricksApplied - std::min(stats.bricksApplied, appliedBefore_)),
      double(stats.bricksHeld),
      double(stats.bricksTotal),
      quantile(latencyMs_, 0.5),
      quantile(latencyMs_, 0.95),
      staleFrames_ > 0 ? staleSum_ / staleFrames_ * 1e3 : none,
      staleFrames_ > 0 ? staleMax_ * 1e3 : none,
      lagMax_ >= 0 ? lagMax_ : none,
      frameSum_ / frames_,
      frameMax_,
      frames_ / seconds,
      double(stats.serverFieldVersion),
      double(stats.badDatagrams - std::min(stats.badDatagrams, badBefore_))};
  bytesBefore_ = bytes;
  appliedBefore_ = stats.bricksApplied;
  badBefore_ = stats.badDatagrams;
  rowStart_ = now;
  frames_ = staleFrames_ = 0;
  staleSum_ = staleMax_ = frameSum_ = frameMax_ = 0;
  lagMax_ = -1;
  latencyMs_.clear();
  return writer_->write(row);
}

ClientSeriesTotals ClientSeries::totals() const {
  ClientSeriesTotals t;
  std::vector<float> latency = allLatencyMs_, frames = allFrameMs_;
  t.latencySamples = latency.size();
  if (!latency.empty()) {
    t.latencyP50Ms = quantile(latency, 0.5);
    t.latencyP95Ms = quantile(latency, 0.95);
    t.latencyMaxMs = *std::max_element(latency.begin(), latency.end());
  }
  if (lagFrames_ > 0) {
    t.versionLagMean = lagSum_ / double(lagFrames_);
    t.versionLagMax = lagMaxAll_;
  }
  if (!frames.empty()) {
    double sum = 0;
    for (float f : frames) sum += f;
    t.frameMsMean = sum / double(frames.size());
    t.frameMsP95 = quantile(frames, 0.95);
    t.frameMsMax = *std::max_element(frames.begin(), frames.end());
  }
  return t;
}

}  // namespace pc::client
