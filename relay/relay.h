// probecast-relay's core: a stateless edge that follows the field server's bucket (catching up
// from it when it starts, then following its changes) into a FieldHub of its own, and serves
// clients from that hub with the server's own network layer (NetServer: TLS, connect tokens,
// sealed datagrams, rate control, repair, limits), so a client cannot tell a relay from the
// server. Residual encodings are made here, against the versions this relay holds; what comes
// through NATS is self-contained. The relay sends its clients' viewer poses (for the field
// server's scheduler) and its load (clients) back on NATS subjects, and nothing else.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "common/result.h"
#include "protocol/brick_codec.h"
#include "protocol/session_messages.h"
#include "relay/field_bucket.h"
#include "relay/nats_client.h"
#include "server/net_server.h"

namespace pc::relay {

struct RelayOptions {
  NatsOptions nats;
  std::string bucket = "probecast-field";
  std::string relayId;  // subject token of its poses and load (letters, digits, '-', '_')
  // The client-facing side, as the server's. sceneName empty: the catalogue's.
  NetServerOptions net;
  PublisherOptions publisher;
  std::string advertise;      // host:port clients reach this relay at, in its load reports
  double poseInterval = 0.2;  // s between pose messages
  double loadInterval = 1.0;  // s between load messages
  // No change for this long (the field server puts its state every heartbeat) restarts the
  // watch, which then catches up from the bucket again: how a NATS restart is got over.
  double watchSilence = 2.0;
  // Bricks without their state are committed after this long anyway (s).
  double commitDelay = 0.05;
};

struct RelayStats {
  bool serving = false;  // caught up and listening
  bool natsConnected = false;
  std::uint64_t epoch = 0;  // the field server run whose field this relay holds
  std::uint64_t fieldVersion = 0;
  std::uint64_t bricksApplied = 0, statesApplied = 0, commits = 0;
  std::uint64_t badRecords = 0;    // values that did not decode or fit the layout
  std::uint64_t staleRecords = 0;  // of another epoch, or not newer than what is held
  std::uint64_t watchRestarts = 0, epochChanges = 0;
  std::uint64_t poseMessages = 0, loadMessages = 0, publishErrors = 0;
  double natsLatencyMs = 0;  // field server's publish -> this relay's commit, latest state
  std::string lastError;
};

// probecast_relay_* for the relay's /metrics.
void appendRelayMetrics(MetricsText& out, const RelayStats& stats);

class Relay {
 public:
  static Result<std::unique_ptr<Relay>> create(RelayOptions options);
  ~Relay();  // stop()
  Relay(const Relay&) = delete;
  Relay& operator=(const Relay&) = delete;

  // Starts following; returns once the relay has caught up and listens for clients, or an
  // Error after `timeoutSeconds` (nothing in the bucket yet, NATS away) or where the listener
  // cannot be bound. The follower goes on either way until stop().
  Status start(double timeoutSeconds);
  void stop();

  std::uint16_t port() const;
  std::uint16_t metricsPort() const;
  const std::string& tlsFingerprint() const;
  RelayStats stats() const;
  // The serving side's figures (sessions, bytes); zeros before serving.
  NetServerStats serverStats() const;
  // Reads the hub under its lock (tests): false before serving.
  bool withHub(const std::function<void(const FieldHub&)>& read) const;

 private:
  explicit Relay(RelayOptions options, NatsConnection nats);
  void run();
  void handle(const KvChange& change, double now);
  void onCatalogue(const CatalogueRecord& catalogue);
  void onBrick(const BrickRecord& record);
  void commit(double now);
  void sendPosesAndLoad(double now);
  void setError(const std::string& why);

  RelayOptions options_;
  NatsConnection nats_;
  KvBucket bucket_;
  KvWatcher watcher_;
  double lastChange_ = 0, retryAt_ = 0, lastPoses_ = 0, lastLoad_ = 0;

  // The field as far as this relay follows it (follower thread only, but for the hub's own lock).
  std::optional<CatalogueRecord> catalogue_;
  std::optional<StateRecord> state_;
  bool stateChanged_ = false;
  std::vector<std::vector<std::uint64_t>> held_;  // [cascade][brick] newest version taken
  std::vector<PreparedBricks::Brick> pending_;
  double pendingSince_ = 0, pendingWall_ = 0;
  bool caughtUp_ = false;
  std::vector<KvChange> early_;  // changes before the catalogue arrived
  std::size_t earlyBytes_ = 0;
  static constexpr std::size_t kMaxEarlyBytes = 256u << 20;

  mutable std::mutex serveMutex_;  // guards hub_ and server_ against readers on other threads
  std::unique_ptr<FieldHub> hub_;
  std::unique_ptr<NetServer> server_;
  std::uint16_t boundPort_ = 0, metricsPort_ = 0;
  std::string fingerprint_;

  std::atomic<bool> stop_{false};
  std::atomic<bool> serving_{false};
  std::thread thread_;
  mutable std::mutex statsMutex_;
  RelayStats stats_;
};

}  // namespace pc::relay
