// What the field thread and the network thread share: the FieldPublisher (with every client's
// StreamSender reading it), the newest scene state, and the viewers' positions. One mutex
// guards all of it; the field thread holds it only while publishing a finished update, the
// network threads while they poll the senders, so neither waits long for the other. Polls of
// senders share it (sharedLock: the publisher and the change cache guard what readers
// change); everything else takes it whole (lock).
#pragma once

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <deque>
#include <glm/glm.hpp>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <shared_mutex>
#include <string>
#include <vector>

#include "common/field.h"
#include "common/result.h"
#include "protocol/field_publisher.h"
#include "protocol/session_messages.h"

namespace pc {

// The server's clock: seconds on a monotonic clock. Publishing and every sender use it.
inline double steadySeconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

class FieldHub {
 public:
  FieldHub(const Field& layout, PublisherOptions options = {}) : publisher_(layout, options) {}

  // Field thread: a finished update and the scene state it was traced at. The state goes out
  // stamped with the field version and the moment it became visible to the senders (`now` is
  // the tick's start, before tracing), so clients can measure latency from publish to apply.
  // Quantizing the changed bricks is the slow part and happens before the lock is taken (only
  // this thread changes what it reads), so the network thread waits only for the commit.
  Status publish(const Field& field, const SceneStateMsg& state, double now) {
    auto prepared = publisher_.prepare(field);
    if (!prepared) return prepared.error();
    SceneStateMsg stamped = state;
    stamped.fieldVersion = field.version;
    stamped.publishTime = steadySeconds();
    commit(std::move(prepared).value(), stamped, now);
    return Status::success();
  }

  // A relay's publish: bricks quantized elsewhere (the field server's, decoded from NATS) and
  // the scene state they go with, stamped already. Versions only ever grow: the caller passes
  // bricks newer than the ones held.
  void commit(PreparedBricks prepared, const SceneStateMsg& stamped, double now) {
    auto frame = std::make_shared<const std::vector<std::uint8_t>>(encodeMessage(stamped));
    std::unique_lock lock(mutex_);
    sceneFrame_ = std::move(frame);
    animationTime_ = stamped.animationTime;
    ++sceneSerial_;
    publisher_.moveCascades(stamped.cascadePlaces);
    publisher_.commit(std::move(prepared), now);
    publishTimes_.emplace_back(stamped.fieldVersion, stamped.publishTime);
    if (publishTimes_.size() > kPublishTimesKept) publishTimes_.pop_front();
  }

  // Viewer positions by session, for the probe scheduler. A session holds one viewer (its
  // newest pose replaces the previous one), which counts when its weight is at least 1: the
  // scheduler ranks probes by their nearest viewer, a viewer of weight w counting as w times
  // nearer, so a weight never buys a client more viewers; weight 0 gives a session's pose no
  // say at all.
  void setViewer(std::uint32_t session, glm::vec3 position, int weight = 1) {
    std::unique_lock lock(mutex_);
    viewers_[session] = Viewer{position, weight};
  }
  void removeViewer(std::uint32_t session) {
    std::unique_lock lock(mutex_);
    viewers_.erase(session);
  }
  // Viewers of another process's clients (a relay's, through NATS), replacing what `source`
  // sent before; they count as this process's own until `expiresAt` (steadySeconds()), so a
  // relay that dies stops steering the scheduler. Weights as setViewer's.
  void setRemoteViewers(const std::string& source, std::vector<glm::vec3> positions,
                        std::vector<float> weights, double expiresAt) {
    std::unique_lock lock(mutex_);
    remote_[source] = Remote{std::move(positions), std::move(weights), expiresAt};
  }
  // The same with each viewer's weight, for the scheduler (ProbeScheduler::plan).
  void weightedViewers(std::vector<glm::vec3>& positions, std::vector<float>& weights) const {
    std::shared_lock lock(mutex_);
    positions.clear();
    weights.clear();
    for (const auto& [id, v] : viewers_) {
      if (v.weight <= 0) continue;
      positions.push_back(v.position);
      weights.push_back(float(v.weight));
    }
    const double now = steadySeconds();
    for (const auto& [source, r] : remote_) {
      if (r.expiresAt < now) continue;
      for (std::size_t i = 0; i < r.positions.size() && i < r.weights.size(); ++i) {
        if (!(r.weights[i] > 0)) continue;
        positions.push_back(r.positions[i]);
        weights.push_back(r.weights[i]);
      }
    }
  }
  std::vector<glm::vec3> viewers() const {
    std::vector<glm::vec3> out;
    std::vector<float> weights;
    weightedViewers(out, weights);
    return out;
  }

  // Everything below is read under lock() by the network thread, or under sharedLock() by the
  // threads that poll senders (StreamSender::poll and what it reads) at once.
  std::unique_lock<std::shared_mutex> lock() const { return std::unique_lock(mutex_); }
  std::shared_lock<std::shared_mutex> sharedLock() const { return std::shared_lock(mutex_); }
  FieldPublisher& publisher() { return publisher_; }
  // Encoded SceneState of the newest update (null before the first), and a counter that
  // changes with it.
  std::shared_ptr<const std::vector<std::uint8_t>> sceneFrame() const { return sceneFrame_; }
  std::uint64_t sceneSerial() const { return sceneSerial_; }
  double animationTime() const { return animationTime_; }
  // When a brick version became visible to the senders: the publish time (the one clients
  // measure latency from, SceneStateMsg::publishTime) of the first field version at or after
  // it; nothing once it is older than the versions kept.
  std::optional<double> publishTimeOf(std::uint64_t version) const {
    auto it = std::lower_bound(publishTimes_.begin(), publishTimes_.end(), version,
                               [](const auto& p, std::uint64_t v) { return p.first < v; });
    if (it == publishTimes_.end() || (it == publishTimes_.begin() && it->first != version))
      return std::nullopt;
    return it->second;
  }

 private:
  mutable std::shared_mutex mutex_;
  FieldPublisher publisher_;
  std::shared_ptr<const std::vector<std::uint8_t>> sceneFrame_;
  std::uint64_t sceneSerial_ = 0;
  double animationTime_ = 0;
  static constexpr std::size_t kPublishTimesKept = 256;
  std::deque<std::pair<std::uint64_t, double>> publishTimes_;  // (field version, publish time)
  struct Viewer {
    glm::vec3 position;
    int weight;
  };
  std::map<std::uint32_t, Viewer> viewers_;
  struct Remote {
    std::vector<glm::vec3> positions;
    std::vector<float> weights;
    double expiresAt = 0;
  };
  std::map<std::string, Remote> remote_;
};

}  // namespace pc
