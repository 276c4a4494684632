// In-memory links with simulated faults, for tests and benchmarks of the stream logic (and a
// model for a fault-injecting UDP relay): FaultLink loses, bursts, duplicates, reorders,
// corrupts and delays datagrams; ReliableLink delivers a byte stream's messages in order after
// a delay, as TCP would. Deterministic for a given seed; time is passed in.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <random>
#include <vector>

namespace pc {

struct FaultProfile {
  double loss = 0;         // probability a datagram is dropped
  double burstStart = 0;   // probability a loss burst starts at a datagram
  double burstLength = 8;  // mean datagrams lost in a burst
  double duplicate = 0;    // probability a datagram is delivered twice
  double reorder = 0;      // probability a datagram is held back by reorderDelay more
  double reorderDelay = 0.05;
  double corrupt = 0;             // probability a datagram has bits flipped or is truncated
  double delay = 0.01;            // s, one way
  double jitter = 0;              // s, uniform extra delay
  std::size_t queueLimit = 4096;  // datagrams in flight; more are dropped (a full router queue)
  // A bottleneck: > 0 sends datagrams one after another at this many bytes per second through
  // a drop-tail queue of queueBytes (a router before a slow link, as tbf models it).
  double rate = 0;
  std::size_t queueBytes = 64 * 1024;
};

struct LinkStats {
  std::uint64_t sent = 0, delivered = 0, lost = 0, duplicated = 0, corrupted = 0, reordered = 0;
  std::uint64_t overflow = 0;
  std::size_t maxInFlight = 0;
};

class FaultLink {
 public:
  explicit FaultLink(std::uint64_t seed) : rng_(seed) {}
  void setProfile(const FaultProfile& p) { profile_ = p; }
  const FaultProfile& profile() const { return profile_; }
  void send(std::vector<std::uint8_t> bytes, double now);
  // Datagrams whose delivery time has come, in delivery order.
  std::vector<std::vector<std::uint8_t>> receive(double now);
  std::size_t inFlight() const { return queue_.size(); }
  const LinkStats& stats() const { return stats_; }

 private:
  struct InFlight {
    double at;
    std::uint64_t order;
    std::vector<std::uint8_t> bytes;
  };
  void enqueue(std::vector<std::uint8_t> bytes, double at);
  double uniform() { return std::uniform_real_distribution<double>(0.0, 1.0)(rng_); }

  FaultProfile profile_;
  std::mt19937_64 rng_;
  std::vector<InFlight> queue_;
  std::uint64_t order_ = 0;
  int burstLeft_ = 0;
  double linkFree_ = 0;  // when the bottleneck has sent what it holds
  LinkStats stats_;
};

class ReliableLink {
 public:
  void setDelay(double seconds) { delay_ = seconds; }
  void send(std::vector<std::uint8_t> bytes, double now);
  std::vector<std::vector<std::uint8_t>> receive(double now);
  std::size_t inFlight() const { return queue_.size(); }

 private:
  double delay_ = 0.01;
  double last_ = -1e30;
  std::deque<std::pair<double, std::vector<std::uint8_t>>> queue_;
};

}  // namespace pc
