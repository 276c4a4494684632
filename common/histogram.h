// A fixed-bucket histogram of observations (durations, in seconds), as Prometheus histograms
// count them: each bucket counts the observations at or below its upper bound, and the sum and
// count of all of them are kept beside. Plain data: the owner guards it, and copies it to
// whoever renders it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace pc {

class Histogram {
 public:
  Histogram() = default;
  // Upper bounds, increasing; an implicit +Inf bucket follows the last.
  explicit Histogram(std::vector<double> bounds)
      : bounds_(std::move(bounds)), counts_(bounds_.size() + 1, 0) {}

  void observe(double value) {
    if (counts_.empty()) counts_.assign(1, 0);
    std::size_t i = 0;
    while (i < bounds_.size() && value > bounds_[i]) ++i;
    ++counts_[i];
    sum_ += value;
    ++count_;
  }
  // Adds another histogram of the same bounds (per-session histograms into a total).
  void merge(const Histogram& other) {
    if (other.counts_.size() != counts_.size()) return;
    for (std::size_t i = 0; i < counts_.size(); ++i) counts_[i] += other.counts_[i];
    sum_ += other.sum_;
    count_ += other.count_;
  }

  const std::vector<double>& bounds() const { return bounds_; }
  // Observations at or below bounds()[i] (cumulative, as the exposition format writes them);
  // i == bounds().size() is the +Inf bucket, equal to count().
  std::uint64_t cumulative(std::size_t i) const {
    std::uint64_t n = 0;
    for (std::size_t k = 0; k <= i && k < counts_.size(); ++k) n += counts_[k];
    return n;
  }
  double sum() const { return sum_; }
  std::uint64_t count() const { return count_; }

 private:
  std::vector<double> bounds_;
  std::vector<std::uint64_t> counts_;  // per bucket, not cumulative; the last is +Inf
  double sum_ = 0;
  std::uint64_t count_ = 0;
};

// Bounds from `first` up, each `factor` times the one before, `n` of them (Prometheus'
// exponential buckets): 0.0001 x 2, 16 spans 0.1 ms to 3.3 s.
inline std::vector<double> exponentialBounds(double first, double factor, int n) {
  std::vector<double> b;
  for (int i = 0; i < n; ++i, first *= factor) b.push_back(first);
  return b;
}

}  // namespace pc
