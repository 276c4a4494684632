#include "relay.h"

#include <pthread.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>

#include "common/log.h"
#include "net/tls_certificate.h"
#include "relay/field_export.h"

namespace pc::relay {

namespace {

void sleepSeconds(double s) { std::this_thread::sleep_for(std::chrono::duration<double>(s)); }

// A relay id where none was given: the host name and the process id, as a subject token.
std::string defaultRelayId() {
  char host[256] = {};
  gethostname(host, sizeof host - 1);
  std::string id;
  for (const char* c = host; *c; ++c)
    id += (std::isalnum(static_cast<unsigned char>(*c)) || *c == '-') ? *c : '_';
  return (id.empty() ? "relay" : id.substr(0, 40)) + "-" + std::to_string(getpid());
}

}  // namespace

Result<std::unique_ptr<Relay>> Relay::create(RelayOptions options) {
  if (options.relayId.empty()) options.relayId = defaultRelayId();
  if (!validToken(options.relayId))
    return Error{"relay id '" + options.relayId +
                 "': letters, digits, '-' and '_' only (64 at most)"};
  if (!validToken(options.bucket))
    return Error{"bucket name '" + options.bucket + "': letters, digits, '-' and '_' only"};
  if (options.nats.name.empty()) options.nats.name = "probecast-relay " + options.relayId;
  // One development certificate for the relay's life: the server it makes again for a new
  // field server run presents the same one, which clients have pinned.
  if (options.net.tls.enabled && options.net.tls.devSelfSigned && !options.net.tls.devCertificate) {
    auto dev = net::makeDevCertificate();
    if (!dev) return Error{"TLS: " + dev.error().message};
    options.net.tls.devCertificate =
        std::make_shared<const net::DevCertificate>(std::move(dev).value());
  }
  auto nats = NatsConnection::connect(options.nats);
  if (!nats) return nats.error();
  return std::unique_ptr<Relay>(new Relay(std::move(options), std::move(nats).value()));
}

Relay::Relay(RelayOptions options, NatsConnection nats)
    : options_(std::move(options)), nats_(std::move(nats)) {}

Relay::~Relay() { stop(); }

Status Relay::start(double timeoutSeconds) {
  if (!thread_.joinable()) {
    thread_ = std::thread([this] {
      pthread_setname_np(pthread_self(), "pc-follow");
      run();
    });
  }
  const double until = steadySeconds() + timeoutSeconds;
  while (!serving_ && steadySeconds() < until) sleepSeconds(0.01);
  if (serving_) return Status::success();
  const RelayStats s = stats();
  return Error{"no field to serve from bucket " + options_.bucket + " within " +
               std::to_string(int(timeoutSeconds)) +
               " s (is the field server running with --nats?)" +
               (s.lastError.empty() ? "" : ": " + s.lastError)};
}

void Relay::stop() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
  std::lock_guard lock(serveMutex_);
  if (server_) server_->stop();
  server_.reset();
  hub_.reset();
  serving_ = false;
}

std::uint16_t Relay::port() const {
  std::lock_guard lock(serveMutex_);
  return boundPort_;
}
std::uint16_t Relay::metricsPort() const {
  std::lock_guard lock(serveMutex_);
  return metricsPort_;
}
const std::string& Relay::tlsFingerprint() const {
  std::lock_guard lock(serveMutex_);
  return fingerprint_;
}

RelayStats Relay::stats() const {
  std::lock_guard lock(statsMutex_);
  RelayStats s = stats_;
  s.serving = serving_;
  s.natsConnected = nats_.connected();
  return s;
}

NetServerStats Relay::serverStats() const {
  std::lock_guard lock(serveMutex_);
  return server_ ? server_->stats() : NetServerStats{};
}

bool Relay::withHub(const std::function<void(const FieldHub&)>& read) const {
  std::lock_guard lock(serveMutex_);
  if (!hub_ || !serving_) return false;
  auto hubLock = hub_->lock();
  read(*hub_);
  return true;
}

void Relay::setError(const std::string& why) {
  std::lock_guard lock(statsMutex_);
  if (stats_.lastError != why) logWarn("relay: " + why);
  stats_.lastError = why;
}

void Relay::run() {
  while (!stop_) {
    double now = steadySeconds();
    if (!watcher_) {
      if (now < retryAt_) {
        sleepSeconds(0.02);
        sendPosesAndLoad(now);
        continue;
      }
      if (!bucket_) {
        auto bucket = nats_.openBucket(options_.bucket);
        if (!bucket) {
          setError(bucket.error().message);
          retryAt_ = now + 0.5;
          continue;
        }
        bucket_ = std::move(bucket).value();
      }
      // Every key's current value, then the changes: a relay that starts late, or whose
      // watch broke, catches up from the bucket. What it holds already is skipped.
      auto watcher = bucket_.watchAll();
      if (!watcher) {
        setError(watcher.error().message);
        bucket_ = KvBucket();
        retryAt_ = now + 0.5;
        continue;
      }
      watcher_ = std::move(watcher).value();
      lastChange_ = now;
    }
    auto change = watcher_.next(0.02);
    now = steadySeconds();
    if (!change) {
      setError(change.error().message);
      watcher_ = KvWatcher();
      retryAt_ = now + 0.25;
      std::lock_guard lock(statsMutex_);
      ++stats_.watchRestarts;
    } else if (*change) {
      lastChange_ = now;
      handle(**change, now);
    } else if (now - lastChange_ > options_.watchSilence) {
      // The field server puts its state every heartbeat: silence means the watch is broken
      // (a NATS server restarted, a consumer lost). Watch again; the relay serves what it
      // holds meanwhile.
      watcher_ = KvWatcher();
      std::lock_guard lock(statsMutex_);
      ++stats_.watchRestarts;
    }
    if (!pending_.empty() && caughtUp_ && now - pendingSince_ > options_.commitDelay) commit(now);
    sendPosesAndLoad(now);
  }
}

void Relay::handle(const KvChange& change, double now) {
  auto bad = [&](const std::string& why) {
    std::lock_guard lock(statsMutex_);
    ++stats_.badRecords;
    if (stats_.lastError != why) logWarn("relay: " + why);
    stats_.lastError = why;
  };
  if (change.caughtUp) {
    if (!catalogue_) {
      // An empty bucket: the field server made it and has put nothing yet (or this relay
      // started first). Everything from here on comes as it is put: the catalogue, then the
      // bricks, then the state naming their version, so the relay holds the whole field at
      // that first state and serves from there (commit).
      logInfo("relay: bucket " + options_.bucket + " is empty; waiting for the field server");
      caughtUp_ = true;
      return;
    }
    if (!caughtUp_) logInfo("relay: caught up from bucket " + options_.bucket);
    caughtUp_ = true;
    commit(now);
    return;
  }
  if (change.deleted) return;
  if (change.key == kCatalogueKey) {
    auto catalogue = decodeCatalogue(change.value);
    if (!catalogue) return bad(change.key + ": " + catalogue.error().message);
    onCatalogue(*catalogue);
    // What came before the catalogue, now that there is a layout to put it in.
    std::vector<KvChange> early = std::move(early_);
    early_.clear();
    earlyBytes_ = 0;
    for (const KvChange& c : early) handle(c, now);
    return;
  }
  if (!catalogue_) {
    // The catalogue is the bucket's first key, so this holds little; bounded all the same.
    if (earlyBytes_ + change.value.size() <= kMaxEarlyBytes) {
      earlyBytes_ += change.value.size();
      early_.push_back(change);
    }
    return;
  }
  if (change.key == kStateKey) {
    auto state = decodeState(change.value);
    if (!state) return bad(change.key + ": " + state.error().message);
    if (state->epoch != catalogue_->epoch) {
      std::lock_guard lock(statsMutex_);
      ++stats_.staleRecords;
      return;
    }
    // The heartbeat puts the same state again: nothing for the clients.
    if (state_ && state_->sceneStateFrame == state->sceneStateFrame) return;
    state_ = std::move(state).value();
    stateChanged_ = true;
    // The field server puts a version's bricks, then its state: the version is complete.
    if (caughtUp_) commit(now);
    return;
  }
  auto key = parseBrickKey(change.key);
  if (!key) return;  // a key of a later format: not this relay's business
  auto record = decodeBrickRecord(change.value);
  if (!record) return bad(change.key + ": " + record.error().message);
  if (record->cascade != key->first || record->brick != key->second)
    return bad(change.key + ": holds brick " + std::to_string(record->cascade) + "." +
               std::to_string(record->brick));
  onBrick(*record);
}

void Relay::onCatalogue(const CatalogueRecord& catalogue) {
  if (catalogue_ && catalogue_->epoch == catalogue.epoch) return;  // put again, same run
  auto message = decodeMessage(catalogue.sessionInfoFrame);
  const SessionInfoMsg* info = message ? std::get_if<SessionInfoMsg>(&*message) : nullptr;
  if (!info) {
    std::lock_guard lock(statsMutex_);
    ++stats_.badRecords;
    stats_.lastError = "catalogue: no session info";
    return;
  }
  auto layout = mirrorField(*info);
  if (!layout) {
    setError("catalogue: " + layout.error().message);
    std::lock_guard lock(statsMutex_);
    ++stats_.badRecords;
    return;
  }
  const bool rebuilding = hub_ != nullptr;
  if (rebuilding) {
    logWarn("relay: the field server started a new run (epoch " + std::to_string(catalogue.epoch) +
            "): clients start over with its field");
    std::lock_guard lock(statsMutex_);
    ++stats_.epochChanges;
  }
  catalogue_ = catalogue;
  if (state_ && state_->epoch != catalogue.epoch) state_.reset();
  pending_.clear();
  held_.assign(std::size_t(layout->cascadeCount()), {});
  for (int k = 0; k < layout->cascadeCount(); ++k)
    held_[std::size_t(k)].assign(std::size_t(gpu::pcBrickCount(layout->cascade(k))), 0);

  // The field server's epoch: its brick versions name the same content here, so clients
  // moving between its relays (or to it) resume (PROTOCOL.md "Resuming a session").
  PublisherOptions publisher = options_.publisher;
  publisher.epoch = catalogue.epoch;
  auto hub = std::make_unique<FieldHub>(*layout, publisher);
  NetServerOptions net = options_.net;
  if (net.sceneName.empty()) net.sceneName = catalogue.sceneName;
  std::lock_guard lock(serveMutex_);
  if (server_) server_->stop();  // its sessions end; clients reconnect to the new run's field
  server_.reset();
  hub_ = std::move(hub);
  serving_ = false;
  if (boundPort_ != 0) net.port = boundPort_;  // the same port again
  // Ready (GET /readyz): caught up, taking clients, and following the field with NATS up.
  // While NATS is away the relay goes on serving what it holds, but new clients are better
  // sent to a relay that follows the field.
  net.ready = [this] {
    const RelayStats s = stats();
    return s.serving && s.natsConnected;
  };
  auto server = NetServer::create(*hub_, net);
  if (!server) {
    setError("cannot serve: " + server.error().message);
    return;
  }
  server_ = std::move(server).value();
  server_->setExtraMetrics([this](MetricsText& m) { appendRelayMetrics(m, stats()); });
  boundPort_ = server_->port();
  metricsPort_ = server_->metricsPort();
  fingerprint_ = server_->tlsFingerprint();
  {
    std::lock_guard statsLock(statsMutex_);
    stats_.epoch = catalogue.epoch;
  }
  // Clients are let in once the relay holds the field (caught up), or at once on a new run.
  if (rebuilding) {
    server_->start();
    serving_ = true;
  }
}

void Relay::onBrick(const BrickRecord& r) {
  auto stale = [&] {
    std::lock_guard lock(statsMutex_);
    ++stats_.staleRecords;
  };
  if (r.epoch != catalogue_->epoch) return stale();
  if (r.cascade >= held_.size() || r.brick >= held_[r.cascade].size()) {
    std::lock_guard lock(statsMutex_);
    ++stats_.badRecords;
    stats_.lastError = "brick " + std::to_string(r.cascade) + "." + std::to_string(r.brick) +
                       " outside the catalogue's layout";
    return;
  }
  std::uint64_t& held = held_[r.cascade][r.brick];
  if (r.version <= held) return stale();
  auto decoded = decodeBrick(r.payload, nullptr);
  if (!decoded) {
    setError("brick " + std::to_string(r.cascade) + "." + std::to_string(r.brick) + ": " +
             decoded.error().message);
    std::lock_guard lock(statsMutex_);
    ++stats_.badRecords;
    return;
  }
  held = r.version;
  auto content = std::make_shared<const QuantizedBrick>(std::move(decoded).value());
  auto same = std::find_if(pending_.begin(), pending_.end(), [&](const PreparedBricks::Brick& b) {
    return b.cascade == int(r.cascade) && b.brick == r.brick;
  });
  if (same != pending_.end()) {
    same->version = r.version;
    same->content = std::move(content);
  } else {
    if (pending_.empty()) pendingSince_ = steadySeconds();
    pending_.push_back(
        PreparedBricks::Brick{int(r.cascade), r.brick, r.version, std::move(content)});
  }
}

void Relay::commit(double now) {
  if (!hub_ || !state_) return;
  if (pending_.empty() && !stateChanged_ && serving_) return;
  auto message = decodeMessage(state_->sceneStateFrame);
  const SceneStateMsg* state = message ? std::get_if<SceneStateMsg>(&*message) : nullptr;
  if (!state) {
    setError("state: no scene state");
    state_.reset();
    return;
  }
  PreparedBricks prepared;
  prepared.fieldVersion = state_->fieldVersion;
  for (const PreparedBricks::Brick& b : pending_)
    prepared.fieldVersion = std::max(prepared.fieldVersion, b.version);
  {
    auto lock = hub_->lock();
    prepared.fieldVersion = std::max(prepared.fieldVersion, hub_->publisher().fieldVersion());
  }
  const std::size_t bricks = pending_.size();
  prepared.bricks = std::move(pending_);
  pending_.clear();
  for (const auto& b : prepared.bricks) prepared.quantizedCodes += b.content->codes.size();
  // Clients measure latency from the field server's publish: its time, on this relay's clock.
  const double latency = std::max(0.0, wallSeconds() - state_->wallTime);
  SceneStateMsg stamped = *state;
  stamped.fieldVersion = prepared.fieldVersion;
  stamped.publishTime = now - latency;
  hub_->commit(std::move(prepared), stamped, stamped.publishTime);
  stateChanged_ = false;
  {
    std::lock_guard lock(statsMutex_);
    stats_.bricksApplied += bricks;
    ++stats_.statesApplied;
    ++stats_.commits;
    stats_.fieldVersion = stamped.fieldVersion;
    stats_.natsLatencyMs = latency * 1e3;
  }
  if (!serving_ && caughtUp_) {
    std::lock_guard lock(serveMutex_);
    if (server_) {
      server_->start();
      serving_ = true;
      logInfo("relay: serving field version " + std::to_string(stamped.fieldVersion) + " on port " +
              std::to_string(boundPort_));
    }
  }
}

void Relay::sendPosesAndLoad(double now) {
  auto sent = [&](const Status& s, std::uint64_t RelayStats::*counter) {
    std::lock_guard lock(statsMutex_);
    if (s) {
      ++(stats_.*counter);
    } else {
      ++stats_.publishErrors;
    }
  };
  if (now - lastPoses_ >= options_.poseInterval && hub_) {
    lastPoses_ = now;
    PosesMessage poses;
    poses.relay = options_.relayId;
    hub_->weightedViewers(poses.positions, poses.weights);
    sent(nats_.publish(posesSubject(options_.bucket, options_.relayId), encodePoses(poses)),
         &RelayStats::poseMessages);
  }
  if (now - lastLoad_ >= options_.loadInterval && serving_) {
    lastLoad_ = now;
    LoadMessage load;
    load.relay = options_.relayId;
    load.endpoint = options_.advertise.empty()
                        ? options_.net.bindAddress + ":" + std::to_string(boundPort_)
                        : options_.advertise;
    load.clients = serverStats().clients.size();
    load.maxClients = options_.net.maxClients;
    sent(nats_.publish(loadSubject(options_.bucket, options_.relayId), encodeLoad(load)),
         &RelayStats::loadMessages);
  }
}

void appendRelayMetrics(MetricsText& m, const RelayStats& s) {
  m.gauge("probecast_relay_serving", "1 once the relay holds the field and takes clients.",
          s.serving ? 1.0 : 0.0);
  m.gauge("probecast_relay_nats_connected", "1 while the relay's NATS connection is up.",
          s.natsConnected ? 1.0 : 0.0);
  m.gauge("probecast_relay_field_version", "The newest field version the relay holds.",
          double(s.fieldVersion));
  m.counter("probecast_relay_bricks_total", "Brick versions taken from the bucket.",
            double(s.bricksApplied));
  m.counter("probecast_relay_bad_records_total", "Bucket values that did not decode or fit.",
            double(s.badRecords));
  m.counter("probecast_relay_watch_restarts_total", "Times the bucket was watched again.",
            double(s.watchRestarts));
  m.counter("probecast_relay_epoch_changes_total", "New field server runs followed.",
            double(s.epochChanges));
  m.gauge("probecast_relay_nats_latency_seconds",
          "The field server's publish to this relay's commit, latest field version.",
          s.natsLatencyMs / 1e3);
}

}  // namespace pc::relay
