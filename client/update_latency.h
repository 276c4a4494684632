// The update latency a client sees: from the server publishing a field version (the publish
// time its SceneState carries) to a brick of that version arriving here. The server's clock
// is taken onto this one by the smallest offset seen in the session (arrival less publish
// time of the scene states), so the figure needs no shared clock: it is the latency beyond
// the fastest scene state's delivery. Bricks often overtake their version's SceneState
// (datagrams against the stream): they wait here until it comes, a few seconds at most.
#pragma once

#include <cstdint>
#include <deque>
#include <optional>
#include <utility>
#include <vector>

namespace pc::client {

class UpdateLatency {
 public:
  // A new session; bricks up to `joinVersion` (the newest at its start) are the initial
  // sync's, not updates, and are not measured.
  void startSession(std::uint64_t joinVersion);
  // A scene state: `version` published at `publishTime` (the server's clock), here at `now`.
  void published(std::uint64_t version, double publishTime, double now);
  // A brick of `version` arrived at `now`.
  void arrived(std::uint64_t version, double now);
  // The latencies (ms) measured since the last call.
  std::vector<float> take();

 private:
  std::optional<double> publishedAt(std::uint64_t version) const;
  void resolvePending(double now);

  std::uint64_t joinVersion_ = 0;
  std::optional<double> offset_;
  std::deque<std::pair<std::uint64_t, double>> publishTimes_;  // by version
  std::deque<std::pair<std::uint64_t, double>> pending_;       // (version, arrival)
  std::vector<float> samples_;
};

}  // namespace pc::client
