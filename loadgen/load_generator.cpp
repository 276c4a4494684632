#include "load_generator.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <boost/asio.hpp>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <deque>
#include <fstream>
#include <functional>
#include <future>
#include <limits>
#include <mutex>
#include <optional>
#include <random>
#include <thread>

#include "common/series_csv.h"
#include "net/load_probe.h"
#include "net/session_stream.h"
#include "protocol/client_session.h"
#include "shared_decoder.h"

namespace pc::load {

namespace asio = boost::asio;
using asio::ip::tcp;
using asio::ip::udp;
using Bytes = std::vector<std::uint8_t>;

namespace {

double nowSeconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// Publish times of this many recent field versions are kept per client.
constexpr std::size_t kMaxVersions = 1024;
// Applied updates whose publish time has not arrived yet wait this long, then count as
// unmatched.
constexpr double kPendingSeconds = 2.0;
constexpr double kStalenessSampleInterval = 0.1;
constexpr double kErrorRetryDelay = 0.5;

double residentMb() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmRSS:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  }
  return 0;
}

}  // namespace

class Client;

struct Worker {
  asio::io_context io;
  asio::steady_timer timer{io};
  std::vector<std::unique_ptr<Client>> clients;
  std::thread thread;
  bool stopping = false;
};

struct LoadGenerator::Impl {
  explicit Impl(LoadOptions o) : options(std::move(o)) {}

  void noteError(const std::string& message) {
    ++errors;
    std::lock_guard lock(mutex);
    if (errorSamples.size() < 10 &&
        std::find(errorSamples.begin(), errorSamples.end(), message) == errorSamples.end())
      errorSamples.push_back(message);
  }
  void scheduleTick(Worker& w);
  // Runs fn(worker) on every worker's own thread (or here once the threads are gone) and
  // waits, so reports and windows never race the clients' handlers.
  void onEveryWorker(const std::function<void(Worker&)>& fn);
  // What keeping a decoded field would cost, once per run (it allocates one).
  void measureLayout(const SessionInfoMsg& info);
  LoadInterval takeInterval();

  LoadOptions options;
  // options.host:port, then options.alternates, resolved once (every address of a name), with
  // the host names TLS checks.
  std::vector<tcp::endpoint> endpoints;
  std::vector<std::string> hosts;
  std::unique_ptr<std::atomic<int>[]> inSessionAt;  // clients in a session, per endpoint

  // Choosing by load (PROTOCOL.md "Choosing an endpoint by load"): a thread asks every endpoint
  // for its load every loadProbeInterval; between probes each session this process opens is
  // added to its endpoint's count, so that a ramp of joins spreads instead of following one
  // stale figure.
  std::size_t pickEndpoint(const std::string& avoid);
  void probeLoads();
  std::mutex loadMutex;
  std::vector<net::ProbedEndpoint> probed;
  std::vector<int> openedSinceProbe;
  std::thread prober;
  std::condition_variable proberWake;
  bool proberStop = false;
  std::shared_ptr<net::TlsClient> tls;  // shared by every client's connections
  std::unique_ptr<SharedBrickDecoder> decoder;
  std::vector<std::unique_ptr<Worker>> workers;
  bool running = false;
  double windowStart = 0;

  std::atomic<std::uint64_t> sessionsStarted{0}, sessionsEnded{0}, errors{0};
  std::atomic<std::uint64_t> newestFieldVersion{0};
  std::atomic<int> inSession{0}, synced{0};
  std::mutex mutex;  // errorSamples and the layout figures
  std::vector<std::string> errorSamples;
  double decodedFieldMb = 0, brickCodesMb = 0;
  bool layoutMeasured = false;

  // The series (options.seriesPath): a thread that writes a row every second.
  void writeSeries();
  std::unique_ptr<SeriesWriter> series;
  std::thread seriesThread;
  std::mutex seriesMutex;
  std::condition_variable seriesWake;
  bool seriesStop = false;
  double startedAt = 0, intervalStart = 0;
};

void LoadGenerator::Impl::writeSeries() {
  for (int second = 1;; ++second) {
    {
      std::unique_lock lock(seriesMutex);
      const auto due = std::chrono::steady_clock::time_point(
          std::chrono::duration_cast<std::chrono::steady_clock::duration>(
              std::chrono::duration<double>(startedAt + second)));
      if (seriesWake.wait_until(lock, due, [this] { return seriesStop; })) return;
    }
    // The row's figures come from the workers' threads (takeInterval waits for them).
    const LoadInterval interval = takeInterval();
    if (Status written = series->write(interval.seriesRow(double(second))); !written) {
      noteError(written.error().message);
      return;
    }
  }
}

void LoadGenerator::Impl::measureLayout(const SessionInfoMsg& info) {
  std::lock_guard lock(mutex);
  if (layoutMeasured) return;
  layoutMeasured = true;
  if (auto full = mirrorField(info)) {
    const double atlasFloats = double(full->irradiance.texels.size() + full->depth.texels.size() +
                                      full->occlusion.texels.size());
    decodedFieldMb = atlasFloats * sizeof(float) / 1e6;
    std::size_t bricks = 0;
    for (const auto& c : full->brickVersions) bricks += c.size();
    brickCodesMb = double(bricks) * double(quantizeBrick(*full, 0, 0).codes.size()) *
                   sizeof(std::uint16_t) / 1e6;
  }
}

namespace {

ClientSessionOptions sessionOptions(const LoadGenerator::Impl& gen, int index) {
  const LoadOptions& o = gen.options;
  ClientSessionOptions s;
  s.token =
      o.clientTokens.empty() ? o.token : o.clientTokens[std::size_t(index) % o.clientTokens.size()];
  s.name = "loadgen-" + std::to_string(index);
  s.connectTimeout = o.connectTimeout;
  s.silenceTimeout = o.silenceTimeout;
  s.poseInterval = o.poseInterval;
  s.maxMirrorBytes = o.maxMirrorBytes;
  s.uplinkDatagrams = !o.tcpOnly;
  s.receiver.keepField = o.keepField;
  s.receiver.decoder = o.shareDecoding ? gen.decoder.get() : nullptr;
  return s;
}

}  // namespace

// One simulated client: a sequence of sessions of one ClientSession, which holds the
// protocol; this class holds the sockets, the simulated viewer, churn and the figures. Lives
// on its worker's thread only; handlers carry the connection number they were started for
// and do nothing once it has changed.
class Client {
 public:
  Client(LoadGenerator::Impl& gen, Worker& worker, int index, double firstConnectAt)
      : gen_(gen),
        o_(gen.options),
        worker_(worker),
        index_(index),
        session_(sessionOptions(gen, index)),
        udp_(worker.io),
        rng_(gen.options.seed * 7919 + std::uint64_t(index)),
        nextConnectAt_(firstConnectAt) {
    std::uniform_real_distribution<double> phase(0.0, 6.283185307179586);
    posePhase_ = phase(rng_);
    // Classes in index order by their shares: client i is at (i + 0.5) / N of the population.
    const auto& links = gen.options.links;
    double total = 0;
    for (const LinkClass& l : links) total += l.share;
    if (total > 0) {
      const double at = (double(index) + 0.5) / double(std::max(1, gen.options.clients)) * total;
      double upTo = 0;
      for (std::size_t i = 0; i < links.size(); ++i) {
        upTo += links[i].share;
        if (at < upTo || i + 1 == links.size()) {
          linkClass_ = int(i);
          linkRate_ = links[i].mbit * 1e6 / 8.0;
          break;
        }
      }
    }
  }

  void tick(double now);
  void shutdown();
  int linkClass() const { return linkClass_; }
  void beginWindow(double now);
  ClientReport report(double now, std::vector<float>& latency, std::vector<float>& staleness,
                      std::uint64_t& unmatched);
  // Adds what this client saw since the last call to `sums`, and starts the next interval.
  void takeInterval(LoadInterval& sums, std::vector<float>& latency, std::vector<float>& staleness,
                    std::vector<float>& ages, std::vector<float>& psnr);

 private:
  // Session: the session's layout arrived (ClientSession streaming).
  enum class State { Idle, Connecting, Session, Done };

  struct Window {
    double start = 0;
    std::uint64_t sessions = 0, bytesDown = 0, bytesUp = 0, datagrams = 0, applied = 0, repairs = 0,
                  gapReports = 0, stale = 0, errors = 0, unmatched = 0;
    double sessionSeconds = 0, maxGap = 0, maxStaleness = 0;
    std::vector<float> latencyMs, stalenessMs;
    // The server's stream reports: squared errors (from the PSNR), oldest change ages, rates.
    std::vector<float> oldestChange;
    double heldSquares = 0, rateSum = 0, levelSum = 0;
    std::uint64_t reports = 0, linkDrops = 0, linkDatagrams = 0;
    std::string lastError;
  };
  // What the series' current second collects (LoadGenerator::takeInterval), window or not.
  struct Interval {
    std::uint64_t bytesDown = 0, errors = 0, reports = 0, gapReports = 0;
    double maxGap = 0;  // s between datagrams of a session, the longest in the interval
    std::vector<float> latencyMs, stalenessMs, oldestChange;
    double heldSquares = 0;
  };
  void addBytesDown(std::size_t n) {
    window_.bytesDown += n;
    interval_.bytesDown += n;
  }
  void addError(const std::string& message) {
    ++window_.errors;
    ++interval_.errors;
    window_.lastError = message;
    gen_.noteError(message);
  }
  void addLatency(double appliedAt, double published) {
    const float ms = float(std::max(0.0, appliedAt - published) * 1e3);
    if (inWindow(appliedAt)) window_.latencyMs.push_back(ms);
    interval_.latencyMs.push_back(ms);
  }

  void connect(double now);
  void endSession(double now, const std::string& error);
  void readStream();
  void receiveUdp();
  void afterInput(double now);
  void onLayout(double now);
  void onSceneState(const SceneStateMsg& state, double now);
  void onDatagram(const Status& status, double now);
  void noteSynced();  // counts the session as synced once it holds every brick
  void onReport(double now);
  // The emulated link: a datagram that reached this client's socket at `now` enters the
  // link's queue (or is dropped at its tail); deliverLink hands on those whose time came.
  void enterLink(std::span<const std::uint8_t> bytes, double now);
  void deliverLink(double now);
  void send(Bytes frame);
  // Acks and repair requests as datagrams to the server's UDP port (ClientSession decides).
  void sendUplink();
  void writeNext();
  void simulateViewer(double now);
  void sampleStaleness(double now);
  // Publish time of a field version on this client's clock; nullopt when unknown.
  std::optional<double> publishTime(std::uint64_t version) const;
  void recordLatency(std::uint64_t version, double appliedAt);
  void resolvePending(double now);
  bool inWindow(double t) const { return t >= window_.start; }

  LoadGenerator::Impl& gen_;
  const LoadOptions& o_;
  Worker& worker_;
  int index_;
  std::size_t endpoint_ = 0;  // into gen_.endpoints: chosen by load at each connect
  std::string avoid_;         // address:port of an endpoint whose session just failed
  ClientSession session_;
  // One stream per session; handlers hold it, so a closed stream outlives them.
  std::shared_ptr<net::SessionStream> stream_;
  udp::socket udp_;
  std::mt19937_64 rng_;
  double posePhase_ = 0;

  State state_ = State::Idle;
  std::uint64_t connection_ = 0;
  double nextConnectAt_ = 0, sessionStartedAt_ = 0, sessionEndsAt_ = 0;
  double lastDatagramAt_ = 0, lastStaleSampleAt_ = -1e30;
  std::uint64_t infoVersion_ = 0;  // field version at join: bricks up to it are the initial sync
  bool synced_ = false;
  double syncSeconds_ = -1;
  std::uint64_t maxHeld_ = 0, lastApplied_ = 0, lastRepairs_ = 0, lastGapReports_ = 0,
                lastStale_ = 0;
  std::deque<std::pair<std::uint64_t, double>> versions_;  // (field version, publish time)
  std::deque<std::pair<std::uint64_t, double>> pending_;   // (version, applied at)
  std::optional<double> clockOffset_;                      // client clock - server clock

  std::array<std::uint8_t, 4096> readBuffer_{};
  std::array<std::uint8_t, 2048> udpBuffer_{};
  udp::endpoint udpFrom_;  // a datagram's source: only the server's address counts
  std::deque<Bytes> writes_;
  std::size_t queuedBytes_ = 0;
  bool writing_ = false;

  Window window_;
  Interval interval_;
  int linkClass_ = -1;
  double linkRate_ = 0;                             // bytes/s; 0: no emulated link
  double linkFree_ = 0;                             // when the link finishes sending what it holds
  std::deque<std::pair<double, Bytes>> linkQueue_;  // (delivery time, datagram)
};

void Client::tick(double now) {
  switch (state_) {
    case State::Done:
      return;
    case State::Idle:
      if (now >= nextConnectAt_) connect(now);
      return;
    case State::Connecting:
    case State::Session:
      break;
  }
  deliverLink(now);
  if (session_.poseDue(now)) simulateViewer(now);
  auto frames = session_.poll(now);  // the connect and silence timeouts too
  if (!frames) return endSession(now, frames.error().message);
  for (Bytes& f : *frames) send(std::move(f));
  if (state_ != State::Session) return;  // a send may have failed
  // A resumed session may hold every brick from its start, with no datagram to say so.
  noteSynced();
  sendUplink();
  const ReceiverStats& rs = session_.receiver()->stats();
  window_.repairs += rs.repairBricks - lastRepairs_;
  window_.gapReports += rs.gapReports - lastGapReports_;
  interval_.gapReports += rs.gapReports - lastGapReports_;
  window_.stale += rs.stale - lastStale_;
  lastRepairs_ = rs.repairBricks;
  lastGapReports_ = rs.gapReports;
  lastStale_ = rs.stale;
  if (now - lastStaleSampleAt_ >= kStalenessSampleInterval) sampleStaleness(now);
  resolvePending(now);
  if (sessionEndsAt_ > 0 && now >= sessionEndsAt_) endSession(now, "");
}

void Client::connect(double now) {
  // Claims a session number; past maxSessions the client is done.
  std::uint64_t n = gen_.sessionsStarted.load();
  do {
    if (o_.maxSessions > 0 && n >= o_.maxSessions) {
      state_ = State::Done;
      return;
    }
  } while (!gen_.sessionsStarted.compare_exchange_weak(n, n + 1));
  ++window_.sessions;
  endpoint_ = gen_.pickEndpoint(avoid_);
  avoid_.clear();
  const std::uint64_t id = ++connection_;
  state_ = State::Connecting;
  session_.connecting(now);

  // A fresh UDP socket (and port) per session: datagrams still in flight for the previous
  // session never reach this one.
  std::uint16_t udpPort = 0;
  if (!o_.tcpOnly) {
    boost::system::error_code ec;
    udp_.open(gen_.endpoints[endpoint_].protocol() == tcp::v4() ? udp::v4() : udp::v6(), ec);
    if (!ec) udp_.bind(udp::endpoint(udp_.local_endpoint(ec).protocol(), 0), ec);
    if (!ec) udpPort = udp_.local_endpoint(ec).port();
    if (!ec) udp_.non_blocking(true, ec);
    if (ec) return endSession(now, "UDP socket: " + ec.message());
    receiveUdp();
  }
  stream_ = gen_.tls
                ? std::make_shared<net::SessionStream>(tcp::socket(worker_.io), gen_.tls->context())
                : std::make_shared<net::SessionStream>(tcp::socket(worker_.io));
  if (gen_.tls) {
    if (Status s = gen_.tls->prepare(*stream_->tlsStream(), gen_.hosts[endpoint_]); !s)
      return endSession(now, s.error().message);
  }
  auto onHandshake = [this, id, udpPort, st = stream_](boost::system::error_code ec) {
    if (id != connection_ || worker_.stopping) return;
    const double t = nowSeconds();
    if (ec) return endSession(t, "TLS handshake: " + ec.message());
    if (st->tls()) {
      auto secret = st->datagramSecret();
      if (!secret) return endSession(t, secret.error().message);
      session_.setDatagramKeys(deriveDatagramKeys(*secret));
    }
    send(session_.connected(t, udpPort));
    readStream();
  };
  stream_->socket().async_connect(gen_.endpoints[endpoint_], [this, id, st = stream_, onHandshake](
                                                                 boost::system::error_code ec) {
    if (id != connection_ || worker_.stopping) return;
    if (ec) return endSession(nowSeconds(), "connect: " + ec.message());
    boost::system::error_code ignored;
    st->socket().set_option(tcp::no_delay(true), ignored);
    st->asyncHandshake(net::ssl::stream_base::client, onHandshake);
  });
}

// Ends the current session: voluntarily (churn, shutdown) with an empty `error`.
void Client::endSession(double now, const std::string& error) {
  ++connection_;
  boost::system::error_code ec;
  if (stream_) stream_->close();
  udp_.close(ec);
  if (state_ == State::Session) {
    --gen_.inSession;
    --gen_.inSessionAt[endpoint_];
    window_.sessionSeconds += now - std::max(sessionStartedAt_, window_.start);
  }
  if (synced_) --gen_.synced;
  if (state_ == State::Session || state_ == State::Connecting) ++gen_.sessionsEnded;
  synced_ = false;
  session_.close();
  // Churn stands for a new client joining, which holds nothing; a lost connection (a relay
  // killed) resumes on the next endpoint from what the session held.
  if (error.empty()) session_.forgetHeld();
  writes_.clear();
  queuedBytes_ = 0;
  writing_ = false;
  pending_.clear();
  linkQueue_.clear();
  linkFree_ = 0;
  if (!error.empty()) addError(error);
  if (state_ == State::Done) return;
  state_ = worker_.stopping ? State::Done : State::Idle;
  nextConnectAt_ = now + (error.empty() ? o_.rejoinDelay : kErrorRetryDelay);
  // A session that failed moves on at once to the least loaded other endpoint (a relay that
  // died).
  if (!error.empty() && gen_.endpoints.size() > 1) {
    const tcp::endpoint& failed = gen_.endpoints[endpoint_];
    avoid_ = failed.address().to_string() + ":" + std::to_string(failed.port());
    nextConnectAt_ = now + o_.rejoinDelay;
  }
}

void Client::shutdown() {
  const double now = nowSeconds();
  if (state_ == State::Session || state_ == State::Connecting) endSession(now, "");
  state_ = State::Done;
}

void Client::readStream() {
  const std::uint64_t id = connection_;
  stream_->async_read_some(asio::buffer(readBuffer_), [this, id, st = stream_](
                                                          boost::system::error_code ec,
                                                          std::size_t n) {
    if (id != connection_ || worker_.stopping) return;
    const double now = nowSeconds();
    if (ec) {
      const bool closed = ec == asio::error::eof || ec == net::ssl::error::stream_truncated;
      return endSession(now, closed ? "connection closed by the server" : "read: " + ec.message());
    }
    addBytesDown(n);
    Status status = session_.onStreamBytes(std::span(readBuffer_.data(), n), now);
    afterInput(now);
    if (!status) return endSession(now, status.error().message);
    readStream();
  });
}

void Client::receiveUdp() {
  const std::uint64_t id = connection_;
  udp_.async_receive_from(
      asio::buffer(udpBuffer_), udpFrom_, [this, id](boost::system::error_code ec, std::size_t n) {
        if (id != connection_ || worker_.stopping) return;
        // Errors on a UDP socket are per datagram (an ICMP error, a truncated
        // read): keep going.
        if (!ec && n <= kMaxDatagramBytes + kSealOverheadBytes) {
          const double now = nowSeconds();
          const std::span bytes(udpBuffer_.data(), n);
          const DatagramSource source{udpFrom_.address() == gen_.endpoints[endpoint_].address(),
                                      udpFrom_.port()};
          if (linkRate_ > 0 && source.serverAddress) {
            enterLink(bytes, now);
            deliverLink(now);
          } else {
            addBytesDown(n);
            (void)session_.onDatagram(bytes, now, source);
            afterInput(now);
          }
        }
        if (id == connection_) receiveUdp();
      });
}

void Client::afterInput(double now) {
  for (const SessionEvent& e : session_.events()) {
    switch (e.kind) {
      case SessionEvent::Kind::Welcomed:
        break;
      case SessionEvent::Kind::Layout:
        onLayout(now);
        break;
      case SessionEvent::Kind::SceneState:
        onSceneState(e.scene, now);
        break;
      case SessionEvent::Kind::Datagram:
        onDatagram(e.status, now);
        break;
      case SessionEvent::Kind::StreamReport:
        onReport(now);
        break;
      case SessionEvent::Kind::EditResult:  // load clients send no edits
        break;
    }
  }
}

void Client::enterLink(std::span<const std::uint8_t> bytes, double now) {
  if (inWindow(now)) ++window_.linkDatagrams;
  // Drop-tail: the queue holds linkQueueSeconds of sending at the link's rate.
  const double start = std::max(linkFree_, now);
  if (start - now > o_.linkQueueSeconds) {
    if (inWindow(now)) ++window_.linkDrops;
    return;
  }
  linkFree_ = start + double(bytes.size()) / linkRate_;
  linkQueue_.emplace_back(linkFree_, Bytes(bytes.begin(), bytes.end()));
}

void Client::deliverLink(double now) {
  // Each datagram is handled at the time it left the link: its arrival time in the acks is
  // what a receiver behind that link would have seen.
  while (!linkQueue_.empty() && linkQueue_.front().first <= now) {
    auto [at, bytes] = std::move(linkQueue_.front());
    linkQueue_.pop_front();
    if (state_ != State::Connecting && state_ != State::Session) continue;
    addBytesDown(bytes.size());
    (void)session_.onDatagram(bytes, at);
    afterInput(at);
  }
}

void Client::onReport(double now) {
  const auto& r = session_.report();
  if (!r || !synced_) return;
  ++interval_.reports;
  interval_.heldSquares += std::pow(10.0, -double(r->heldPsnrDb) / 10.0);
  interval_.oldestChange.push_back(r->oldestChangeSeconds);
  if (!inWindow(now)) return;
  ++window_.reports;
  window_.heldSquares += std::pow(10.0, -double(r->heldPsnrDb) / 10.0);
  window_.oldestChange.push_back(r->oldestChangeSeconds);
  window_.rateSum += r->rate;
  window_.levelSum += r->qualityLevel;
}

void Client::onLayout(double now) {
  gen_.measureLayout(session_.info());
  state_ = State::Session;
  ++gen_.inSession;
  ++gen_.inSessionAt[endpoint_];
  sessionStartedAt_ = now;
  lastDatagramAt_ = now;
  synced_ = false;
  syncSeconds_ = -1;
  infoVersion_ = session_.info().fieldVersion;
  maxHeld_ = lastApplied_ = lastRepairs_ = lastGapReports_ = lastStale_ = 0;
  versions_.clear();
  pending_.clear();
  clockOffset_.reset();
  if (o_.sessionSeconds > 0) {
    std::uniform_real_distribution<double> jitter(-o_.sessionJitter, o_.sessionJitter);
    sessionEndsAt_ = now + o_.sessionSeconds * (1.0 + jitter(rng_));
  } else {
    sessionEndsAt_ = 0;
  }
}

void Client::onSceneState(const SceneStateMsg& state, double now) {
  if (state.fieldVersion == 0) return;  // a server without publish times
  if (!o_.sameClock) {
    const double offset = now - state.publishTime;
    if (!clockOffset_ || offset < *clockOffset_) clockOffset_ = offset;
  }
  for (std::uint64_t v = gen_.newestFieldVersion.load(); state.fieldVersion > v;) {
    if (gen_.newestFieldVersion.compare_exchange_weak(v, state.fieldVersion)) break;
  }
  if (versions_.empty() || state.fieldVersion > versions_.back().first) {
    versions_.emplace_back(state.fieldVersion, state.publishTime);
    if (versions_.size() > kMaxVersions) versions_.pop_front();
  }
  resolvePending(now);
}

std::optional<double> Client::publishTime(std::uint64_t version) const {
  auto it = std::lower_bound(versions_.begin(), versions_.end(), version,
                             [](const auto& e, std::uint64_t v) { return e.first < v; });
  if (it == versions_.end() || it->first != version) return std::nullopt;
  return it->second + (o_.sameClock ? 0.0 : clockOffset_.value_or(0.0));
}

void Client::recordLatency(std::uint64_t version, double appliedAt) {
  if (auto published = publishTime(version)) {
    addLatency(appliedAt, *published);
  } else if (pending_.size() < 4096) {
    pending_.emplace_back(version, appliedAt);
  }
}

void Client::resolvePending(double now) {
  std::erase_if(pending_, [&](const std::pair<std::uint64_t, double>& p) {
    if (auto published = publishTime(p.first)) {
      addLatency(p.second, *published);
      return true;
    }
    if (now - p.second > kPendingSeconds) {
      if (inWindow(p.second)) ++window_.unmatched;
      return true;
    }
    return false;
  });
}

// One datagram the session handled (its layout had arrived): the gap since the previous one,
// its error, and the bricks it changed, whose latency is measured from here.
void Client::onDatagram(const Status& status, double now) {
  if (inWindow(now)) window_.maxGap = std::max(window_.maxGap, now - lastDatagramAt_);
  interval_.maxGap = std::max(interval_.maxGap, now - lastDatagramAt_);
  lastDatagramAt_ = now;
  ++window_.datagrams;
  if (!status) addError(status.error().message);
  const StreamReceiver& receiver = *session_.receiver();
  const std::uint64_t applied = receiver.stats().applied;
  if (applied == lastApplied_) return;
  window_.applied += applied - lastApplied_;
  lastApplied_ = applied;
  for (auto [k, b] : session_.takeChangedBricks()) {
    const std::uint64_t version = receiver.brickVersion(k, b);
    maxHeld_ = std::max(maxHeld_, version);
    // Versions up to the one at join were published before the session: initial sync.
    if (version > infoVersion_) recordLatency(version, now);
  }
  noteSynced();
}

void Client::noteSynced() {
  if (synced_ || !session_.synced()) return;
  synced_ = true;
  ++gen_.synced;
  syncSeconds_ = session_.syncSeconds();
}

// How long the client has been behind: since the publish of the oldest announced field
// version newer than every brick it holds (0 when it holds the newest). Sampled once synced.
void Client::sampleStaleness(double now) {
  lastStaleSampleAt_ = now;
  if (!synced_) return;
  auto it = std::upper_bound(versions_.begin(), versions_.end(), maxHeld_,
                             [](std::uint64_t v, const auto& e) { return v < e.first; });
  double staleness = 0;
  if (it != versions_.end()) {
    const double offset = o_.sameClock ? 0.0 : clockOffset_.value_or(0.0);
    staleness = std::max(0.0, now - (it->second + offset));
  }
  interval_.stalenessMs.push_back(float(staleness * 1e3));
  if (!inWindow(now)) return;
  window_.stalenessMs.push_back(float(staleness * 1e3));
  window_.maxStaleness = std::max(window_.maxStaleness, staleness);
}

// A slow loop through the first cascade's volume, each client at its own phase; the session
// sends it.
void Client::simulateViewer(double now) {
  const gpu::CascadeDesc& c = session_.receiver()->field().desc.cascades[0];
  const glm::vec3 lo = c.origin;
  const glm::vec3 size = c.spacing * glm::vec3(c.counts - 1);
  const double a = posePhase_ + 6.283185307179586 * now / o_.posePeriod;
  const glm::vec3 unit(0.5f + 0.35f * float(std::cos(a)), 0.5f + 0.15f * float(std::sin(2 * a)),
                       0.5f + 0.35f * float(std::sin(a)));
  session_.setViewer(lo + unit * size, glm::angleAxis(float(-a), glm::vec3(0, 1, 0)));
}

void Client::send(Bytes f) {
  if (state_ != State::Connecting && state_ != State::Session) return;
  if (queuedBytes_ + f.size() > kMaxClientQueuedBytes)
    return endSession(nowSeconds(), "server not reading");
  queuedBytes_ += f.size();
  window_.bytesUp += f.size();
  writes_.push_back(std::move(f));
  if (!writing_) writeNext();
}

void Client::sendUplink() {
  const udp::endpoint to(gen_.endpoints[endpoint_].address(), session_.uplinkPort());
  for (const Bytes& d : session_.takeUplinkDatagrams()) {
    // Non-blocking: a datagram the socket cannot take now is lost, as on the way; the next
    // ack repeats what it said.
    boost::system::error_code ec;
    udp_.send_to(asio::buffer(d), to, 0, ec);
    if (!ec) window_.bytesUp += d.size();
  }
}

void Client::writeNext() {
  writing_ = true;
  const std::uint64_t id = connection_;
  asio::async_write(*stream_, asio::buffer(writes_.front()),
                    [this, id, st = stream_](boost::system::error_code ec, std::size_t) {
                      if (id != connection_ || worker_.stopping) return;
                      if (ec) return endSession(nowSeconds(), "write: " + ec.message());
                      queuedBytes_ -= writes_.front().size();
                      writes_.pop_front();
                      if (writes_.empty()) {
                        writing_ = false;
                      } else {
                        writeNext();
                      }
                    });
}

void Client::beginWindow(double now) {
  window_ = Window{};
  window_.start = now;
}

ClientReport Client::report(double now, std::vector<float>& latency, std::vector<float>& staleness,
                            std::uint64_t& unmatched) {
  ClientReport r;
  r.index = index_;
  const double seconds = std::max(1e-9, now - window_.start);
  r.sessions = window_.sessions;
  r.sessionSeconds = window_.sessionSeconds;
  double gap = window_.maxGap;
  if (state_ == State::Session) {
    r.sessionSeconds += now - std::max(sessionStartedAt_, window_.start);
    gap = std::max(gap, now - std::max(lastDatagramAt_, window_.start));
  }
  r.bytesDown = window_.bytesDown;
  r.bytesUp = window_.bytesUp;
  r.kbitDown = double(window_.bytesDown) * 8 / 1e3 / seconds;
  r.kbitUp = double(window_.bytesUp) * 8 / 1e3 / seconds;
  r.datagrams = window_.datagrams;
  r.bricksApplied = window_.applied;
  r.repairBricks = window_.repairs;
  r.gapReports = window_.gapReports;
  r.staleUpdates = window_.stale;
  r.errors = window_.errors;
  r.maxDatagramGap = gap;
  r.maxStaleness = window_.maxStaleness;
  r.syncSeconds = syncSeconds_;
  r.lastError = window_.lastError;
  r.linkClass = linkClass_;
  r.linkMbit = linkRate_ * 8.0 / 1e6;
  r.linkDrops = window_.linkDrops;
  r.reports = window_.reports;
  if (window_.reports > 0) {
    const double mse = window_.heldSquares / double(window_.reports);
    r.heldPsnrDb = mse > 0 ? -10.0 * std::log10(mse) : 99.0;
    std::vector<float> ages = window_.oldestChange;
    r.oldestChangeP95 = percentiles(ages).p95;
    r.rateMbit = window_.rateSum / double(window_.reports) * 8.0 / 1e6;
    r.qualityLevel = window_.levelSum / double(window_.reports);
  }
  if (gap > o_.starveSeconds) {
    r.starved = true;
    r.starvedWhy = "no datagram for " + std::to_string(gap) + " s";
  } else if (window_.maxStaleness > o_.starveSeconds) {
    r.starved = true;
    r.starvedWhy =
        "behind the newest field version for " + std::to_string(window_.maxStaleness) + " s";
  } else if (r.reports > 0 && r.heldPsnrDb < o_.minHeldPsnr) {
    r.starved = true;
    r.starvedWhy = "held field at " + std::to_string(r.heldPsnrDb) + " dB against the current one";
  } else if (r.reports > 0 && r.oldestChangeP95 > o_.maxChangeAge) {
    r.starved = true;
    r.starvedWhy = "changes " + std::to_string(r.oldestChangeP95) + " s old not held (p95)";
  } else if (state_ == State::Session && !synced_ &&
             now - sessionStartedAt_ > o_.starveSeconds + o_.syncLimit) {
    r.starved = true;
    r.starvedWhy =
        "not every brick held " + std::to_string(now - sessionStartedAt_) + " s into the session";
  }
  std::vector<float> own = window_.latencyMs;
  r.latencyMs = percentiles(own);
  latency.insert(latency.end(), window_.latencyMs.begin(), window_.latencyMs.end());
  staleness.insert(staleness.end(), window_.stalenessMs.begin(), window_.stalenessMs.end());
  unmatched += window_.unmatched;
  return r;
}

void Client::takeInterval(LoadInterval& sums, std::vector<float>& latency,
                          std::vector<float>& staleness, std::vector<float>& ages,
                          std::vector<float>& psnr) {
  sums.bytesDown += interval_.bytesDown;
  sums.errors += interval_.errors;
  sums.gapReports += interval_.gapReports;
  // A session still waiting for its next datagram: the wait so far counts as a gap.
  double gap = interval_.maxGap;
  if (state_ == State::Session) gap = std::max(gap, nowSeconds() - lastDatagramAt_);
  sums.maxGapSeconds = std::max(sums.maxGapSeconds, gap);
  sums.inSession += state_ == State::Session;
  sums.synced += synced_;
  latency.insert(latency.end(), interval_.latencyMs.begin(), interval_.latencyMs.end());
  staleness.insert(staleness.end(), interval_.stalenessMs.begin(), interval_.stalenessMs.end());
  ages.insert(ages.end(), interval_.oldestChange.begin(), interval_.oldestChange.end());
  if (interval_.reports > 0) {
    const double mse = interval_.heldSquares / double(interval_.reports);
    psnr.push_back(
        float(mse > 0 ? -10.0 * std::log10(mse) : 99.0));  // the server's cap: equal fields
  }
  interval_ = Interval{};
}

void LoadGenerator::Impl::scheduleTick(Worker& w) {
  w.timer.expires_after(std::chrono::duration_cast<asio::steady_timer::duration>(
      std::chrono::duration<double>(options.pollInterval)));
  w.timer.async_wait([this, &w](boost::system::error_code ec) {
    if (ec || w.stopping) return;
    const double now = nowSeconds();
    for (auto& c : w.clients) c->tick(now);
    scheduleTick(w);
  });
}

void LoadGenerator::Impl::onEveryWorker(const std::function<void(Worker&)>& fn) {
  if (!running) {
    for (auto& w : workers) fn(*w);
    return;
  }
  std::vector<std::future<void>> done;
  for (auto& w : workers) {
    auto task = std::make_shared<std::packaged_task<void()>>([&fn, &w] { fn(*w); });
    done.push_back(task->get_future());
    asio::post(w->io, [task] { (*task)(); });
  }
  for (auto& f : done) f.get();
}

Percentiles percentiles(std::vector<float>& samples) {
  Percentiles p;
  p.count = samples.size();
  if (samples.empty()) return p;
  auto at = [&](double q) {
    const std::size_t i = std::min(samples.size() - 1, std::size_t(q * double(samples.size())));
    std::nth_element(samples.begin(), samples.begin() + std::ptrdiff_t(i), samples.end());
    return double(samples[i]);
  };
  p.p50 = at(0.50);
  p.p95 = at(0.95);
  p.p99 = at(0.99);
  p.max = *std::max_element(samples.begin(), samples.end());
  double sum = 0;
  for (float s : samples) sum += s;
  p.mean = sum / double(samples.size());
  return p;
}

LoadInterval LoadGenerator::Impl::takeInterval() {
  const double now = nowSeconds();
  LoadInterval r;
  r.seconds = std::max(1e-9, now - intervalStart);
  intervalStart = now;
  std::vector<float> latency, staleness, ages, psnr;
  std::mutex merge;
  onEveryWorker([&](Worker& w) {
    LoadInterval sums;
    std::vector<float> lat, stale, age, held;
    for (auto& c : w.clients) c->takeInterval(sums, lat, stale, age, held);
    std::lock_guard lock(merge);
    r.inSession += sums.inSession;
    r.synced += sums.synced;
    r.bytesDown += sums.bytesDown;
    r.errors += sums.errors;
    r.gapReports += sums.gapReports;
    r.maxGapSeconds = std::max(r.maxGapSeconds, sums.maxGapSeconds);
    latency.insert(latency.end(), lat.begin(), lat.end());
    staleness.insert(staleness.end(), stale.begin(), stale.end());
    ages.insert(ages.end(), age.begin(), age.end());
    psnr.insert(psnr.end(), held.begin(), held.end());
  });
  r.latencyMs = percentiles(latency);
  r.stalenessMs = percentiles(staleness);
  r.changeAgeS = percentiles(ages);
  r.reports = !psnr.empty();
  if (r.reports) {
    std::sort(psnr.begin(), psnr.end());
    r.heldPsnrP5 = psnr[std::size_t(0.05 * double(psnr.size() - 1))];
  }
  return r;
}

std::vector<double> LoadInterval::seriesRow(double time) const {
  const double none = std::numeric_limits<double>::quiet_NaN();
  const double kbit = double(bytesDown) * 8 / 1e3 / seconds;
  const auto p = [none](const Percentiles& q, double v) { return q.count > 0 ? v : none; };
  return {time,
          double(inSession),
          double(synced),
          kbit,
          inSession > 0 ? kbit / inSession : none,
          p(latencyMs, latencyMs.p50),
          p(latencyMs, latencyMs.p95),
          p(latencyMs, latencyMs.p99),
          p(stalenessMs, stalenessMs.p95),
          p(changeAgeS, changeAgeS.p95),
          inSession > 0 ? maxGapSeconds * 1e3 : none,
          double(gapReports),
          reports ? heldPsnrP5 : none,
          double(errors)};
}

LoadGenerator::LoadGenerator(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

LoadGenerator::~LoadGenerator() { stop(); }

Result<std::unique_ptr<LoadGenerator>> LoadGenerator::create(LoadOptions options) {
  if (options.clients < 1) return Error{"clients: at least 1"};
  if (options.threads < 1) return Error{"threads: at least 1"};
  if (options.pollInterval <= 0 || options.poseInterval <= 0 || options.posePeriod <= 0)
    return Error{"poll interval, pose interval and pose period must be positive"};
  auto impl = std::make_unique<Impl>(std::move(options));
  Impl& g = *impl;
  // Resolved once: a thousand clients never ask the resolver a thousand times.
  std::vector<net::LoadEndpoint> all{{g.options.host, g.options.port}};
  for (const auto& [host, port] : g.options.alternates) all.push_back({host, port});
  g.probed = net::resolveEndpoints(all);
  for (std::size_t i = 0; i < all.size(); ++i) {
    if (std::none_of(g.probed.begin(), g.probed.end(),
                     [&](const net::ProbedEndpoint& p) { return p.given == i; }))
      return Error{"resolve " + all[i].host + ": no address"};
  }
  for (const net::ProbedEndpoint& p : g.probed) {
    boost::system::error_code ec;
    g.endpoints.emplace_back(asio::ip::make_address(p.address, ec), p.port);
    g.hosts.push_back(p.host);
  }
  g.inSessionAt = std::make_unique<std::atomic<int>[]>(g.endpoints.size());
  g.openedSinceProbe.assign(g.endpoints.size(), 0);
  if (g.options.tls) {
    net::TlsClientSettings settings;
    settings.pinnedFingerprint = g.options.serverFingerprint;
    settings.caFile = g.options.caFile;
    auto tls = net::TlsClient::create(settings);
    if (!tls) return Error{"TLS: " + tls.error().message};
    g.tls = *tls;
  }
  if (g.options.shareDecoding) g.decoder = std::make_unique<SharedBrickDecoder>();
  if (!g.options.seriesPath.empty()) {
    auto series = SeriesWriter::create(g.options.seriesPath, kSeriesColumns);
    if (!series) return series.error();
    g.series = std::move(series).value();
  }
  for (int t = 0; t < g.options.threads; ++t) g.workers.push_back(std::make_unique<Worker>());
  return std::unique_ptr<LoadGenerator>(new LoadGenerator(std::move(impl)));
}

void LoadGenerator::start() {
  Impl& g = *impl_;
  if (g.running) return;
  // The first clients choose from fresh figures.
  if (g.endpoints.size() > 1 && g.options.loadProbeInterval > 0) {
    g.probeLoads();
    g.prober = std::thread([&g] {
      std::unique_lock lock(g.loadMutex);
      while (!g.proberStop) {
        g.proberWake.wait_for(lock, std::chrono::duration<double>(g.options.loadProbeInterval));
        if (g.proberStop) break;
        lock.unlock();
        g.probeLoads();
        lock.lock();
      }
    });
  }
  const double now = nowSeconds();
  g.windowStart = g.startedAt = g.intervalStart = now;
  for (int i = 0; i < g.options.clients; ++i) {
    Worker& w = *g.workers[std::size_t(i) % g.workers.size()];
    const double at = now + g.options.rampSeconds * double(i) / double(g.options.clients);
    w.clients.push_back(std::make_unique<Client>(g, w, i, at));
    w.clients.back()->beginWindow(now);
  }
  for (auto& w : g.workers) {
    g.scheduleTick(*w);
    w->thread = std::thread([&w = *w] { w.io.run(); });
  }
  g.running = true;
  if (g.series) g.seriesThread = std::thread([&g] { g.writeSeries(); });
}

void LoadGenerator::stop() {
  Impl& g = *impl_;
  if (!g.running) return;
  if (g.seriesThread.joinable()) {
    {
      std::lock_guard lock(g.seriesMutex);
      g.seriesStop = true;
    }
    g.seriesWake.notify_all();
    g.seriesThread.join();
  }
  for (auto& w : g.workers) {
    asio::post(w->io, [&w = *w] {
      for (auto& c : w.clients) c->shutdown();
      w.stopping = true;
      w.timer.cancel();
    });
  }
  for (auto& w : g.workers) w->thread.join();
  if (g.prober.joinable()) {
    {
      std::lock_guard lock(g.loadMutex);
      g.proberStop = true;
    }
    g.proberWake.notify_all();
    g.prober.join();
  }
  g.running = false;
}

void LoadGenerator::Impl::probeLoads() {
  std::vector<net::ProbedEndpoint> fresh;
  {
    std::lock_guard lock(loadMutex);
    fresh = probed;
  }
  net::probeLoads(fresh, options.loadProbeTimeout);
  std::lock_guard lock(loadMutex);
  probed = std::move(fresh);
  std::fill(openedSinceProbe.begin(), openedSinceProbe.end(), 0);
}

std::size_t LoadGenerator::Impl::pickEndpoint(const std::string& avoid) {
  if (endpoints.size() == 1) return 0;
  std::lock_guard lock(loadMutex);
  const std::size_t i = net::chooseEndpoint(probed, avoid, openedSinceProbe).value_or(0);
  ++openedSinceProbe[i];
  return i;
}

void LoadGenerator::beginWindow() {
  Impl& g = *impl_;
  const double now = nowSeconds();
  g.windowStart = now;
  g.onEveryWorker([now](Worker& w) {
    for (auto& c : w.clients) c->beginWindow(now);
  });
}

LoadReport LoadGenerator::report() {
  Impl& g = *impl_;
  const double now = nowSeconds();
  LoadReport r;
  r.options = g.options;
  r.seconds = now - g.windowStart;
  r.clients = g.options.clients;
  std::vector<float> latency, staleness;
  // Latencies per link class (index + 1; 0: no emulated link).
  std::vector<std::vector<float>> classLatency(g.options.links.size() + 1);
  std::uint64_t unmatched = 0;
  std::mutex merge;
  g.onEveryWorker([&](Worker& w) {
    std::vector<float> lat, stale;
    std::vector<ClientReport> reports;
    std::vector<std::pair<int, std::vector<float>>> own;
    std::uint64_t um = 0;
    for (auto& c : w.clients) {
      std::vector<float> mine;
      reports.push_back(c->report(now, mine, stale, um));
      lat.insert(lat.end(), mine.begin(), mine.end());
      own.emplace_back(c->linkClass() + 1, std::move(mine));
    }
    std::lock_guard lock(merge);
    for (auto& [k, v] : own)
      classLatency[std::size_t(k)].insert(classLatency[std::size_t(k)].end(), v.begin(), v.end());
    latency.insert(latency.end(), lat.begin(), lat.end());
    staleness.insert(staleness.end(), stale.begin(), stale.end());
    unmatched += um;
    for (ClientReport& c : reports) r.perClient.push_back(std::move(c));
  });
  std::sort(r.perClient.begin(), r.perClient.end(),
            [](const ClientReport& a, const ClientReport& b) { return a.index < b.index; });
  r.latencyMs = percentiles(latency);
  r.stalenessMs = percentiles(staleness);
  r.unmatchedUpdates = unmatched;
  std::vector<float> kbit;
  for (const ClientReport& c : r.perClient) {
    kbit.push_back(float(c.kbitDown));
    r.bricksApplied += c.bricksApplied;
    r.repairBricks += c.repairBricks;
    r.gapReports += c.gapReports;
    r.datagrams += c.datagrams;
    r.errors += c.errors;
    r.sessionsStarted += c.sessions;
    r.starvedClients += c.starved;
  }
  r.kbitPerClient = percentiles(kbit);
  // Per class, and for all clients together.
  const auto summarize = [&](int linkClass, std::vector<float> lat) {
    ClassReport c;
    std::vector<float> kb, psnr, ages;
    std::uint64_t drops = 0, reached = 0;
    double rate = 0;
    for (const ClientReport& p : r.perClient) {
      if (linkClass >= -1 && p.linkClass != linkClass) continue;
      ++c.clients;
      c.starved += p.starved;
      kb.push_back(float(p.kbitDown));
      if (p.reports > 0) {
        psnr.push_back(float(p.heldPsnrDb));
        ages.push_back(float(p.oldestChangeP95));
      }
      drops += p.linkDrops;
      reached += p.linkDrops + p.datagrams;
      rate += p.rateMbit;
      c.linkMbit = p.linkMbit;
    }
    c.latencyMs = percentiles(lat);
    c.kbitPerClient = percentiles(kb);
    // p5 over clients: the worst twentieth's held field.
    if (!psnr.empty()) {
      std::sort(psnr.begin(), psnr.end());
      c.heldPsnrP5 = psnr[std::size_t(0.05 * double(psnr.size() - 1))];
    }
    c.oldestChangeP95 = percentiles(ages).p95;
    c.linkDropShare = reached > 0 ? double(drops) / double(reached) : 0.0;
    c.rateMbitMean = c.clients > 0 ? rate / c.clients : 0.0;
    return c;
  };
  r.all = summarize(-2, latency);
  r.all.linkMbit = 0;
  for (std::size_t i = 0; i < g.options.links.size(); ++i)
    r.classes.push_back(summarize(int(i), classLatency[i + 1]));
  r.sessionsEnded = g.sessionsEnded.load();
  if (g.decoder) {
    const SharedBrickDecoder::Stats d = g.decoder->stats();
    r.decodedPayloads = d.decoded;
    r.sharedDecodes = d.shared;
    r.contentMismatches = d.mismatches;
    r.errors += d.mismatches;
  }
  r.residentMb = residentMb();
  std::lock_guard lock(g.mutex);
  r.decodedFieldMb = g.decodedFieldMb;
  r.brickCodesMb = g.brickCodesMb;
  r.errorSamples = g.errorSamples;
  return r;
}

LoadInterval LoadGenerator::takeInterval() { return impl_->takeInterval(); }

LoadSnapshot LoadGenerator::snapshot() const {
  const Impl& g = *impl_;
  LoadSnapshot s;
  s.clients = g.options.clients;
  s.inSession = g.inSession.load();
  s.synced = g.synced.load();
  s.sessionsStarted = g.sessionsStarted.load();
  s.sessionsEnded = g.sessionsEnded.load();
  s.errors = g.errors.load();
  s.newestFieldVersion = g.newestFieldVersion.load();
  for (std::size_t i = 0; i < g.endpoints.size(); ++i) {
    const tcp::endpoint& e = g.endpoints[i];
    s.perEndpoint.emplace_back(e.address().to_string() + ":" + std::to_string(e.port()),
                               g.inSessionAt[i].load());
  }
  return s;
}

}  // namespace pc::load
