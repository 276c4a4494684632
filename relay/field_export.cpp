#include "field_export.h"

#include <pthread.h>

#include <algorithm>
#include <chrono>

#include "common/log.h"
#include "protocol/session_messages.h"

namespace pc::relay {

double wallSeconds() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

double wallTimeOf(double steady) { return wallSeconds() - (steadySeconds() - steady); }

Result<std::unique_ptr<FieldExporter>> FieldExporter::create(FieldHub& hub, ExportOptions options) {
  if (!validToken(options.bucket.name))
    return Error{"bucket name '" + options.bucket.name + "': letters, digits, '-' and '_' only"};
  auto nats = NatsConnection::connect(options.nats);
  if (!nats) return nats.error();
  return std::unique_ptr<FieldExporter>(
      new FieldExporter(hub, std::move(options), std::move(nats).value()));
}

FieldExporter::FieldExporter(FieldHub& hub, ExportOptions options, NatsConnection nats)
    : hub_(hub), options_(std::move(options)), nats_(std::move(nats)) {
  // The publisher's epoch, fresh for every run: relays holding an earlier run's field start
  // over, and clients of every relay resume with the versions of this one.
  {
    auto hubLock = hub_.lock();
    epoch_ = hub_.publisher().sessionInfo().fieldEpoch;
  }
  std::lock_guard lock(statsMutex_);
  stats_.epoch = epoch_;
}

FieldExporter::~FieldExporter() { stop(); }

void FieldExporter::start() {
  if (thread_.joinable()) return;
  thread_ = std::thread([this] {
    pthread_setname_np(pthread_self(), "pc-export");
    run();
  });
}

void FieldExporter::stop() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
}

ExportStats FieldExporter::stats() const {
  std::lock_guard lock(statsMutex_);
  ExportStats s = stats_;
  s.connected = bucket_ && nats_.connected();
  return s;
}

void FieldExporter::failed(const std::string& why) {
  std::lock_guard lock(statsMutex_);
  ++stats_.putErrors;
  if (stats_.lastError != why) logWarn("field export: " + why);
  stats_.lastError = why;
}

void FieldExporter::run() {
  auto sub = nats_.subscribe("probecast." + options_.bucket.name + ".*.*");
  if (sub)
    relaySubjects_ = std::move(sub).value();
  else
    failed(sub.error().message);
  while (!stop_) {
    // The wait for relays' messages is the loop's pace.
    if (relaySubjects_) {
      auto m = relaySubjects_.next(options_.pollInterval);
      if (m && *m) onMessage(**m, steadySeconds());
    } else {
      std::this_thread::sleep_for(std::chrono::duration<double>(options_.pollInterval));
    }
    const double now = steadySeconds();
    if (!bucket_ && (now < retryAt_ || !openBucket())) continue;
    exportChanges(now);
  }
}

bool FieldExporter::openBucket() {
  auto bucket = nats_.createBucket(options_.bucket);
  if (!bucket) {
    retryAt_ = steadySeconds() + 0.5;
    failed(bucket.error().message);
    return false;
  }
  maxValueBytes_ =
      options_.bucket.maxValueBytes > 0 ? options_.bucket.maxValueBytes : nats_.maxPayload();
  bucket_ = std::move(bucket).value();
  CatalogueRecord catalogue;
  catalogue.epoch = epoch_;
  catalogue.sceneName = options_.sceneName;
  {
    auto lock = hub_.lock();
    const FieldPublisher& p = hub_.publisher();
    catalogue.sessionInfoFrame = encodeMessage(p.sessionInfo());
    exported_.assign(std::size_t(p.cascadeCount()), {});
    for (int k = 0; k < p.cascadeCount(); ++k)
      exported_[std::size_t(k)].assign(std::size_t(p.brickCount(k)), 0);
  }
  sceneSerial_ = 0;
  if (!put(kCatalogueKey, encodeCatalogue(catalogue))) return false;
  logInfo("field export: bucket " + options_.bucket.name + " open, epoch " +
          std::to_string(epoch_) + ", putting the whole field");
  std::lock_guard lock(statsMutex_);
  ++stats_.republishes;
  return true;
}

bool FieldExporter::put(const std::string& key, const std::vector<std::uint8_t>& value) {
  if (maxValueBytes_ > 0 && std::int64_t(value.size()) > maxValueBytes_) {
    std::lock_guard lock(statsMutex_);
    ++stats_.oversized;
    stats_.lastError =
        key + ": " + std::to_string(value.size()) + " bytes, over the bucket's limit";
    return true;  // left out; relays keep the older value (see PROTOCOL.md)
  }
  auto revision = bucket_.put(key, value);
  if (!revision) {
    // Whatever NATS lost, the bucket is opened (created where it vanished) and the whole field
    // put again once it answers.
    failed(revision.error().message);
    bucket_ = KvBucket();
    retryAt_ = steadySeconds() + 0.25;
    return false;
  }
  std::lock_guard lock(statsMutex_);
  stats_.bytesPut += value.size();
  return true;
}

void FieldExporter::exportChanges(double now) {
  struct Due {
    int cascade;
    std::uint32_t brick;
    std::uint64_t version;
  };
  std::vector<Due> due;
  std::shared_ptr<const std::vector<std::uint8_t>> sceneFrame;
  std::uint64_t serial = 0, fieldVersion = 0;
  {
    auto lock = hub_.lock();
    serial = hub_.sceneSerial();
    if (serial == sceneSerial_ && now - lastStatePut_ < options_.heartbeat) return;
    const FieldPublisher& p = hub_.publisher();
    for (int k = 0; k < p.cascadeCount(); ++k)
      for (int b = 0; b < p.brickCount(k); ++b) {
        const std::uint64_t v = p.current(k, b).version;
        if (v != 0 && v != exported_[std::size_t(k)][std::size_t(b)])
          due.push_back(Due{k, std::uint32_t(b), v});
      }
    sceneFrame = hub_.sceneFrame();
    fieldVersion = p.fieldVersion();
  }
  for (const Due& d : due) {
    BrickRecord record;
    record.epoch = epoch_;
    record.cascade = std::uint16_t(d.cascade);
    record.brick = d.brick;
    record.version = d.version;
    {
      // One brick per lock: the network thread's senders interleave with a large export. The
      // self-contained encoding comes from the publisher's cache, where a client that needs one
      // finds it too, so each is made once.
      auto lock = hub_.lock();
      auto encoded = hub_.publisher().encoded(d.cascade, int(d.brick), d.version, 0);
      if (!encoded) continue;  // superseded meanwhile: the next round puts the newer one
      record.payload = encoded->payload;
      record.wallTime = wallTimeOf(hub_.publisher().current(d.cascade, int(d.brick)).publishedAt);
    }
    if (!put(brickKey(d.cascade, d.brick), encodeBrickRecord(record))) return;
    exported_[std::size_t(d.cascade)][d.brick] = d.version;
    std::lock_guard lock(statsMutex_);
    ++stats_.bricksPut;
  }
  if (!sceneFrame) return;
  StateRecord state;
  state.epoch = epoch_;
  state.fieldVersion = fieldVersion;
  state.sceneStateFrame = *sceneFrame;
  if (auto decoded = decodeMessage(*sceneFrame); decoded) {
    if (const auto* s = std::get_if<SceneStateMsg>(&*decoded))
      state.wallTime = wallTimeOf(s->publishTime);
  }
  if (!put(kStateKey, encodeState(state))) return;
  sceneSerial_ = serial;
  lastStatePut_ = now;
  std::lock_guard lock(statsMutex_);
  ++stats_.statesPut;
  stats_.fieldVersion = fieldVersion;
}

void FieldExporter::onMessage(const NatsMessage& m, double now) {
  const std::string posesPrefix = "probecast." + options_.bucket.name + ".poses.";
  const std::string loadPrefix = "probecast." + options_.bucket.name + ".load.";
  // The relay's name is the subject's last token (NATS permissions tie it to the relay's
  // credentials), not what the message says.
  if (m.subject.rfind(posesPrefix, 0) == 0) {
    auto poses = decodePoses(m.data);
    std::lock_guard lock(statsMutex_);
    if (!poses) {
      ++stats_.badMessages;
      return;
    }
    ++stats_.poseMessages;
    hub_.setRemoteViewers(m.subject.substr(posesPrefix.size()), std::move(poses->positions),
                          std::move(poses->weights), now + options_.poseLifetime);
  } else if (m.subject.rfind(loadPrefix, 0) == 0) {
    auto load = decodeLoad(m.data);
    std::lock_guard lock(statsMutex_);
    if (!load) {
      ++stats_.badMessages;
      return;
    }
    load->relay = m.subject.substr(loadPrefix.size());
    loads_[load->relay] = {*load, now};
    stats_.relays.clear();
    for (auto it = loads_.begin(); it != loads_.end();) {
      if (now - it->second.second > 10.0) {
        it = loads_.erase(it);
        continue;
      }
      stats_.relays.push_back(RelayLoad{it->second.first, now - it->second.second});
      ++it;
    }
  }
}

void appendExportMetrics(MetricsText& m, const ExportStats& s) {
  m.gauge("probecast_export_connected", "1 while NATS answers and the field's bucket is open.",
          s.connected ? 1.0 : 0.0);
  m.gauge("probecast_export_field_version", "The newest field version put into the bucket.",
          double(s.fieldVersion));
  m.counter("probecast_export_bricks_total", "Brick versions put into the bucket.",
            double(s.bricksPut));
  m.counter("probecast_export_bytes_total", "Bytes put into the bucket.", double(s.bytesPut));
  m.counter("probecast_export_errors_total", "Puts NATS refused (each re-puts the whole field).",
            double(s.putErrors));
  m.counter("probecast_export_republishes_total", "Times the whole field was put (bucket opened).",
            double(s.republishes));
  m.counter("probecast_export_oversized_total", "Values over the bucket's size limit, left out.",
            double(s.oversized));
  m.counter("probecast_export_pose_messages_total", "Viewer pose messages from relays.",
            double(s.poseMessages));
  m.gauge("probecast_relays", "Relays heard from within 10 s.", double(s.relays.size()));
  for (const RelayLoad& r : s.relays)
    m.gauge("probecast_relay_clients", "Clients each relay serves (its latest report).",
            double(r.load.clients), {{"relay", r.load.relay}});
}

}  // namespace pc::relay
