#include "update_latency.h"

#include <algorithm>

namespace pc::client {

namespace {

constexpr std::size_t kMaxPublishTimes = 1024;  // 100 s at 10 updates a second
constexpr std::size_t kMaxPending = 4096;
constexpr std::size_t kMaxSamples = 1 << 20;  // a caller that never takes them
constexpr double kPendingSeconds = 5.0;       // a version's SceneState later than this: lost

}  // namespace

void UpdateLatency::startSession(std::uint64_t joinVersion) {
  joinVersion_ = joinVersion;
  offset_.reset();
  publishTimes_.clear();
  pending_.clear();
}

void UpdateLatency::published(std::uint64_t version, double publishTime, double now) {
  if (version == 0) return;  // a server that states no publish times
  const double offset = now - publishTime;
  if (!offset_ || offset < *offset_) offset_ = offset;
  if (publishTimes_.empty() || version > publishTimes_.back().first) {
    publishTimes_.emplace_back(version, publishTime);
    if (publishTimes_.size() > kMaxPublishTimes) publishTimes_.pop_front();
  }
  resolvePending(now);
}

void UpdateLatency::arrived(std::uint64_t version, double now) {
  if (version <= joinVersion_) return;
  if (auto at = publishedAt(version)) {
    if (samples_.size() < kMaxSamples) samples_.push_back(float(std::max(0.0, now - *at) * 1e3));
  } else if (pending_.size() < kMaxPending) {
    pending_.emplace_back(version, now);
  }
}

std::vector<float> UpdateLatency::take() { return std::exchange(samples_, {}); }

std::optional<double> UpdateLatency::publishedAt(std::uint64_t version) const {
  auto it = std::lower_bound(publishTimes_.begin(), publishTimes_.end(), version,
                             [](const auto& e, std::uint64_t v) { return e.first < v; });
  if (it == publishTimes_.end() || it->first != version || !offset_) return std::nullopt;
  return it->second + *offset_;
}

void UpdateLatency::resolvePending(double now) {
  std::erase_if(pending_, [&](const std::pair<std::uint64_t, double>& p) {
    if (auto at = publishedAt(p.first)) {
      if (samples_.size() < kMaxSamples)
        samples_.push_back(float(std::max(0.0, p.second - *at) * 1e3));
      return true;
    }
    return now - p.second > kPendingSeconds;
  });
}

}  // namespace pc::client
