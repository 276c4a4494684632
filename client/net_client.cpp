#include "net_client.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <boost/asio.hpp>
#include <chrono>
#include <deque>
#include <mutex>
#include <thread>
#include <utility>

#include "common/log.h"
#include "net/load_probe.h"
#include "net/session_stream.h"
#include "protocol/client_session.h"
#include "update_latency.h"

namespace pc::client {

namespace asio = boost::asio;
using asio::ip::tcp;
using asio::ip::udp;
using Bytes = std::vector<std::uint8_t>;

double netClockSeconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

namespace {

asio::steady_timer::duration toDuration(double seconds) {
  return std::chrono::duration_cast<asio::steady_timer::duration>(
      std::chrono::duration<double>(std::max(0.0, seconds)));
}

// Mirror versions are the client's own, increasing across sessions: a restarted server counts
// its brick versions from the start again, and the mirror only takes newer versions. Baked
// fallback files carry versions far below this.
constexpr std::uint64_t kFirstMirrorVersion = std::uint64_t(1) << 40;

ClientSessionOptions sessionOptions(const NetClientOptions& o) {
  ClientSessionOptions s;
  s.token = o.token;
  s.name = o.name;
  s.connectTimeout = o.connectTimeout;
  s.silenceTimeout = o.silenceTimeout;
  s.poseInterval = o.poseInterval;
  s.maxMirrorBytes = o.maxMirrorBytes;
  s.uplinkDatagrams = !o.tcpOnly;
  s.resume = o.resume;
  s.receiver = o.receiver;
  return s;
}

}  // namespace

// The sockets, the timers and the hand-off to the mirror; every rule of the session is the
// ClientSession's.
struct NetClient::Impl {
  Impl(FieldMirror& m, NetClientOptions o)
      : mirror(m),
        options(std::move(o)),
        session(sessionOptions(options)),
        udpSocket(io),
        pollTimer(io),
        retryTimer(io),
        resolver(io) {}

  // Network thread only.
  void connect();
  void onConnected(std::uint64_t id);
  void onHandshake(std::uint64_t id);
  void fail(const std::string& why);
  void readStream();
  void receiveUdp();
  void afterInput(double now);
  void onLayout(double now);
  void schedulePoll();
  void poll();
  void send(Bytes frame);
  // Acks and repair requests as datagrams to the server's UDP port (ClientSession decides).
  void sendUplink();
  void writeNext();
  // Writes a line about the connection unless the budget for such lines is spent.
  void logConnection(LogLevel level, const std::string& line);

  FieldMirror& mirror;
  NetClientOptions options;
  ClientSession session;
  asio::io_context io;
  // One stream per connection; every operation on it holds it, so a closed stream outlives
  // the handlers still to run.
  std::shared_ptr<net::SessionStream> stream;
  std::shared_ptr<net::TlsClient> tls;  // TLS settings, parsed once (start())
  udp::socket udpSocket;
  asio::steady_timer pollTimer, retryTimer;
  tcp::resolver resolver;
  std::thread thread;
  std::atomic<bool> stopping{false};
  std::uint16_t udpPortNumber = 0;  // set before the thread starts

  // Connection state (network thread).
  std::uint64_t connection = 0;  // bumps per connection: handlers of an old one do nothing
  bool tcpOpen = false;
  double backoff = 0;
  // Where the next connection goes: every address of every endpoint given, asked for its load
  // before each connection where there is more than one (net/load_probe.h), the least loaded
  // taken; the one that just failed (`avoid`) goes after the others of its class.
  std::string current, avoid;  // address:port of the current (latest) and the failed endpoint
  NetEndpoint chooseEndpoint(std::string& connectTo);
  std::array<std::uint8_t, 16 * 1024> readBuffer{};
  std::array<std::uint8_t, 2048> udpBuffer{};
  udp::endpoint udpFrom;
  asio::ip::address serverAddress;  // the TCP session's peer: datagrams must come from it
  LogBudget logBudget{5, 10.0};     // lines about the connection: 5 every 10 s at most
  std::deque<Bytes> writes;
  std::size_t queuedBytes = 0;
  bool writing = false;
  std::uint64_t mirrorVersion = kFirstMirrorVersion;
  UpdateLatency latency;

  // Shared with the frame thread.
  mutable std::mutex mutex;
  NetClientStats stats;
  std::optional<ViewerPoseMsg> viewer;
  AnimationClock clock;               // the session's, copied as scene states arrive
  std::vector<float> latencySamples;  // UpdateLatency's, until takeLatencySamples
  std::uint64_t layoutGeneration = 0;
  std::optional<SceneStateMsg> editedScene;  // the session's, as scene states arrive
  std::vector<EditMsg> editsToSend;          // until the next poll
  std::vector<EditResultMsg> editResults;    // until takeEditResults
  std::vector<EditArrival> editArrivals;     // until takeEditArrivals
  std::uint64_t newestEditVersion = 0;
};

void NetClient::Impl::connect() {
  if (stopping) return;
  const std::uint64_t id = ++connection;
  session.connecting(netClockSeconds());
  {
    std::lock_guard lock(mutex);
    stats.connectAttempts = session.stats().connectAttempts;
  }
  if (options.tls && !tls) return fail("TLS is not set up");
  stream = tls ? std::make_shared<net::SessionStream>(tcp::socket(io), tls->context())
               : std::make_shared<net::SessionStream>(tcp::socket(io));
  std::string address;  // what to connect to: a numeric address, or the name to resolve
  const NetEndpoint to = chooseEndpoint(address);
  {
    std::lock_guard lock(mutex);
    stats.endpoint = to.host + ":" + std::to_string(to.port);
  }
  if (tls) {
    if (Status s = tls->prepare(*stream->tlsStream(), to.host); !s) return fail(s.error().message);
  }
  resolver.async_resolve(address, std::to_string(to.port),
                         [this, id, st = stream, host = to.host](
                             boost::system::error_code ec, tcp::resolver::results_type results) {
                           if (id != connection || stopping) return;
                           if (ec) return fail("resolve " + host + ": " + ec.message());
                           asio::async_connect(st->socket(), results,
                                               [this, id, st](boost::system::error_code ec2,
                                                              const tcp::endpoint& server) {
                                                 if (id != connection || stopping) return;
                                                 if (ec2) return fail("connect: " + ec2.message());
                                                 serverAddress = server.address();
                                                 onConnected(id);
                                               });
                         });
}

NetEndpoint NetClient::Impl::chooseEndpoint(std::string& connectTo) {
  std::vector<net::LoadEndpoint> given{{options.host, options.port}};
  for (const NetEndpoint& e : options.alternates) given.push_back({e.host, e.port});
  std::vector<net::ProbedEndpoint> candidates = net::resolveEndpoints(given);
  if (candidates.empty()) {  // nothing resolves now: the first, whose resolve error is logged
    connectTo = options.host;
    return NetEndpoint{options.host, options.port};
  }
  if (candidates.size() > 1 && options.loadProbeTimeout > 0)
    net::probeLoads(candidates, options.loadProbeTimeout);
  const net::ProbedEndpoint& chosen = candidates[*net::chooseEndpoint(candidates, avoid)];
  if (!current.empty() && chosen.key() != current) {
    std::lock_guard lock(mutex);
    ++stats.endpointSwitches;
  }
  current = chosen.key();
  avoid.clear();
  connectTo = chosen.address;
  return NetEndpoint{chosen.host, chosen.port};
}

void NetClient::Impl::onConnected(std::uint64_t id) {
  boost::system::error_code ignored;
  stream->socket().set_option(tcp::no_delay(true), ignored);
  stream->asyncHandshake(net::ssl::stream_base::client,
                         [this, id, st = stream](boost::system::error_code ec) {
                           if (id != connection || stopping) return;
                           if (ec) return fail("TLS handshake: " + ec.message());
                           onHandshake(id);
                         });
}

void NetClient::Impl::onHandshake(std::uint64_t) {
  if (stream->tls()) {
    auto secret = stream->datagramSecret();
    if (!secret) return fail(secret.error().message);
    session.setDatagramKeys(deriveDatagramKeys(*secret));
  }
  tcpOpen = true;
  const std::uint16_t udpPort = options.tcpOnly            ? 0
                                : options.udpAdvertisePort ? options.udpAdvertisePort
                                                           : udpPortNumber;
  send(session.connected(netClockSeconds(), udpPort));
  readStream();
}

// Ends the connection (if any) and tries again after the backoff. The mirror keeps what it
// holds: the frame loop goes on rendering it.
void NetClient::Impl::fail(const std::string& why) {
  ++connection;
  const bool wasConnected = session.receiver() != nullptr;
  // A rejected client keeps trying at the slowest pace: the token may be fixed server-side.
  const bool rejected = session.phase() == SessionPhase::Rejected;
  if (stream) stream->close();
  tcpOpen = false;
  session.close();
  writes.clear();
  queuedBytes = 0;
  writing = false;
  if (wasConnected) backoff = options.backoffInitial;
  if (rejected) backoff = options.backoffMax;
  {
    std::lock_guard lock(mutex);
    if (stats.lastError != why || wasConnected)
      logConnection(LogLevel::Warn, "server " + stats.endpoint + ": " + why);
    stats.lastError = why;
    stats.connected = false;
    stats.synced = false;
  }
  if (stopping) return;
  // With several endpoints serving the field, the next connection goes to the least loaded
  // live one: a relay that died is left at once (after the short first backoff), and one that
  // refuses is not asked again first.
  avoid = current;
  const double wait = backoff;
  backoff = std::min(options.backoffMax, std::max(options.backoffInitial, backoff * 2));
  retryTimer.expires_after(toDuration(wait));
  retryTimer.async_wait([this](boost::system::error_code e) {
    if (!e && !stopping) connect();
  });
}

void NetClient::Impl::readStream() {
  const std::uint64_t id = connection;
  stream->async_read_some(
      asio::buffer(readBuffer),
      [this, id, st = stream](boost::system::error_code ec, std::size_t n) {
        if (id != connection || stopping) return;
        // A server that closes without TLS's close_notify ends the stream "truncated".
        if (ec) {
          const bool closed = ec == asio::error::eof || ec == net::ssl::error::stream_truncated;
          return fail(closed ? "connection closed" : "read: " + ec.message());
        }
        const double now = netClockSeconds();
        Status status = session.onStreamBytes(std::span(readBuffer.data(), n), now);
        afterInput(now);
        if (!status) return fail(status.error().message);
        if (id == connection) readStream();
      });
}

void NetClient::Impl::receiveUdp() {
  auto onReceived = [this](boost::system::error_code ec, std::size_t n) {
    if (stopping) return;
    // Errors on a UDP socket (an ICMP unreachable from an earlier send, a truncated read) are
    // per datagram: keep receiving.
    if (!ec && n <= kMaxDatagramBytes + kSealOverheadBytes) {
      const double now = netClockSeconds();
      const DatagramSource source{tcpOpen && udpFrom.address() == serverAddress, udpFrom.port()};
      (void)session.onDatagram(std::span(udpBuffer.data(), n), now, source);
      afterInput(now);
    }
    receiveUdp();
  };
  udpSocket.async_receive_from(asio::buffer(udpBuffer), udpFrom, onReceived);
}

// What the session made of the bytes: a new layout for the mirror, the clock for the frame
// loop, and the counters.
void NetClient::Impl::afterInput(double now) {
  bool clockChanged = false;
  std::vector<EditResultMsg> results;
  for (const SessionEvent& e : session.events()) {
    if (e.kind == SessionEvent::Kind::Layout) onLayout(now);
    if (e.kind == SessionEvent::Kind::SceneState)
      latency.published(e.scene.fieldVersion, e.scene.publishTime, now);
    if (e.kind == SessionEvent::Kind::EditResult) results.push_back(e.edit);
    clockChanged |= e.kind == SessionEvent::Kind::SceneState;
  }
  const ClientSessionStats& s = session.stats();
  std::lock_guard lock(mutex);
  if (clockChanged) {
    clock = session.clock();
    editedScene = session.editedScene();
    if (editedScene && editedScene->editVersion > newestEditVersion) {
      newestEditVersion = editedScene->editVersion;
      if (editArrivals.size() < kMaxKeptEditEvents)
        editArrivals.push_back({newestEditVersion, now});
    }
  }
  for (EditResultMsg& r : results) {
    if (editResults.size() < kMaxKeptEditEvents) editResults.push_back(std::move(r));
  }
  stats.connectAttempts = s.connectAttempts;
  stats.rejects = s.rejects;
  stats.tcpBytes = s.tcpBytes;
  stats.udpBytes = s.udpBytes;
  stats.udpDatagrams = s.udpDatagrams;
  stats.tcpDatagrams = s.tcpDatagrams;
  stats.badDatagrams = s.badDatagrams;
  stats.unsealedRefused = s.unsealedRefused;
  stats.foreignDatagrams = s.foreignDatagrams;
}

void NetClient::Impl::onLayout(double now) {
  const Field& layout = session.receiver()->field();
  const std::optional<gpu::FieldDesc> current = mirror.desc();
  if (!current || !sameLayout(*current, layout.desc)) {
    // The baked fallback (if any) is for another layout: its tiles would land in the wrong
    // places. Start from the empty field; the stream fills it.
    mirror.reset(layout, now);
    std::lock_guard lock(mutex);
    ++stats.layoutResets;
    ++layoutGeneration;
  }
  backoff = options.backoffInitial;
  latency.startSession(session.receiver()->serverFieldVersion());
  std::lock_guard lock(mutex);
  stats.heldFieldVersion = 0;
  stats.sessions = session.stats().sessions;
  stats.connected = true;
  stats.synced = false;
  stats.bricksHeld = 0;
  stats.bricksTotal = session.bricksTotal();
  stats.lastError.clear();
  logConnection(LogLevel::Info, "connected to " + stats.endpoint + ", session " +
                                    std::to_string(session.sessionId()) + ", " +
                                    std::to_string(session.bricksTotal()) + " bricks" +
                                    (options.tcpOnly ? " (TCP only)" : ""));
}

// Called with `mutex` held.
void NetClient::Impl::logConnection(LogLevel level, const std::string& line) {
  if (!logBudget.take(netClockSeconds())) {
    ++stats.suppressedLogLines;
    return;
  }
  const std::uint64_t left = logBudget.takeSuppressed();
  log(level,
      left == 0 ? line : line + " (" + std::to_string(left) + " lines like it left out before)");
}

void NetClient::Impl::schedulePoll() {
  pollTimer.expires_after(toDuration(options.pollInterval));
  pollTimer.async_wait([this](boost::system::error_code ec) {
    if (ec || stopping) return;
    poll();
    schedulePoll();
  });
}

void NetClient::Impl::poll() {
  const double now = netClockSeconds();
  {
    std::lock_guard lock(mutex);
    if (viewer) session.setViewer(viewer->position, viewer->orientation);
    for (const EditMsg& edit : std::exchange(editsToSend, {})) {
      // Refused here (no session, an older server): the caller hears it as the server's
      // answer would come.
      if (Status sent = session.sendEdit(edit); !sent && editResults.size() < kMaxKeptEditEvents)
        editResults.push_back(EditResultMsg{edit.editId, false, sent.error().message, 0, 0});
    }
  }
  auto frames = session.poll(now);
  if (!frames) return fail(frames.error().message);
  for (Bytes& f : *frames) send(std::move(f));
  if (!tcpOpen || !session.streaming()) return;  // send() may have failed the connection
  sendUplink();

  // Hand changed bricks to the mirror: the frame loop uploads them on its own schedule.
  const StreamReceiver& receiver = *session.receiver();
  std::uint64_t applied = 0, held = 0;
  // Cascades that followed the viewers move first, records and all, in one step.
  mirror.movePlaces(receiver.field());
  for (auto [k, b] : session.takeChangedBricks()) {
    if (mirror.applyBrick(receiver.field(), BrickId{k, b}, ++mirrorVersion, now)) ++applied;
    const std::uint64_t version = receiver.brickVersion(k, b);
    latency.arrived(version, now);
    held = std::max(held, version);
  }
  std::vector<float> samples = latency.take();

  std::lock_guard lock(mutex);
  if (latencySamples.size() < (1u << 20))
    latencySamples.insert(latencySamples.end(), samples.begin(), samples.end());
  stats.heldFieldVersion = std::max(stats.heldFieldVersion, held);
  stats.bricksApplied += applied;
  stats.bricksHeld = session.bricksHeld();
  stats.serverFieldVersion = receiver.serverFieldVersion();
  stats.receiver = receiver.stats();
  // Synced once the mirror has every brick, not only the receiver.
  if (!stats.synced && session.synced()) {
    stats.synced = true;
    stats.lastSyncedAt = now;
    stats.lastResyncSeconds = session.syncSeconds();
    logInfo("field synced " + std::to_string(int(stats.lastResyncSeconds * 1000)) +
            " ms after connecting");
  }
}

void NetClient::Impl::send(Bytes f) {
  if (!tcpOpen) return;
  if (queuedBytes + f.size() > kMaxClientQueuedBytes) return fail("server not reading");
  queuedBytes += f.size();
  writes.push_back(std::move(f));
  if (!writing) writeNext();
}

void NetClient::Impl::sendUplink() {
  const std::uint16_t port = options.udpServerPort ? options.udpServerPort : session.uplinkPort();
  std::uint64_t sent = 0;
  for (const Bytes& d : session.takeUplinkDatagrams()) {
    // Non-blocking: a datagram the socket cannot take now is lost, as on the way; the next
    // ack repeats what it said.
    boost::system::error_code ec;
    udpSocket.send_to(asio::buffer(d), udp::endpoint(serverAddress, port), 0, ec);
    sent += !ec;
  }
  if (sent == 0) return;
  std::lock_guard lock(mutex);
  stats.uplinkDatagrams += sent;
}

void NetClient::Impl::writeNext() {
  writing = true;
  const std::uint64_t id = connection;
  auto onWritten = [this, id, st = stream](boost::system::error_code ec, std::size_t) {
    if (id != connection || stopping) return;
    if (ec) return fail("write: " + ec.message());
    queuedBytes -= writes.front().size();
    writes.pop_front();
    if (writes.empty()) {
      writing = false;
    } else {
      writeNext();
    }
  };
  asio::async_write(*stream, asio::buffer(writes.front()), onWritten);
}

NetClient::NetClient(FieldMirror& mirror, NetClientOptions options)
    : impl_(std::make_unique<Impl>(mirror, std::move(options))) {}

NetClient::~NetClient() { stop(); }

void NetClient::start() {
  Impl& s = *impl_;
  if (s.thread.joinable()) return;
  boost::system::error_code ec;
  s.udpSocket.open(udp::v4(), ec);
  if (!ec) s.udpSocket.bind(udp::endpoint(udp::v4(), 0), ec);
  // Room for a burst of datagrams while this thread is busy applying bricks.
  if (!ec) s.udpSocket.set_option(asio::socket_base::receive_buffer_size(4 << 20), ec);
  if (!ec) s.udpSocket.non_blocking(true, ec);
  if (ec) {
    logWarn("UDP socket: " + ec.message() + "; asking for datagrams over TCP");
    s.options.tcpOnly = true;
  } else {
    s.udpPortNumber = s.udpSocket.local_endpoint(ec).port();
    s.receiveUdp();
  }
  if (s.options.tls) {
    net::TlsClientSettings settings;
    settings.pinnedFingerprint = s.options.serverFingerprint;
    settings.caFile = s.options.caFile;
    auto tls = net::TlsClient::create(settings);
    if (tls) {
      s.tls = *tls;
    } else {
      // connect() fails with the reason, and the stats say it, until the client stops.
      logError("TLS: " + tls.error().message);
    }
  }
  s.backoff = s.options.backoffInitial;
  s.connect();
  s.schedulePoll();
  s.thread = std::thread([&s] { s.io.run(); });
}

void NetClient::stop() {
  Impl& s = *impl_;
  if (!s.thread.joinable()) return;
  s.stopping = true;
  asio::post(s.io, [&s] {
    boost::system::error_code ec;
    ++s.connection;
    s.resolver.cancel();
    if (s.stream) s.stream->close();
    s.udpSocket.close(ec);
    s.pollTimer.cancel();
    s.retryTimer.cancel();
  });
  s.thread.join();
}

std::optional<double> NetClient::animationTime() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->clock.at(netClockSeconds());
}

void NetClient::setViewer(glm::vec3 position, glm::quat orientation) {
  std::lock_guard lock(impl_->mutex);
  ViewerPoseMsg pose;
  pose.position = position;
  pose.orientation = orientation;
  impl_->viewer = pose;
}

NetClientStats NetClient::stats() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->stats;
}

std::vector<float> NetClient::takeLatencySamples() {
  std::lock_guard lock(impl_->mutex);
  return std::exchange(impl_->latencySamples, {});
}

std::uint16_t NetClient::udpPort() const { return impl_->udpPortNumber; }

void NetClient::sendEdit(const EditMsg& edit) {
  std::lock_guard lock(impl_->mutex);
  if (impl_->editsToSend.size() < kMaxQueuedEdits) {
    impl_->editsToSend.push_back(edit);
  } else {
    impl_->editResults.push_back(
        EditResultMsg{edit.editId, false, "too many edits waiting to be sent", 0, 0});
  }
}

std::vector<EditResultMsg> NetClient::takeEditResults() {
  std::lock_guard lock(impl_->mutex);
  return std::exchange(impl_->editResults, {});
}

std::optional<SceneStateMsg> NetClient::editedScene() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->editedScene;
}

std::vector<EditArrival> NetClient::takeEditArrivals() {
  std::lock_guard lock(impl_->mutex);
  return std::exchange(impl_->editArrivals, {});
}

std::uint64_t NetClient::layoutGeneration() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->layoutGeneration;
}

}  // namespace pc::client
