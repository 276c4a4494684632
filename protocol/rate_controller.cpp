#include "rate_controller.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace pc {

namespace {
// Sent datagrams remembered for matching reports: enough for seconds at any sane rate.
constexpr std::size_t kMaxSentRecords = 1u << 15;
constexpr double kSentRecordSeconds = 3.0;
// Loss is judged over at least this many datagrams: at 0.5 Mbit/s the window holds a dozen,
// and one loss among them is not 8% loss.
constexpr std::size_t kMinLossSamples = 20;
// The queue delay is the floor of at least this many datagrams' one-way delays.
constexpr std::size_t kMinDelaySamples = 3;
// Deliveries below this share of what was sent over the same time: the link, not the sender,
// set them.
constexpr double kShortDelivery = 0.8;
}  // namespace

double RateController::sentRate(double now) const {
  double bytes = 0;
  for (auto it = sent_.rbegin(); it != sent_.rend() && it->sentAt >= now - options_.measureWindow;
       ++it)
    bytes += it->bytes;
  return bytes / options_.measureWindow;
}

RateController::RateController(RateControlOptions options) : options_(options) {
  estimate_.rate = std::clamp(options_.startRate, options_.minRate, options_.maxRate);
}

void RateController::setMaxRate(double maxRate) {
  options_.maxRate = std::max(maxRate, options_.minRate);
  estimate_.rate = std::min(estimate_.rate, options_.maxRate);
}

void RateController::onSent(std::uint32_t sequence, std::size_t bytes, double now) {
  if (!sent_.empty() && sequence != sent_.back().sequence + 1) sent_.clear();  // a new stream
  if (sent_.empty()) nextUnsettled_ = sequence;
  sent_.push_back(Sent{sequence, std::uint32_t(bytes), now, -1.0, false});
  while (!sent_.empty() && (sent_.size() > kMaxSentRecords ||
                            (sent_.front().settled && now - sent_.front().sentAt > 1.0) ||
                            now - sent_.front().sentAt > kSentRecordSeconds))
    sent_.pop_front();
}

double RateController::unwrap(std::uint32_t micros) {
  if (!clockKnown_) {
    clockKnown_ = true;
    receiverClock_ = 0;
  } else {
    // Reports come in order of arrival, so the difference is small and of either sign only
    // by the receiver's own batching: a signed 32-bit difference unwraps it.
    receiverClock_ += double(std::int32_t(micros - lastMicros_)) * 1e-6;
  }
  lastMicros_ = micros;
  return receiverClock_;
}

void RateController::onArrivals(std::span<const Arrival> arrivals, double now) {
  if (arrivals.empty()) return;
  estimate_.haveReports = true;
  for (const Arrival& a : arrivals) {
    const double at = unwrap(a.arrivalMicros);
    if (sent_.empty()) continue;
    const std::uint32_t index = a.sequence - sent_.front().sequence;
    if (index >= sent_.size()) continue;  // older than the records, or never sent
    Sent& s = sent_[index];
    if (s.arrivedAt >= 0) continue;  // a duplicate
    s.arrivedAt = at;
    if (!s.settled) {
      s.settled = true;
      outcomes_.push_back(Outcome{at, s.bytes, false});
    }
    // One-way delay with the clocks' unknown offset in it; only its differences are used.
    const double delay = at - s.sentAt;
    recentDelays_.emplace_back(at, delay);
    const double bin = std::floor(now);
    if (baseMinima_.empty() || baseMinima_.back().first != bin)
      baseMinima_.emplace_back(bin, delay);
    else
      baseMinima_.back().second = std::min(baseMinima_.back().second, delay);
    if (!haveNewest_ || std::int32_t(a.sequence - newestSequence_) > 0) {
      newestSequence_ = a.sequence;
      haveNewest_ = true;
    }
    newestArrival_ = std::max(newestArrival_, at);
  }
  while (!baseMinima_.empty() && baseMinima_.front().first < now - options_.baseDelayWindow)
    baseMinima_.pop_front();
  // The window keeps its newest kMinDelaySamples whatever their age: at a low rate (64 kbit/s
  // is 6 datagrams a second) the queueDelayWindow holds fewer, and a queue delay left at its
  // last value would keep a drained queue counted as over-use, and the rate at its floor, for
  // good.
  while (recentDelays_.size() > kMinDelaySamples &&
         recentDelays_.front().first < newestArrival_ - options_.queueDelayWindow)
    recentDelays_.pop_front();
  // A floor needs a few samples: under heavy loss a window may hold one delayed datagram.
  if (recentDelays_.size() >= kMinDelaySamples && !baseMinima_.empty()) {
    double base = std::numeric_limits<double>::infinity();
    for (const auto& m : baseMinima_) base = std::min(base, m.second);
    estimate_.baseDelay = base;
    // The smallest delay over the last queueDelayWindow is the queue's floor then: jitter and
    // reordering only ever add to a datagram's delay, a standing queue adds to every one.
    double floor = std::numeric_limits<double>::infinity();
    for (const auto& d : recentDelays_) floor = std::min(floor, d.second);
    estimate_.queueDelay = std::max(0.0, floor - base);
  }
  settle();
  decide(now);
}

void RateController::settle() {
  if (!haveNewest_) return;
  // Datagrams sent before the newest one that arrived, by more than the reordering tolerance,
  // and not reported: lost.
  // Records before nextUnsettled_ are all settled: each report looks at the new ones only.
  std::uint32_t i = sent_.empty() ? 0 : nextUnsettled_ - sent_.front().sequence;
  if (!sent_.empty() && i > sent_.size()) i = 0;  // the records were dropped past it
  for (; i < sent_.size(); ++i) {
    Sent& s = sent_[i];
    if (std::int32_t(newestSequence_ - s.sequence) < std::int32_t(options_.reorderTolerance)) break;
    if (!s.settled) {
      s.settled = true;
      outcomes_.push_back(Outcome{newestArrival_, s.bytes, true});
    }
  }
  if (!sent_.empty()) nextUnsettled_ = sent_.front().sequence + i;
  while (!outcomes_.empty() && outcomes_.size() > kMinLossSamples &&
         outcomes_.front().at < newestArrival_ - options_.measureWindow)
    outcomes_.pop_front();
  std::size_t lost = 0, arrived = 0;
  double bytes = 0, first = std::numeric_limits<double>::infinity(), last = -first;
  std::uint32_t firstBytes = 0;
  for (const Outcome& o : outcomes_) {
    if (o.lost) {
      ++lost;
      continue;
    }
    ++arrived;
    bytes += o.bytes;
    if (o.at < first) {
      first = o.at;
      firstBytes = o.bytes;
    }
    last = std::max(last, o.at);
  }
  estimate_.loss = lost + arrived > 0 ? double(lost) / double(lost + arrived) : 0.0;
  // What arrived between the first and the last arrival of the window, over that time (the
  // first datagram's bytes arrived before the span begins).
  const double span = last - first;
  estimate_.delivered = arrived >= 4 && span >= 0.02 ? (bytes - firstBytes) / span : 0.0;
}

void RateController::decide(double now) {
  const double dt = lastDecision_ < 0 ? 0.0 : std::clamp(now - lastDecision_, 0.0, 0.1);
  lastDecision_ = now;
  estimate_.appLimited = appLimited_;
  const bool enoughForLoss = outcomes_.size() >= kMinLossSamples;
  const double loss = enoughForLoss ? estimate_.loss : 0.0;
  double& rate = estimate_.rate;
  const double congestive = loss;
  // Loss with a queue is congestion. Loss without one is taken as the path's own (radio): a
  // router whose queue is shorter than lossQueueDelay would go unseen, which is the price.
  const bool congestionLoss =
      congestive > options_.lossOveruse && estimate_.queueDelay > options_.lossQueueDelay;
  if (estimate_.queueDelay > options_.queueDelayTarget || congestionLoss) {
    if (now >= holdUntil_) {
      // What arrived is the link's rate while the sender had more to send: an
      // application-limited sender's deliveries say nothing of the link, and cutting to them
      // would leave a sender that sends little (a still field, coarse versions) at a rate far
      // below its link when its changes come back. Then the cut is from the rate, unless
      // what arrived fell short of what it sent: then a queue holds or drops the rest, and
      // what arrived is the link's rate however little the sender had to send. (Cut from a
      // rate far above its link, 15% at a time, a sender whose link narrowed kept sending
      // ten times what the link carried for seconds.)
      const double delivered = estimate_.delivered;
      const bool linkLimited = !appLimited_ || delivered < kShortDelivery * sentRate(now);
      const double arrived = delivered > 0 && linkLimited ? delivered : rate;
      lastOveruseRate_ = arrived;
      rate = std::min(rate, options_.decrease * arrived);
      ++estimate_.overuses;
      // Start-up ends where a queue built, not at loss alone (which may be the path's).
      if (estimate_.queueDelay > options_.queueDelayTarget) startupDone_ = true;
      // The queue drains at (1 - decrease) of the link's rate: the next decision waits for
      // that, or it would cut again for the queue this cut already dealt with.
      holdUntil_ = now + std::clamp(estimate_.queueDelay / (1.0 - options_.decrease),
                                    options_.holdSeconds, 1.0);
    }
  } else if ((congestive <= options_.lossTolerated ||
              estimate_.queueDelay <= options_.lossQueueDelay) &&
             estimate_.queueDelay <= 0.5 * options_.queueDelayTarget && now >= holdUntil_ &&
             !appLimited_) {
    // Loss without a queue does not stop the growth: the queue that more than the link
    // carries would build shows in the delay first.
    const bool near =
        lastOveruseRate_ > 0 && rate >= 0.8 * lastOveruseRate_ && rate <= 1.15 * lastOveruseRate_;
    const double doubling =
        startupDone_ ? options_.doublingSeconds : options_.startupDoublingSeconds;
    const double growth = std::log(2.0) / doubling * (near ? 0.25 : 1.0);
    rate = rate * std::exp(growth * dt) + options_.additiveIncrease * dt;
  }
  rate = std::clamp(rate, options_.minRate, options_.maxRate);
}

}  // namespace pc
