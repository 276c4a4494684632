// Congestion control of one client's stream, on the sender's side and without clocks or
// sockets: told what was sent (sequence, bytes, time) and fed the receiver's reports of when
// each datagram arrived (Ack arrivals, in the receiver's clock), it says how fast to send.
//
// The ideas it takes, and from where:
// - From LEDBAT (RFC 6817): the one-way delay of each datagram, less the smallest seen over
//   the last baseDelayWindow seconds, is the queueing delay the stream causes; the clocks of
//   the two ends need not agree, since only differences of one-way delays are used. A target
//   for it (queueDelayTarget) keeps router queues short, which is what keeps a headset's
//   latency low on a shared access point; LEDBAT's 100 ms is too long for interactive use.
// - From Google Congestion Control (draft-ietf-rmcat-gcc): the decisions are taken on the
//   receive side's measurements: over-use (queueing delay over the target, or loss over
//   lossOveruse with a queue) cuts the rate to `decrease` x the rate the receiver saw arriving, so
//   the queue the over-use built drains; loss between lossTolerated and lossOveruse holds the rate;
//   and while the rate is far from the last point of over-use it grows multiplicatively, near it
//   slowly.
// - From BBR: the rate is a pacing rate (the sender spends tokens at it), and only a sender
//   that used its rate learns from growing it: while the application had less to send than
//   the rate allowed (app-limited), the rate does not grow, so a quiet stream does not earn a
//   rate it never tested and then burst into a queue; nor is it cut to what arrived then (a
//   quiet stream's deliveries are not the link's rate), only by `decrease` from the rate.
// Sharing one bottleneck: every stream on it sees the same queueing delay, so over-use is
// detected by all at once and each cuts by the same factor; the additive part of the growth
// (additiveIncrease, the same for every stream) then moves the shares towards equal
// (Chiu and Jain's argument for additive increase, multiplicative decrease).
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <span>

namespace pc {

struct RateControlOptions {
  // bytes/s (4 Mbit/s) before any report, growing as startupDoublingSeconds says until the
  // first over-use: a client must hold the whole field within a second of joining, and a
  // slower start would take that long to find even a few Mbit/s.
  double startRate = 125e3;
  double startupDoublingSeconds = 0.1;
  double minRate = 8e3;            // bytes/s (64 kbit/s): never less, whatever the reports say
  double maxRate = 1e12;           // bytes/s: the ceiling (the server's --rate-limit)
  double queueDelayTarget = 0.03;  // s of queueing over the base delay counted as over-use
  // Loss share over which the rate is cut (GCC), when the queueing delay shows a queue
  // (lossQueueDelay): a drop-tail router drops only from a full queue, while loss on a radio
  // link without a queue is not congestion, and cutting for it would starve the stream (BBR
  // leaves such loss alone too).
  double lossOveruse = 0.1;
  double lossQueueDelay = 0.004;
  double lossTolerated = 0.02;    // loss share under which the rate may grow (GCC)
  double decrease = 0.85;         // over-use: rate = this x the rate that arrived (GCC)
  double baseDelayWindow = 10.0;  // s: base delay is the least one-way delay over this
  double queueDelayWindow = 0.1;  // s: queueing delay is the least one-way delay over this,
                                  // less the base delay
  double measureWindow = 0.3;     // s of arrivals the arrival rate and loss are measured over
  // Growth: far from the last over-use (below 0.8x or above 1.15x its rate, or none yet) the
  // rate doubles every doublingSeconds; near it, a quarter as fast, so the stream returns to the
  // point where the queue built quickly and then probes past it with care.
  double doublingSeconds = 0.4;
  double additiveIncrease = 25e3;  // bytes/s per second, added in every growth
  // After a cut, no new cut and no growth for at least this, and for as long as the queue seen
  // takes to drain at the cut rate (at most 1 s): the measurements must describe the new rate.
  double holdSeconds = 0.15;
  double reorderTolerance = 3;  // datagrams: one arriving this far behind is counted lost
};

struct RateEstimate {
  double rate = 0;             // bytes/s to send at
  double delivered = 0;        // bytes/s that arrived over the measurement window (0: unknown)
  double queueDelay = 0;       // s
  double baseDelay = 0;        // s, least one-way delay (with the clocks' offset in it)
  double loss = 0;             // share of datagrams lost over the window
  std::uint64_t overuses = 0;  // cuts so far
  bool appLimited = false;
  bool haveReports = false;  // any arrival report seen
};

class RateController {
 public:
  explicit RateController(RateControlOptions options = {});

  // A datagram left: `sequence` (consecutive per stream), its bytes and the sender's time.
  void onSent(std::uint32_t sequence, std::size_t bytes, double now);
  // The sender had less to send than the rate allowed since the last report (see above).
  void setAppLimited(bool limited) { appLimited_ = limited; }
  // Datagrams that arrived: (sequence, receiver time in microseconds, wrapping at 2^32).
  struct Arrival {
    std::uint32_t sequence;
    std::uint32_t arrivalMicros;
  };
  void onArrivals(std::span<const Arrival> arrivals, double now);

  double rate() const { return estimate_.rate; }
  const RateEstimate& estimate() const { return estimate_; }
  void setMaxRate(double maxRate);

 private:
  struct Sent {
    std::uint32_t sequence;
    std::uint32_t bytes;
    double sentAt;
    double arrivedAt;  // receiver time, s (unwrapped); < 0: not yet reported
    bool settled;      // counted as arrived or lost
  };
  struct Outcome {
    double at;  // receiver time of arrival, or sender time when counted lost
    std::uint32_t bytes;
    bool lost;
  };
  double unwrap(std::uint32_t micros);
  // Bytes/s sent over the last measureWindow.
  double sentRate(double now) const;
  void settle();
  void decide(double now);

  RateControlOptions options_;
  RateEstimate estimate_;
  std::deque<Sent> sent_;
  std::deque<Outcome> outcomes_;  // arrivals and losses over the measurement window
  // Least one-way delay per second of the base-delay window (LEDBAT's base delay history).
  std::deque<std::pair<double, double>> baseMinima_;
  std::deque<std::pair<double, double>> recentDelays_;  // (receiver time, one-way delay)
  bool clockKnown_ = false;
  std::uint32_t lastMicros_ = 0;
  double receiverClock_ = 0;  // s, unwrapped
  double newestArrival_ = -1;
  std::uint32_t newestSequence_ = 0;
  std::uint32_t nextUnsettled_ = 0;  // sequence of the oldest record not yet settled
  bool haveNewest_ = false;
  double lastDecision_ = -1, holdUntil_ = -1;
  double lastOveruseRate_ = 0;
  bool startupDone_ = false;
  bool appLimited_ = false;
};

}  // namespace pc
