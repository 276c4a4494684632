// The field server's side of field distribution: a thread that follows the FieldHub and puts
// each brick version, once and self-contained, with the field's catalogue and the newest scene
// state, into a NATS JetStream key-value bucket (PROTOCOL.md, "Field distribution over NATS");
// it takes the relays' viewer poses into the hub, so the probe scheduler serves the union of
// every relay's viewers, and keeps the load each relay reports.
#pragma once

#include <atomic>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "common/result.h"
#include "relay/field_bucket.h"
#include "relay/nats_client.h"
#include "server/net_hub.h"
#include "server/net_metrics.h"

namespace pc::relay {

struct ExportOptions {
  NatsOptions nats;
  BucketOptions bucket;
  std::string sceneName = "builtin";  // what connect tokens name, for the relays
  double pollInterval = 0.01;         // s between looks at the hub (and waits for pose messages)
  double heartbeat = 0.5;             // s: the state is put at least this often, so relays see life
  double poseLifetime = 2.0;  // s a relay's poses steer the scheduler after its last message
};

struct RelayLoad {
  LoadMessage load;
  double age = 0;  // s since its latest report
};

struct ExportStats {
  bool connected = false;  // to NATS, with the bucket open
  std::uint64_t epoch = 0;
  std::uint64_t fieldVersion = 0;  // the newest field version put (its state)
  std::uint64_t bricksPut = 0, statesPut = 0, bytesPut = 0;
  std::uint64_t putErrors = 0;
  std::uint64_t republishes = 0;  // times the whole field was put again (bucket (re)opened)
  std::uint64_t oversized = 0;    // values over the bucket's size limit, left out
  std::uint64_t poseMessages = 0, badMessages = 0;
  std::string lastError;
  std::vector<RelayLoad> relays;  // relays heard from within the last 10 s
};

// probecast_export_* and probecast_relay_clients for the server's /metrics.
void appendExportMetrics(MetricsText& out, const ExportStats& stats);

class FieldExporter {
 public:
  // Connects to NATS; the bucket is created (or opened) by the thread, which retries while
  // NATS is away. `hub` must outlive the exporter.
  static Result<std::unique_ptr<FieldExporter>> create(FieldHub& hub, ExportOptions options);
  ~FieldExporter();  // stop()
  FieldExporter(const FieldExporter&) = delete;
  FieldExporter& operator=(const FieldExporter&) = delete;

  void start();
  void stop();
  ExportStats stats() const;

 private:
  FieldExporter(FieldHub& hub, ExportOptions options, NatsConnection nats);
  void run();
  // Puts what changed since the last call (everything after the bucket was opened).
  void exportChanges(double now);
  bool openBucket();
  bool put(const std::string& key, const std::vector<std::uint8_t>& value);
  void onMessage(const NatsMessage& m, double now);
  void failed(const std::string& why);

  FieldHub& hub_;
  ExportOptions options_;
  NatsConnection nats_;
  KvBucket bucket_;
  NatsSubscription relaySubjects_;
  std::uint64_t epoch_ = 0;
  std::int64_t maxValueBytes_ = 0;
  // [cascade][brick]: the version last put (0: none since the bucket was opened).
  std::vector<std::vector<std::uint64_t>> exported_;
  std::uint64_t sceneSerial_ = 0;
  double lastStatePut_ = -1e9;
  double retryAt_ = 0;
  std::map<std::string, std::pair<LoadMessage, double>> loads_;

  std::atomic<bool> stop_{false};
  std::thread thread_;
  mutable std::mutex statsMutex_;
  ExportStats stats_;
};

// Unix seconds now, and a steadySeconds() time as Unix seconds (what records carry, so that a
// relay on another host measures the time since the field server published).
double wallSeconds();
double wallTimeOf(double steady);

}  // namespace pc::relay
