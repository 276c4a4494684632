// Congestion control (protocol/rate_controller.h) over in-memory bottlenecks: greedy senders
// pace datagrams at their controller's rate into a FaultLink with a rate and a drop-tail queue,
// and a receiver reports every arrival every 20 ms, as StreamReceiver's acks do. What a real
// link does is measured by tests/net/links.sh over tbf (CTest net_links); these pin the
// controller's behaviour.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <memory>
#include <numeric>
#include <span>
#include <vector>

#include "protocol/fault_link.h"
#include "protocol/rate_controller.h"

namespace {

using namespace pc;

constexpr double kStep = 0.005;        // s between sender polls
constexpr double kReportEvery = 0.02;  // s between arrival reports
constexpr std::size_t kDatagram = 1200;

// One greedy stream: always has a datagram to send.
struct Stream {
  RateController rc;
  double tokens = 0;
  std::uint32_t sequence = 0;
  std::vector<RateController::Arrival> pending;  // arrivals not yet reported
  double lastReport = 0;
  double startAt = 0;  // joins the link then
  explicit Stream(RateControlOptions o = {}) : rc(o) {}
};

// Encodes the stream index and sequence in the datagram's first bytes.
std::vector<std::uint8_t> datagram(std::size_t stream, std::uint32_t sequence) {
  std::vector<std::uint8_t> d(kDatagram, 0);
  d[0] = std::uint8_t(stream);
  for (int i = 0; i < 4; ++i) d[1 + i] = std::uint8_t(sequence >> (8 * i));
  return d;
}

struct LinkRun {
  std::vector<double> rateAt;  // per stream, the controller's rate at the end
  std::vector<double> arrivedRate;
  double dropShare = 0;
};

// `linkRate(t)` in bytes/s; the streams share one link; returns per-stream figures over the
// last `measure` seconds of `seconds`.
LinkRun run(
    std::vector<std::unique_ptr<Stream>>& streams, FaultLink& link,
    const std::function<double(double)>& linkRate, double seconds, double measure,
    const std::function<void(double, const std::vector<std::unique_ptr<Stream>>&)>& each = {}) {
  std::vector<std::uint64_t> arrivedInWindow(streams.size(), 0);
  std::uint64_t sentInWindow = 0, droppedBefore = 0;
  FaultProfile p = link.profile();
  for (long i = 0;; ++i) {
    const double t = double(i) * kStep;
    if (t > seconds) break;
    if (p.rate != linkRate(t)) {
      p.rate = linkRate(t);
      link.setProfile(p);
    }
    const bool inWindow = t >= seconds - measure;
    if (inWindow && droppedBefore == 0) droppedBefore = link.stats().overflow + 1;
    for (std::size_t s = 0; s < streams.size(); ++s) {
      Stream& st = *streams[s];
      if (t < st.startAt) continue;
      const double burst = std::max(3.0 * kDatagram, st.rc.rate() * 0.01);
      st.tokens = std::min(burst, st.tokens + st.rc.rate() * kStep);
      while (st.tokens > 0) {
        st.rc.onSent(st.sequence, kDatagram, t);
        link.send(datagram(s, st.sequence++), t);
        st.tokens -= double(kDatagram);
        if (inWindow) ++sentInWindow;
      }
    }
    for (auto& d : link.receive(t)) {
      const std::size_t s = d[0];
      std::uint32_t seq = 0;
      for (int k = 0; k < 4; ++k) seq |= std::uint32_t(d[1 + k]) << (8 * k);
      // The receiver's clock runs 1000 s ahead of the sender's: only differences count.
      streams[s]->pending.push_back({seq, std::uint32_t(std::llround((t + 1000.0) * 1e6))});
      if (inWindow) ++arrivedInWindow[s];
    }
    for (auto& sp : streams) {
      Stream& st = *sp;
      if (t - st.lastReport >= kReportEvery && !st.pending.empty()) {
        st.rc.setAppLimited(false);
        st.rc.onArrivals(st.pending, t + 0.01);  // the report's own trip back
        st.pending.clear();
        st.lastReport = t;
      }
    }
    if (each) each(t, streams);
  }
  LinkRun r;
  for (std::size_t s = 0; s < streams.size(); ++s) {
    r.rateAt.push_back(streams[s]->rc.rate());
    r.arrivedRate.push_back(double(arrivedInWindow[s]) * kDatagram / measure);
  }
  const std::uint64_t dropped = link.stats().overflow - (droppedBefore - 1);
  r.dropShare = sentInWindow > 0 ? double(dropped) / double(sentInWindow) : 0.0;
  return r;
}

FaultLink bottleneck(double bytesPerSecond, double queueSeconds) {
  FaultLink link(7);
  FaultProfile p;
  p.delay = 0.02;
  p.rate = bytesPerSecond;
  p.queueBytes = std::size_t(bytesPerSecond * queueSeconds);
  p.queueLimit = 1u << 20;
  link.setProfile(p);
  return link;
}

double jain(const std::vector<double>& x) {
  const double sum = std::accumulate(x.begin(), x.end(), 0.0);
  double squares = 0;
  for (double v : x) squares += v * v;
  return sum * sum / (double(x.size()) * squares);
}

TEST(RateControl, FindsTheRateOfALinkAndKeepsItsQueueShort) {
  for (double mbit : {0.5, 2.0, 10.0}) {
    const double capacity = mbit * 1e6 / 8;
    FaultLink link = bottleneck(capacity, 0.1);
    std::vector<std::unique_ptr<Stream>> streams;
    streams.push_back(std::make_unique<Stream>());
    LinkRun r = run(
        streams, link, [&](double) { return capacity; }, 8.0, 4.0);
    std::printf("%.1f Mbit/s: arrived %.3f Mbit/s, rate %.3f, drops %.2f%%\n", mbit,
                r.arrivedRate[0] * 8 / 1e6, r.rateAt[0] * 8 / 1e6, 100 * r.dropShare);
    EXPECT_GT(r.arrivedRate[0], 0.7 * capacity) << mbit;  // uses the link
    EXPECT_LT(r.dropShare, 0.05) << mbit;                 // without filling its queue
    EXPECT_LT(r.rateAt[0], 1.3 * capacity) << mbit;
  }
}

TEST(RateControl, FollowsALinkWhoseRateChanges) {
  // 2 -> 0.5 -> 2 Mbit/s: within 2 s of each change the rate is within 30% of the link's.
  const double high = 2e6 / 8, low = 0.5e6 / 8;
  FaultLink link = bottleneck(high, 0.1);
  auto linkRate = [&](double t) { return t >= 6.0 && t < 12.0 ? low : high; };
  std::vector<std::unique_ptr<Stream>> streams;
  streams.push_back(std::make_unique<Stream>());
  std::vector<std::pair<double, double>> samples;  // (time, rate)
  run(streams, link, linkRate, 18.0, 1.0,
      [&](double t, const auto& s) { samples.emplace_back(t, s[0]->rc.rate()); });
  for (double change : {6.0, 12.0}) {
    double settled = -1;
    for (const auto& [t, rate] : samples) {
      if (t < change) continue;
      const double target = linkRate(t);
      const bool within = std::abs(rate - target) <= 0.3 * target;
      if (within && settled < 0) settled = t;
      if (!within && t < change + 2.0) settled = -1;
      if (t >= change + 3.0) break;
    }
    std::printf("link change at %.0f s: rate within 30%% from %.2f s on\n", change, settled);
    ASSERT_GE(settled, 0.0) << "change at " << change;
    EXPECT_LE(settled - change, 2.0) << "change at " << change;
  }
}

TEST(RateControl, StreamsSharingALinkShareItFairlyWithFewDrops) {
  // Three streams behind one 2 Mbit/s link, joining one second apart.
  const double capacity = 2e6 / 8;
  FaultLink link = bottleneck(capacity, 0.1);
  std::vector<std::unique_ptr<Stream>> streams;
  for (int i = 0; i < 3; ++i) {
    streams.push_back(std::make_unique<Stream>());
    streams.back()->startAt = double(i);
  }
  LinkRun r = run(
      streams, link, [&](double) { return capacity; }, 30.0, 10.0);
  const double total = std::accumulate(r.arrivedRate.begin(), r.arrivedRate.end(), 0.0);
  std::printf("shared 2 Mbit/s: %.3f %.3f %.3f Mbit/s, Jain %.3f, drops %.2f%%\n",
              r.arrivedRate[0] * 8 / 1e6, r.arrivedRate[1] * 8 / 1e6, r.arrivedRate[2] * 8 / 1e6,
              jain(r.arrivedRate), 100 * r.dropShare);
  EXPECT_GT(total, 0.7 * capacity);
  EXPECT_GT(jain(r.arrivedRate), 0.9);
  EXPECT_LT(r.dropShare, 0.05);
}

TEST(RateControl, RandomLossWithoutAQueueIsNotCongestion) {
  // 10% loss on a 10 Mbit/s link whose queue never fills: the rate must not collapse.
  const double capacity = 10e6 / 8;
  FaultLink link = bottleneck(capacity, 0.1);
  FaultProfile p = link.profile();
  p.loss = 0.1;
  link.setProfile(p);
  std::vector<std::unique_ptr<Stream>> streams;
  RateControlOptions o;
  o.maxRate = 0.5 * capacity;  // a ceiling under the link: no queue ever builds
  streams.push_back(std::make_unique<Stream>(o));
  LinkRun r = run(
      streams, link, [&](double) { return capacity; }, 6.0, 3.0);
  std::printf("10%% random loss: rate %.3f Mbit/s of a %.3f ceiling\n", r.rateAt[0] * 8 / 1e6,
              o.maxRate * 8 / 1e6);
  EXPECT_GT(r.rateAt[0], 0.8 * o.maxRate);
}

}  // namespace

// At the floor rate a stream sends a few datagrams a second, fewer than the queue-delay window
// (100 ms) holds at any time. A queue seen while it sent faster must still be seen to drain:
// the rate recovers once its datagrams arrive at the base delay again, instead of the old
// queue delay holding it at its floor for good.
TEST(RateControl, ASlowStreamSeesItsQueueDrain) {
  RateController rc;
  std::uint32_t sequence = 0;
  double t = 0;
  const auto send = [&](double oneWayDelay, double interval) {
    rc.onSent(sequence, kDatagram, t);
    const RateController::Arrival a{sequence, std::uint32_t((t + oneWayDelay) * 1e6)};
    rc.onArrivals(std::span(&a, 1), t + oneWayDelay);
    ++sequence;
    t += interval;
  };
  for (int i = 0; i < 20; ++i) send(0.010, 0.01);  // the base delay
  for (int i = 0; i < 30; ++i) send(0.060, 0.01);  // a queue of 50 ms: cut after cut
  EXPECT_GT(rc.estimate().queueDelay, 0.04);
  // Now 6 to 7 datagrams a second (the floor rate's pace): the queue stays a while, then
  // drains.
  for (int i = 0; i < 3; ++i) send(0.060, 0.15);
  for (int i = 0; i < 40; ++i) send(0.010, 0.15);
  EXPECT_LT(rc.estimate().queueDelay, 0.001);
  EXPECT_GT(rc.rate(), 4.0 * RateControlOptions{}.minRate) << "the rate stayed near its floor";
}
