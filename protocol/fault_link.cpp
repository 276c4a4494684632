#include "fault_link.h"

#include <algorithm>
#include <cmath>

namespace pc {

void FaultLink::enqueue(std::vector<std::uint8_t> bytes, double at) {
  if (queue_.size() >= profile_.queueLimit) {
    ++stats_.overflow;
    return;
  }
  queue_.push_back(InFlight{at, order_++, std::move(bytes)});
  stats_.maxInFlight = std::max(stats_.maxInFlight, queue_.size());
}

void FaultLink::send(std::vector<std::uint8_t> bytes, double now) {
  ++stats_.sent;
  if (burstLeft_ == 0 && profile_.burstStart > 0 && uniform() < profile_.burstStart) {
    // Geometric burst length with the configured mean.
    const double p = 1.0 / std::max(1.0, profile_.burstLength);
    burstLeft_ =
        1 + int(std::floor(std::log(std::max(uniform(), 1e-12)) / std::log(1.0 - p + 1e-12)));
  }
  if (burstLeft_ > 0) {
    --burstLeft_;
    ++stats_.lost;
    return;
  }
  if (uniform() < profile_.loss) {
    ++stats_.lost;
    return;
  }
  if (!bytes.empty() && uniform() < profile_.corrupt) {
    ++stats_.corrupted;
    if (uniform() < 0.25) {
      bytes.resize(std::size_t(uniform() * double(bytes.size())));
    } else {
      const int flips = 1 + int(uniform() * 3);
      for (int i = 0; i < flips; ++i) {
        const std::size_t at =
            std::min(bytes.size() - 1, std::size_t(uniform() * double(bytes.size())));
        bytes[at] ^= std::uint8_t(1u << int(uniform() * 8));
      }
    }
  }
  double sent = now;
  if (profile_.rate > 0) {
    // Drop-tail: what waits before this datagram, in bytes at the link's rate.
    const double start = std::max(linkFree_, now);
    if ((start - now) * profile_.rate + double(bytes.size()) > double(profile_.queueBytes)) {
      ++stats_.overflow;
      return;
    }
    linkFree_ = start + double(bytes.size()) / profile_.rate;
    sent = linkFree_;
  }
  double at = sent + profile_.delay + profile_.jitter * uniform();
  if (uniform() < profile_.reorder) {
    at += profile_.reorderDelay * uniform();
    ++stats_.reordered;
  }
  if (uniform() < profile_.duplicate) {
    ++stats_.duplicated;
    enqueue(bytes, at + profile_.jitter * uniform() + 0.001);
  }
  enqueue(std::move(bytes), at);
}

std::vector<std::vector<std::uint8_t>> FaultLink::receive(double now) {
  std::vector<InFlight> due;
  auto split =
      std::partition(queue_.begin(), queue_.end(), [&](const InFlight& f) { return f.at > now; });
  std::move(split, queue_.end(), std::back_inserter(due));
  queue_.erase(split, queue_.end());
  std::sort(due.begin(), due.end(), [](const InFlight& a, const InFlight& b) {
    return a.at < b.at || (a.at == b.at && a.order < b.order);
  });
  std::vector<std::vector<std::uint8_t>> out;
  for (InFlight& f : due) out.push_back(std::move(f.bytes));
  stats_.delivered += out.size();
  return out;
}

void ReliableLink::send(std::vector<std::uint8_t> bytes, double now) {
  // In order: never delivered before the message sent ahead of it.
  last_ = std::max(last_, now + delay_);
  queue_.emplace_back(last_, std::move(bytes));
}

std::vector<std::vector<std::uint8_t>> ReliableLink::receive(double now) {
  std::vector<std::vector<std::uint8_t>> out;
  while (!queue_.empty() && queue_.front().first <= now) {
    out.push_back(std::move(queue_.front().second));
    queue_.pop_front();
  }
  return out;
}

}  // namespace pc
