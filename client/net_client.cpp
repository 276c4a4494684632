#include "net_client.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <boost/asio.hpp>
#include <chrono>
#include <deque>
#include <mutex>
#include <thread>

#include "common/log.h"
#include "protocol/brick_codec.h"
#include "protocol/net_framing.h"
#include "protocol/session_messages.h"

namespace pc::client {

namespace asio = boost::asio;
using asio::ip::tcp;
using asio::ip::udp;
using Bytes = std::vector<std::uint8_t>;

double netClockSeconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

std::uint64_t mirrorMemoryBytes(const SessionInfoMsg& info) {
  using namespace gpu;
  constexpr std::uint64_t kTileFloats =
      std::uint64_t(PC_IRRADIANCE_TEXELS + 2) * (PC_IRRADIANCE_TEXELS + 2) * 3 +
      std::uint64_t(PC_DEPTH_TEXELS + 2) * (PC_DEPTH_TEXELS + 2) * 2 +
      std::uint64_t(PC_OCCLUSION_TEXELS + 2) * (PC_OCCLUSION_TEXELS + 2);
  constexpr std::uint64_t kSlotBytes = kTileFloats * sizeof(float) + sizeof(ProbeRecord);
  constexpr std::uint64_t kBrickCodeBytes = brick_layout::kCodes * sizeof(std::uint16_t);
  std::uint64_t bricks = 0;
  for (const CascadeDesc& c : info.cascades) {
    const auto perAxis = [](int n) { return std::uint64_t(std::clamp(n, 1, 1024) + 3) / 4; };
    bricks += perAxis(c.counts.x) * perAxis(c.counts.y) * perAxis(c.counts.z);
  }
  const std::uint64_t slots = bricks * PC_PROBES_PER_BRICK;
  // Two fields (the receiver's and the mirror's) and one set of codes.
  return 2 * slots * kSlotBytes + bricks * kBrickCodeBytes;
}

namespace {

asio::steady_timer::duration toDuration(double seconds) {
  return std::chrono::duration_cast<asio::steady_timer::duration>(
      std::chrono::duration<double>(std::max(0.0, seconds)));
}

// The client sends only small messages; more than this queued means the server is not reading.
constexpr std::size_t kMaxWriteQueueBytes = 1u << 20;

// Mirror versions are the client's own, increasing across sessions: a restarted server counts
// its brick versions from the start again, and the mirror only takes newer versions. Baked
// fallback files carry versions far below this.
constexpr std::uint64_t kFirstMirrorVersion = std::uint64_t(1) << 40;

bool sameLayout(const gpu::FieldDesc& a, const gpu::FieldDesc& b) {
  if (a.cascadeCount != b.cascadeCount || a.probeCount != b.probeCount ||
      a.atlasTileRows != b.atlasTileRows)
    return false;
  for (int k = 0; k < a.cascadeCount; ++k) {
    const gpu::CascadeDesc &x = a.cascades[k], &y = b.cascades[k];
    if (x.counts != y.counts || x.firstProbe != y.firstProbe || x.atlasTileRow != y.atlasTileRow ||
        x.origin != y.origin || x.spacing != y.spacing || x.scroll != y.scroll)
      return false;
  }
  return true;
}

}  // namespace

struct NetClient::Impl {
  Impl(FieldMirror& m, NetClientOptions o)
      : mirror(m), options(std::move(o)), tcpSocket(io), udpSocket(io), pollTimer(io),
        retryTimer(io), resolver(io) {}

  // Network thread only.
  void connect();
  void fail(const std::string& why);
  void readPrefix();
  void onFrame();
  void handle(const SessionMessage& message);
  void onSessionInfo(const SessionInfoMsg& info);
  void onSceneState(const SceneStateMsg& state);
  void onDatagram(std::span<const std::uint8_t> bytes, bool overUdp);
  void receiveUdp();
  void schedulePoll();
  void poll();
  void send(Bytes frame);
  void writeNext();

  FieldMirror& mirror;
  NetClientOptions options;
  asio::io_context io;
  tcp::socket tcpSocket;
  udp::socket udpSocket;
  asio::steady_timer pollTimer, retryTimer;
  tcp::resolver resolver;
  std::thread thread;
  std::atomic<bool> stopping{false};
  std::uint16_t udpPortNumber = 0;  // set before the thread starts

  // Session state (network thread).
  std::uint64_t connection = 0;  // bumps per connection: handlers of an old one do nothing
  bool tcpOpen = false;
  bool attempting = false;  // a resolve/connect/handshake is under way
  double connectStartedAt = 0, lastHeard = 0, lastPoseAt = -1e30;
  double backoff = 0;
  std::uint32_t sessionId = 0;
  bool welcomed = false;
  std::optional<StreamReceiver> receiver;
  std::array<std::uint8_t, kFramePrefixBytes> prefix{};
  Bytes frame;
  std::array<std::uint8_t, 2048> udpBuffer{};
  udp::endpoint udpFrom;
  std::deque<Bytes> writes;
  std::size_t queuedBytes = 0;
  bool writing = false;
  std::uint64_t mirrorVersion = kFirstMirrorVersion;
  int bricksTotal = 0, bricksHeld = 0;
  std::vector<std::vector<bool>> held;

  // Shared with the frame thread.
  mutable std::mutex mutex;
  NetClientStats stats;
  std::optional<ViewerPoseMsg> viewer;
  bool haveClock = false;
  double clockAnim = 0, clockWall = 0, clockRate = 1.0;
  std::uint64_t layoutGeneration = 0;
};

void NetClient::Impl::connect() {
  if (stopping) return;
  const std::uint64_t id = ++connection;
  attempting = true;
  connectStartedAt = netClockSeconds();
  {
    std::lock_guard lock(mutex);
    ++stats.connectAttempts;
  }
  resolver.async_resolve(
      options.host, std::to_string(options.port),
      [this, id](boost::system::error_code ec, tcp::resolver::results_type results) {
        if (id != connection || stopping) return;
        if (ec) return fail("resolve " + options.host + ": " + ec.message());
        asio::async_connect(tcpSocket, results, [this, id](boost::system::error_code ec2, const tcp::endpoint&) {
          if (id != connection || stopping) return;
          if (ec2) return fail("connect: " + ec2.message());
          tcpOpen = true;
          lastHeard = netClockSeconds();
          boost::system::error_code ignored;
          tcpSocket.set_option(tcp::no_delay(true), ignored);
          HelloMsg hello;
          hello.authToken = options.token;
          hello.clientName = options.name;
          hello.wantsUdp = !options.tcpOnly;
          hello.udpPort = options.tcpOnly ? 0
                          : options.udpAdvertisePort ? options.udpAdvertisePort
                                                     : udpSocket.local_endpoint(ignored).port();
          send(encodeMessage(hello));
          readPrefix();
        });
      });
}

// Ends the connection (if any) and tries again after the backoff. The mirror keeps what it
// holds: the frame loop goes on rendering it.
void NetClient::Impl::fail(const std::string& why) {
  ++connection;
  const bool wasConnected = welcomed;
  boost::system::error_code ec;
  tcpSocket.shutdown(tcp::socket::shutdown_both, ec);
  tcpSocket.close(ec);
  tcpOpen = false;
  attempting = false;
  welcomed = false;
  receiver.reset();
  writes.clear();
  queuedBytes = 0;
  writing = false;
  if (wasConnected) backoff = options.backoffInitial;
  {
    std::lock_guard lock(mutex);
    if (stats.lastError != why || wasConnected) logWarn("server " + options.host + ":" +
                                                        std::to_string(options.port) + ": " + why);
    stats.lastError = why;
    stats.connected = false;
    stats.synced = false;
  }
  if (stopping) return;
  const double wait = backoff;
  backoff = std::min(options.backoffMax, std::max(options.backoffInitial, backoff * 2));
  retryTimer.expires_after(toDuration(wait));
  retryTimer.async_wait([this](boost::system::error_code e) {
    if (!e && !stopping) connect();
  });
}

void NetClient::Impl::readPrefix() {
  const std::uint64_t id = connection;
  asio::async_read(tcpSocket, asio::buffer(prefix), [this, id](boost::system::error_code ec, std::size_t) {
    if (id != connection || stopping) return;
    if (ec) return fail(ec == asio::error::eof ? "connection closed" : "read: " + ec.message());
    auto size = frameSize(prefix, kMaxSessionMessageBytes);
    if (!size) return fail("bad frame from the server: " + size.error().message);
    frame.assign(prefix.begin(), prefix.end());
    frame.resize(*size);
    asio::async_read(tcpSocket, asio::buffer(frame.data() + kFramePrefixBytes, *size - kFramePrefixBytes),
                     [this, id](boost::system::error_code ec2, std::size_t) {
                       if (id != connection || stopping) return;
                       if (ec2) return fail("read: " + ec2.message());
                       onFrame();
                     });
  });
}

void NetClient::Impl::onFrame() {
  const std::uint64_t id = connection;
  lastHeard = netClockSeconds();
  {
    std::lock_guard lock(mutex);
    stats.tcpBytes += frame.size();
  }
  switch (classifyFrame(frame)) {
    case FrameKind::Datagram:
      onDatagram(datagramOfFrame(frame), false);
      break;
    case FrameKind::SessionMessage: {
      auto message = decodeMessage(frame);
      if (!message) return fail("bad message from the server: " + message.error().message);
      handle(*message);
      break;
    }
    case FrameKind::Unknown:
      return fail("unknown frame from the server");
  }
  if (id == connection) readPrefix();
}

void NetClient::Impl::handle(const SessionMessage& message) {
  if (const auto* welcome = std::get_if<WelcomeMsg>(&message)) {
    Status version = checkServerVersion(welcome->protocolVersion);
    if (!version) return fail(version.error().message);
    sessionId = welcome->sessionId;
  } else if (const auto* reject = std::get_if<RejectMsg>(&message)) {
    {
      std::lock_guard lock(mutex);
      ++stats.rejects;
    }
    // A rejected client keeps trying at the slowest pace: the token may be fixed server-side.
    backoff = options.backoffMax;
    return fail("rejected: " + reject->reason);
  } else if (const auto* info = std::get_if<SessionInfoMsg>(&message)) {
    onSessionInfo(*info);
  } else if (const auto* state = std::get_if<SceneStateMsg>(&message)) {
    onSceneState(*state);
  } else {
    return fail("unexpected message from the server");
  }
}

void NetClient::Impl::onSessionInfo(const SessionInfoMsg& info) {
  // Checked before anything is laid out: a hostile or broken server could otherwise make this
  // client allocate tens of GiB (mirrorField accepts up to 4M probe slots).
  const std::uint64_t needed = mirrorMemoryBytes(info);
  if (needed > options.maxMirrorBytes) {
    const auto mib = [](std::uint64_t b) { return std::to_string((b + (1u << 20) - 1) >> 20); };
    return fail("session info: the server's field layout (" + std::to_string(info.cascades.size()) +
                " cascades) needs about " + mib(needed) + " MiB of mirror memory, over this "
                "client's cap of " + mib(options.maxMirrorBytes) + " MiB (maxMirrorBytes)");
  }
  auto created = StreamReceiver::create(info, sessionId, options.receiver);
  if (!created) return fail("session info: " + created.error().message);
  receiver.emplace(std::move(created).value());
  const Field& layout = receiver->field();
  const double now = netClockSeconds();
  const std::optional<gpu::FieldDesc> current = mirror.desc();
  if (!current || !sameLayout(*current, layout.desc)) {
    // The baked fallback (if any) is for another layout: its tiles would land in the wrong
    // places. Start from the empty field; the stream fills it.
    mirror.reset(layout, now);
    std::lock_guard lock(mutex);
    ++stats.layoutResets;
    ++layoutGeneration;
  }
  bricksTotal = bricksHeld = 0;
  held.assign(layout.cascadeCount(), {});
  for (int k = 0; k < layout.cascadeCount(); ++k) {
    held[k].assign(layout.brickVersions[k].size(), false);
    bricksTotal += int(layout.brickVersions[k].size());
  }
  welcomed = true;
  backoff = options.backoffInitial;
  std::lock_guard lock(mutex);
  ++stats.sessions;
  stats.connected = true;
  stats.synced = false;
  stats.bricksHeld = 0;
  stats.bricksTotal = bricksTotal;
  stats.lastError.clear();
  logInfo("connected to " + options.host + ":" + std::to_string(options.port) + ", session " +
          std::to_string(sessionId) + ", " + std::to_string(bricksTotal) + " bricks" +
          (options.tcpOnly ? " (TCP only)" : ""));
}

void NetClient::Impl::onSceneState(const SceneStateMsg& state) {
  const double now = netClockSeconds();
  std::lock_guard lock(mutex);
  if (haveClock && now > clockWall + 1e-3) {
    // The rate the server's clock advanced at (0 when it is frozen), so extrapolating between
    // messages never runs past a stopped clock. Clamped: jitter only nudges it.
    clockRate = std::clamp((state.animationTime - clockAnim) / (now - clockWall), 0.0, 2.0);
  }
  haveClock = true;
  clockAnim = state.animationTime;
  clockWall = now;
}

void NetClient::Impl::onDatagram(std::span<const std::uint8_t> bytes, bool overUdp) {
  const double now = netClockSeconds();
  lastHeard = now;
  Status status = receiver ? receiver->onDatagram(bytes, now) : Status(Error{"no session yet"});
  std::lock_guard lock(mutex);
  if (overUdp) {
    ++stats.udpDatagrams;
    stats.udpBytes += bytes.size();
  } else {
    ++stats.tcpDatagrams;
  }
  if (!status) ++stats.badDatagrams;
}

void NetClient::Impl::receiveUdp() {
  udpSocket.async_receive_from(asio::buffer(udpBuffer), udpFrom, [this](boost::system::error_code ec, std::size_t n) {
    if (stopping) return;
    // Errors on a UDP socket (an ICMP unreachable from an earlier send, a truncated read) are
    // per datagram: keep receiving.
    if (!ec && n <= kMaxDatagramBytes) onDatagram(std::span(udpBuffer.data(), n), true);
    receiveUdp();
  });
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
  if (attempting && !welcomed && now - connectStartedAt > options.connectTimeout)
    return fail("no session within " + std::to_string(options.connectTimeout) + " s");
  if (tcpOpen && now - lastHeard > options.silenceTimeout)
    return fail("server silent for " + std::to_string(options.silenceTimeout) + " s");
  if (!receiver || !welcomed) return;

  for (Bytes& f : receiver->poll(now)) send(std::move(f));
  if (!tcpOpen) return;  // send() may have failed the connection

  // Hand changed bricks to the mirror: the frame loop uploads them on its own schedule.
  const Field& field = receiver->field();
  std::uint64_t applied = 0;
  for (auto [k, b] : receiver->takeChangedBricks()) {
    if (mirror.applyBrick(field, BrickId{k, b}, ++mirrorVersion, now)) ++applied;
    if (!held[k][b]) {
      held[k][b] = true;
      ++bricksHeld;
    }
  }

  std::optional<ViewerPoseMsg> pose;
  {
    std::lock_guard lock(mutex);
    stats.bricksApplied += applied;
    stats.bricksHeld = bricksHeld;
    stats.serverFieldVersion = receiver->serverFieldVersion();
    stats.receiver = receiver->stats();
    if (!stats.synced && bricksHeld == bricksTotal) {
      stats.synced = true;
      stats.lastSyncedAt = now;
      stats.lastResyncSeconds = now - connectStartedAt;
      logInfo("field synced " + std::to_string(int(stats.lastResyncSeconds * 1000)) +
              " ms after connecting");
    }
    if (viewer && now - lastPoseAt >= options.poseInterval) {
      pose = viewer;
      if (haveClock) pose->time = clockAnim + clockRate * (now - clockWall);
    }
  }
  if (pose) {
    lastPoseAt = now;
    send(encodeMessage(*pose));
  }
}

void NetClient::Impl::send(Bytes f) {
  if (!tcpOpen) return;
  if (queuedBytes + f.size() > kMaxWriteQueueBytes) return fail("server not reading");
  queuedBytes += f.size();
  writes.push_back(std::move(f));
  if (!writing) writeNext();
}

void NetClient::Impl::writeNext() {
  writing = true;
  const std::uint64_t id = connection;
  asio::async_write(tcpSocket, asio::buffer(writes.front()), [this, id](boost::system::error_code ec, std::size_t) {
    if (id != connection || stopping) return;
    if (ec) return fail("write: " + ec.message());
    queuedBytes -= writes.front().size();
    writes.pop_front();
    if (writes.empty()) {
      writing = false;
    } else {
      writeNext();
    }
  });
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
  if (ec) {
    logWarn("UDP socket: " + ec.message() + "; asking for datagrams over TCP");
    s.options.tcpOnly = true;
  } else {
    s.udpPortNumber = s.udpSocket.local_endpoint(ec).port();
    s.receiveUdp();
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
    s.tcpSocket.close(ec);
    s.udpSocket.close(ec);
    s.pollTimer.cancel();
    s.retryTimer.cancel();
  });
  s.thread.join();
}

std::optional<double> NetClient::animationTime() const {
  std::lock_guard lock(impl_->mutex);
  if (!impl_->haveClock) return std::nullopt;
  // While the server is away the clock runs on at the last rate: the scene keeps moving and
  // the next scene state corrects it.
  const double since = netClockSeconds() - impl_->clockWall;
  return impl_->clockAnim + impl_->clockRate * since;
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

std::uint16_t NetClient::udpPort() const { return impl_->udpPortNumber; }

std::uint64_t NetClient::layoutGeneration() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->layoutGeneration;
}

}  // namespace pc::client
