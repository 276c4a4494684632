#include "net_server.h"

#include <pthread.h>
#include <sys/socket.h>

#include <cerrno>

#include <algorithm>
#include <array>
#include <boost/asio.hpp>
#include <deque>
#include <map>
#include <mutex>
#include <optional>
#include <random>
#include <thread>
#include <variant>

#include "common/log.h"
#include "protocol/net_framing.h"
#include "protocol/session_messages.h"

namespace pc {

namespace asio = boost::asio;
using asio::ip::tcp;
using asio::ip::udp;
using Bytes = std::vector<std::uint8_t>;
using SharedBytes = std::shared_ptr<const Bytes>;

const char* causeName(DisconnectCause cause) {
  switch (cause) {
    case DisconnectCause::ClientClosed:
      return "client_closed";
    case DisconnectCause::HelloTimeout:
      return "hello_timeout";
    case DisconnectCause::Silent:
      return "silent";
    case DisconnectCause::NotReading:
      return "not_reading";
    case DisconnectCause::Malformed:
      return "malformed";
    case DisconnectCause::Oversized:
      return "oversized";
    case DisconnectCause::WrongDirection:
      return "wrong_direction";
    case DisconnectCause::Protocol:
      return "protocol";
    case DisconnectCause::Invalid:
      return "invalid";
    case DisconnectCause::Flood:
      return "flood";
    case DisconnectCause::Rejected:
      return "rejected";
    case DisconnectCause::TooManyPending:
      return "too_many_pending";
    case DisconnectCause::Shutdown:
      return "shutdown";
  }
  return "?";
}

const char* causeName(RejectCause cause) {
  switch (cause) {
    case RejectCause::Auth:
      return "auth";
    case RejectCause::Version:
      return "version";
    case RejectCause::ServerFull:
      return "server_full";
  }
  return "?";
}

namespace {

// Before a client has shown a valid token it may send one small Hello, nothing bigger: an
// unauthenticated peer never makes the server allocate the full message limit.
constexpr std::size_t kMaxHelloFrameBytes = 4096;
// A receive buffer grown past this by one large message (a full ack) is given back after it.
constexpr std::size_t kKeptFrameCapacity = 64u << 10;

SharedBytes share(Bytes bytes) { return std::make_shared<const Bytes>(std::move(bytes)); }

std::uint32_t readLittleEndian32(const std::array<std::uint8_t, kFramePrefixBytes>& b) {
  return std::uint32_t(b[0]) | std::uint32_t(b[1]) << 8 | std::uint32_t(b[2]) << 16 |
         std::uint32_t(b[3]) << 24;
}

// Causes that a client brings on itself: logged as warnings.
bool misbehaviour(DisconnectCause c) {
  switch (c) {
    case DisconnectCause::ClientClosed:
    case DisconnectCause::Rejected:
    case DisconnectCause::Shutdown:
      return false;
    default:
      return true;
  }
}

// The causes that refuse a message (Session::refuse), as opposed to timeouts and closes.
constexpr DisconnectCause kMessageCauses[] = {
    DisconnectCause::Malformed, DisconnectCause::Oversized, DisconnectCause::WrongDirection,
    DisconnectCause::Protocol,  DisconnectCause::Invalid,   DisconnectCause::Flood};

const char* messageName(const SessionMessage& m) {
  constexpr const char* kNames[] = {"Hello",      "Welcome",    "Reject", "SessionInfo",
                                    "SceneState", "ViewerPose", "Ack",    "RepairRequest"};
  static_assert(std::size(kNames) == std::variant_size_v<SessionMessage>);
  return kNames[m.index()];
}

// A token bucket: `rate` per second, holding at most `burst`.
struct Bucket {
  double tokens = 0, rate = 0, burst = 0, at = 0;
  void init(double r, double b, double now) {
    rate = r;
    burst = tokens = b;
    at = now;
  }
  // False when taking `n` would leave the bucket in debt.
  bool take(double n, double now) {
    tokens = std::min(burst, tokens + (now - at) * rate);
    at = now;
    tokens -= n;
    return tokens >= 0;
  }
};

}  // namespace

class Session;

struct NetServer::Impl {
  Impl(FieldHub& h, NetServerOptions o)
      : hub(h), options(std::move(o)), acceptor(io), udpSocket(io), pollTimer(io) {}

  void acceptNext();
  void onAccepted(tcp::socket socket);
  static constexpr int kAcceptBatch = 64;  // accepts per turn of the event loop, at most
  void schedulePoll();
  void poll();
  void remove(std::uint32_t id, DisconnectCause cause);
  void publishStats(double pollSeconds = 0);
  void flushUdp();
  std::string renderMetrics() const;

  FieldHub& hub;
  NetServerOptions options;
  asio::io_context io;
  tcp::acceptor acceptor;
  udp::socket udpSocket;
  asio::steady_timer pollTimer;
  std::thread thread;
  bool stopped = false;
  // Perceptual comparisons shared by every session's sender (used under the hub lock).
  BrickChangeCache changeCache;
  // UDP datagrams of one poll, sent together (sendmmsg) after every session was polled.
  struct UdpOut {
    Session* session;  // kept alive by the poll's list of sessions
    udp::endpoint to;
    Bytes bytes;
  };
  std::vector<UdpOut> udpBatch;

  std::map<std::uint32_t, std::shared_ptr<Session>> sessions;
  std::size_t established = 0;  // sessions past the handshake
  std::uint32_t nextSessionId = 0;
  std::uint16_t tcpPort = 0, udpPortNumber = 0;
  // Limits derived from the options and the field (create()).
  std::size_t maxMessageBytes = 0;
  double maxReceiveBytesPerSecond = 0;
  std::size_t fieldBricks = 0;

  // Totals of sessions that have ended, plus a snapshot for stats() from other threads.
  NetServerStats totals;
  mutable std::mutex statsMutex;
  NetServerStats snapshot;

  // Metrics: the endpoint (its own thread) renders from the snapshot and the extra callback.
  std::unique_ptr<MetricsHttpServer> metrics;
  mutable std::mutex extraMutex;
  std::function<void(MetricsText&)> extraMetrics;
};

// One client's connection: reads frames, answers the handshake, feeds its StreamSender, and
// writes through a bounded queue. Lives on the network thread only; async handlers hold a
// shared_ptr so it outlives any operation still in flight after close().
class Session : public std::enable_shared_from_this<Session> {
 public:
  Session(NetServer::Impl& server, tcp::socket socket, std::uint32_t id)
      : server_(server), socket_(std::move(socket)), id_(id) {
    boost::system::error_code ec;
    auto remote = socket_.remote_endpoint(ec);
    peer_ =
        ec ? std::string("?") : remote.address().to_string() + ":" + std::to_string(remote.port());
    acceptedAt_ = lastHeard_ = steadySeconds();
    socket_.set_option(tcp::no_delay(true), ec);
    // Flood limits; before the Hello the prefix check allows one small frame anyway.
    messageBucket_.init(server_.options.maxMessagesPerSecond, server_.options.maxMessagesPerSecond,
                        acceptedAt_);
    byteBucket_.init(server_.maxReceiveBytesPerSecond, server_.maxReceiveBytesPerSecond,
                     acceptedAt_);
  }

  void start() { readPrefix(); }
  bool welcomed() const { return sender_ != nullptr; }

  // Ends the session now: the socket closes, pending operations complete with errors and
  // find the session closed. The cause is logged (one structured event) and counted once.
  void close(DisconnectCause cause, const std::string& detail) {
    if (closed_) return;
    closed_ = true;
    logEvent(misbehaviour(cause) ? LogLevel::Warn : LogLevel::Info, "client disconnected",
             {{"session", id_},
              {"peer", peer_},
              {"name", name_},
              {"cause", causeName(cause)},
              {"detail", detail},
              {"seconds", steadySeconds() - acceptedAt_}});
    boost::system::error_code ec;
    socket_.shutdown(tcp::socket::shutdown_both, ec);
    socket_.close(ec);
    server_.hub.removeViewer(id_);
    server_.remove(id_, cause);
    // After remove(): it counts this session as established while sender_ is set.
    auto lock = server_.hub.lock();
    sender_.reset();
  }

  // A message this client must not have sent: counted by cause, then the session ends.
  void refuse(DisconnectCause cause, const std::string& detail) {
    if (closed_) return;
    ++server_.totals.rejectedMessages[std::size_t(cause)];
    close(cause, detail);
  }

  // Called by the server's poll with the hub locked: datagrams and scene state to send.
  void pollLocked(double now, std::uint64_t sceneSerial, const SharedBytes& sceneFrame,
                  std::vector<Bytes>& datagrams, SharedBytes& scene) {
    if (closed_ || !sender_) return;
    if (sceneSerial != sceneSerialSent_ && sceneFrame) {
      sceneSerialSent_ = sceneSerial;
      scene = sceneFrame;
    }
    // Over TCP the sender is polled only while the queue is short: what it holds back stays
    // one entry per brick (the newest version), never a growing backlog here.
    if (!udpTarget_ && queuedBytes_ >= server_.options.tcpDatagramQueueBytes) {
      ++tcpQueueFullPolls_;
      return;
    }
    datagrams = sender_->poll(now);
    pendingBricks_ = sender_->pendingBricks();
    resends_ = sender_->stats().resends;
    repairedFragments_ = sender_->stats().repairedFragments;
  }

  // Called by the server's poll without the hub lock.
  void send(double now, std::vector<Bytes> datagrams, const SharedBytes& scene) {
    if (closed_) return;
    if (scene) enqueue(scene);
    for (Bytes& d : datagrams) {
      if (closed_) return;
      if (udpTarget_) {
        // Sent with every other session's datagrams of this poll (Impl::flushUdp).
        server_.udpBatch.push_back({this, *udpTarget_, std::move(d)});
        continue;
      }
      enqueue(share(datagramFrame(d)));
      ++datagrams_;
    }
    checkTimeouts(now);
  }

  bool closed() const { return closed_; }
  // What became of a datagram of flushUdp: a full socket buffer drops it (UDP loss, which the
  // protocol repairs).
  void udpSent(std::size_t bytes, bool ok) {
    if (!ok) {
      ++udpDropped_;
      return;
    }
    bytesSent_ += bytes;
    ++datagrams_;
  }

  void checkTimeouts(double now) {
    if (closed_) return;
    if (!sender_ && !closeAfterFlush_ && now - acceptedAt_ > server_.options.helloTimeout) {
      close(DisconnectCause::HelloTimeout,
            "no Hello within " + std::to_string(server_.options.helloTimeout) + " s");
    } else if (writing_ && now - writeStartedAt_ > server_.options.writeStallSeconds) {
      close(DisconnectCause::NotReading,
            "no write progress for " + std::to_string(server_.options.writeStallSeconds) + " s");
    } else if (sender_ && now - lastHeard_ > server_.options.silenceTimeout) {
      close(DisconnectCause::Silent,
            "no message for " + std::to_string(server_.options.silenceTimeout) + " s");
    }
  }

  NetClientInfo info(double now) const {
    NetClientInfo c;
    c.sessionId = id_;
    c.name = name_;
    c.peer = peer_;
    c.udp = udpTarget_.has_value();
    c.connectedSeconds = now - acceptedAt_;
    c.bytesSent = bytesSent_;
    c.datagrams = datagrams_;
    c.udpDropped = udpDropped_;
    c.bytesReceived = bytesReceived_;
    c.messagesReceived = messagesReceived_;
    c.pendingBricks = pendingBricks_;
    c.resends = resends_;
    c.repairedFragments = repairedFragments_;
    return c;
  }
  std::uint64_t tcpQueueFullPolls() const { return tcpQueueFullPolls_; }

 private:
  void readPrefix() {
    auto self = shared_from_this();
    asio::async_read(socket_, asio::buffer(prefix_),
                     [self](boost::system::error_code ec, std::size_t) { self->onPrefix(ec); });
  }

  void onPrefix(boost::system::error_code ec) {
    if (closed_) return;
    if (ec) {
      return close(DisconnectCause::ClientClosed, ec == asio::error::eof
                                                      ? "connection closed by the client"
                                                      : "read failed: " + ec.message());
    }
    // Every check on the prefix alone, before the frame's buffer is allocated.
    const std::size_t limit = sender_ ? server_.maxMessageBytes : kMaxHelloFrameBytes;
    const std::size_t announced = readLittleEndian32(prefix_) + kFramePrefixBytes;
    if (announced > limit) {
      return refuse(DisconnectCause::Oversized,
                    "frame of " + std::to_string(announced) + " bytes announced, the cap is " +
                        std::to_string(limit) + (sender_ ? "" : " before a Hello"));
    }
    auto size = frameSize(prefix_, limit);
    if (!size) return refuse(DisconnectCause::Malformed, "bad frame: " + size.error().message);
    const double now = steadySeconds();
    if (!messageBucket_.take(1, now)) {
      return refuse(DisconnectCause::Flood,
                    "more than " + std::to_string(server_.options.maxMessagesPerSecond) +
                        " messages per second");
    }
    if (!byteBucket_.take(double(*size), now)) {
      return refuse(
          DisconnectCause::Flood,
          "more than " + std::to_string(server_.maxReceiveBytesPerSecond) + " bytes per second");
    }
    frame_.assign(prefix_.begin(), prefix_.end());
    frame_.resize(*size);
    auto self = shared_from_this();
    asio::async_read(socket_,
                     asio::buffer(frame_.data() + kFramePrefixBytes, *size - kFramePrefixBytes),
                     [self](boost::system::error_code ec2, std::size_t) { self->onFrame(ec2); });
  }

  void onFrame(boost::system::error_code ec) {
    if (closed_) return;
    if (ec) return close(DisconnectCause::ClientClosed, "read failed: " + ec.message());
    bytesReceived_ += frame_.size();
    ++messagesReceived_;
    lastHeard_ = steadySeconds();
    switch (classifyFrame(frame_)) {
      case FrameKind::SessionMessage:
        break;
      case FrameKind::Datagram:
        return refuse(DisconnectCause::WrongDirection,
                      "a datagram frame: only the server sends datagrams");
      case FrameKind::Unknown:
        return refuse(DisconnectCause::Malformed, "not a session message frame");
    }
    auto message = decodeMessage(frame_);
    if (!message) return refuse(DisconnectCause::Malformed, message.error().message);
    if (frame_.capacity() > kKeptFrameCapacity) Bytes().swap(frame_);
    if (!handle(*message)) return;
    readPrefix();
  }

  // False when the session ended. A client changes nothing but its own pose and acks: the
  // session is the connection, so nothing it sends can name another session.
  bool handle(const SessionMessage& message) {
    if (!sender_) {
      const HelloMsg* hello = std::get_if<HelloMsg>(&message);
      if (!hello) {
        refuse(DisconnectCause::Protocol,
               std::string("expected Hello as the first message, got ") + messageName(message));
        return false;
      }
      return onHello(*hello);
    }
    if (std::holds_alternative<HelloMsg>(message)) {
      refuse(DisconnectCause::Protocol, "a second Hello");
      return false;
    }
    if (std::holds_alternative<WelcomeMsg>(message) || std::holds_alternative<RejectMsg>(message) ||
        std::holds_alternative<SessionInfoMsg>(message) ||
        std::holds_alternative<SceneStateMsg>(message)) {
      refuse(DisconnectCause::WrongDirection,
             std::string(messageName(message)) + " from a client: only the server sends it");
      return false;
    }
    if (auto invalid = checkSize(message)) {
      refuse(DisconnectCause::Invalid, *invalid);
      return false;
    }
    if (const auto* pose = std::get_if<ViewerPoseMsg>(&message))
      server_.hub.setViewer(id_, pose->position);
    Status status;
    {
      auto lock = server_.hub.lock();
      status = sender_->onMessage(message, steadySeconds());
    }
    if (!status) {
      refuse(DisconnectCause::Invalid, status.error().message);
      return false;
    }
    return true;
  }

  // What an ack or repair request may make the sender do is bounded by the field: a valid ack
  // lists each brick at most once, a repair request need not name one twice. Beyond that it is
  // work (and log lines) a client could multiply at will.
  std::optional<std::string> checkSize(const SessionMessage& message) const {
    const std::uint64_t bricks = server_.fieldBricks;
    if (const auto* ack = std::get_if<AckMsg>(&message)) {
      std::uint64_t covered = 0;
      for (const AckRange& r : ack->ranges) covered += r.count;
      if (ack->ranges.size() > bricks || covered > bricks) {
        return "ack with " + std::to_string(ack->ranges.size()) + " ranges covering " +
               std::to_string(covered) + " bricks; the field has " + std::to_string(bricks);
      }
    } else if (const auto* repair = std::get_if<RepairRequestMsg>(&message)) {
      if (repair->bricks.size() > bricks) {
        return "repair request naming " + std::to_string(repair->bricks.size()) +
               " bricks; the field has " + std::to_string(bricks);
      }
    }
    return std::nullopt;
  }

  bool onHello(const HelloMsg& hello) {
    name_ = hello.clientName.substr(0, 64);
    std::optional<RejectMsg> reject = checkHello(hello, server_.options.token);
    RejectCause cause = RejectCause::Auth;
    if (reject) {
      const bool versionOk =
          hello.protocolVersion >= kMinProtocolVersion && hello.protocolVersion <= kProtocolVersion;
      cause = versionOk ? RejectCause::Auth : RejectCause::Version;
    } else if (server_.established >= server_.options.maxClients) {
      reject = RejectMsg{kProtocolVersion, "server full: " + std::to_string(server_.established) +
                                               " clients connected, the cap is " +
                                               std::to_string(server_.options.maxClients)};
      cause = RejectCause::ServerFull;
    }
    if (reject) {
      logEvent(LogLevel::Warn, "client rejected",
               {{"session", id_},
                {"peer", peer_},
                {"name", name_},
                {"cause", causeName(cause)},
                {"reason", reject->reason}});
      ++server_.totals.rejected;
      ++server_.totals.rejects[std::size_t(cause)];
      // Nothing but the Reject goes out; the connection closes once it is written.
      closeAfterFlush_ = true;
      enqueue(share(encodeMessage(*reject)));
      return false;
    }
    const bool useUdp = !server_.options.tcpOnly && hello.wantsUdp && hello.udpPort != 0;
    if (useUdp) {
      boost::system::error_code ec;
      // Datagrams go only to the address the session came from: a client cannot aim the
      // server at a third party.
      udpTarget_ = udp::endpoint(socket_.remote_endpoint(ec).address(), hello.udpPort);
      if (ec) {
        close(DisconnectCause::ClientClosed, "no remote address: " + ec.message());
        return false;
      }
    }
    SessionInfoMsg info;
    SharedBytes scene;
    {
      auto lock = server_.hub.lock();
      info = server_.hub.publisher().sessionInfo();
      sender_ = std::make_unique<StreamSender>(server_.hub.publisher(), id_,
                                               server_.options.sender, &server_.changeCache);
      scene = server_.hub.sceneFrame();
      sceneSerialSent_ = server_.hub.sceneSerial();
    }
    ++server_.established;
    ++server_.totals.sessions;
    logEvent(LogLevel::Info, "client joined",
             {{"session", id_},
              {"peer", peer_},
              {"name", name_},
              {"transport", useUdp ? "udp" : "tcp"},
              {"udp_port", useUdp ? int(hello.udpPort) : 0}});
    enqueue(share(encodeMessage(WelcomeMsg{kProtocolVersion, id_})));
    enqueue(share(encodeMessage(info)));
    if (scene) enqueue(scene);
    return !closed_;
  }

  void enqueue(SharedBytes bytes) {
    if (closed_) return;
    if (queuedBytes_ + bytes->size() > server_.options.maxWriteQueueBytes) {
      return close(
          DisconnectCause::NotReading,
          "write queue over " + std::to_string(server_.options.maxWriteQueueBytes) + " bytes");
    }
    queuedBytes_ += bytes->size();
    writes_.push_back(std::move(bytes));
    if (!writing_) writeNext();
  }

  void writeNext() {
    writing_ = true;
    writeStartedAt_ = steadySeconds();
    auto self = shared_from_this();
    asio::async_write(
        socket_, asio::buffer(*writes_.front()),
        [self](boost::system::error_code ec, std::size_t n) { self->onWritten(ec, n); });
  }

  void onWritten(boost::system::error_code ec, std::size_t n) {
    if (closed_) return;
    if (ec) return close(DisconnectCause::ClientClosed, "write failed: " + ec.message());
    bytesSent_ += n;
    queuedBytes_ -= writes_.front()->size();
    writes_.pop_front();
    if (!writes_.empty()) return writeNext();
    writing_ = false;
    if (closeAfterFlush_) close(DisconnectCause::Rejected, "Reject written");
  }

  NetServer::Impl& server_;
  tcp::socket socket_;
  std::uint32_t id_;
  std::string peer_, name_;
  bool closed_ = false, closeAfterFlush_ = false;
  std::array<std::uint8_t, kFramePrefixBytes> prefix_{};
  Bytes frame_;
  std::deque<SharedBytes> writes_;
  std::size_t queuedBytes_ = 0;
  bool writing_ = false;
  double writeStartedAt_ = 0, acceptedAt_ = 0, lastHeard_ = 0;
  std::optional<udp::endpoint> udpTarget_;
  std::unique_ptr<StreamSender> sender_;  // created and used with the hub locked
  std::uint64_t sceneSerialSent_ = 0;
  std::uint64_t bytesSent_ = 0, bytesReceived_ = 0, datagrams_ = 0, udpDropped_ = 0;
  std::uint64_t messagesReceived_ = 0, tcpQueueFullPolls_ = 0;
  std::size_t pendingBricks_ = 0;
  std::uint64_t resends_ = 0, repairedFragments_ = 0;
  Bucket messageBucket_, byteBucket_;
};

void NetServer::Impl::acceptNext() {
  acceptor.async_accept([this](boost::system::error_code ec, tcp::socket socket) {
    if (stopped) return;
    if (ec) {
      logWarn("accept: " + ec.message());
    } else {
      onAccepted(std::move(socket));
      // Then whatever else waits in the backlog: one accept per turn of the event loop falls
      // behind a crowd of joining clients once a poll takes longer than the poll interval
      // (connections then waited seconds in the backlog), so the backlog is drained here.
      boost::system::error_code more;
      for (int i = 0; i < kAcceptBatch && !stopped; ++i) {
        tcp::socket next(io);
        acceptor.accept(next, more);
        if (more) break;  // would_block: the backlog is empty
        onAccepted(std::move(next));
      }
    }
    acceptNext();
  });
}

void NetServer::Impl::onAccepted(tcp::socket socket) {
  if (sessions.size() - established >= options.maxPendingConnections) {
    // Too many connections still before their Hello: this one is not read at all (a full
    // server answers a Hello with a Reject, but only this many Hellos are awaited at once).
    boost::system::error_code ignored;
    const auto remote = socket.remote_endpoint(ignored);
    ++totals.accepted;
    ++totals.disconnected;
    ++totals.disconnects[std::size_t(DisconnectCause::TooManyPending)];
    logEvent(LogLevel::Warn, "client disconnected",
             {{"peer", remote.address().to_string() + ":" + std::to_string(remote.port())},
              {"cause", causeName(DisconnectCause::TooManyPending)},
              {"detail", std::to_string(options.maxPendingConnections) +
                             " connections already awaiting their Hello"}});
    socket.close(ignored);
    return;
  }
  const std::uint32_t id = nextSessionId++;
  auto session = std::make_shared<Session>(*this, std::move(socket), id);
  sessions[id] = session;
  ++totals.accepted;
  session->start();
}

void NetServer::Impl::schedulePoll() {
  pollTimer.expires_after(std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(options.pollInterval)));
  pollTimer.async_wait([this](boost::system::error_code ec) {
    if (ec || stopped) return;
    poll();
    schedulePoll();
  });
}

void NetServer::Impl::poll() {
  // The datagrams of one slice of the sessions are built under the hub lock, then sent, before
  // the next slice is polled: what a poll holds at once stays near kPollSliceBytes (plus one
  // session's burst) instead of every session's burst together. All senders' brick
  // self-contained refreshes fall due in the same poll when clients joined together (every
  // selfContainedInterval), and 100 clients then produced about 25 MB of datagrams at once;
  // the heap kept that high-water mark, and the server's RSS stepped up every 30 s.
  constexpr std::size_t kPollSliceBytes = 2u << 20;
  const double now = steadySeconds();
  // Copies: a session may close (and leave the map) while sending.
  std::vector<std::shared_ptr<Session>> list;
  for (auto& [id, s] : sessions) list.push_back(s);
  std::vector<std::vector<Bytes>> datagrams(list.size());
  std::vector<SharedBytes> scenes(list.size());
  double pollSeconds = 0;
  std::size_t next = 0;
  do {
    const std::size_t first = next;
    {
      const double sliceStart = steadySeconds();
      auto lock = hub.lock();
      const std::uint64_t serial = hub.sceneSerial();
      const SharedBytes frame = hub.sceneFrame();
      std::size_t sliceBytes = 0;
      for (; next < list.size() && sliceBytes < kPollSliceBytes; ++next) {
        list[next]->pollLocked(now, serial, frame, datagrams[next], scenes[next]);
        for (const Bytes& d : datagrams[next]) sliceBytes += d.size();
      }
      if (next == list.size()) {
        // The publisher's figures for the metrics, while its lock is held anyway.
        const FieldPublisher& publisher = hub.publisher();
        totals.fieldVersion = publisher.fieldVersion();
        totals.encodes = publisher.encodes();
        totals.encodeSeconds = publisher.encodeSeconds();
        totals.encodeCacheBytes = publisher.cache().bytes();
        totals.encodeCacheEntries = publisher.cache().entries();
        totals.encodeCacheBoundBytes = publisher.cacheBoundBytes();
        totals.historyBytes = publisher.historyBytes();
        totals.historyBoundBytes = publisher.historyBoundBytes();
        totals.currentBricksBytes = publisher.currentBytes();
        totals.changeCacheBytes = changeCache.bytes();
        totals.changeCacheEntries = changeCache.entries();
      }
      pollSeconds += steadySeconds() - sliceStart;
    }
    // send() takes the datagrams and flushUdp() frees them, before the next slice is built.
    for (std::size_t i = first; i < next; ++i)
      list[i]->send(now, std::move(datagrams[i]), scenes[i]);
    flushUdp();
  } while (next < list.size());
  publishStats(pollSeconds);
}

void NetServer::Impl::flushUdp() {
  // One system call per batch instead of one per datagram. A datagram the socket refuses (its
  // buffer is full) is dropped and the rest of the batch is tried, as a send_to per datagram
  // would.
  constexpr std::size_t kBatch = 256;
  std::array<mmsghdr, kBatch> messages;
  std::array<iovec, kBatch> vectors;
  const int fd = udpSocket.native_handle();
  std::size_t i = 0;
  while (i < udpBatch.size()) {
    std::size_t n = 0;
    std::array<std::size_t, kBatch> index;
    for (std::size_t j = i; j < udpBatch.size() && n < kBatch; ++j) {
      UdpOut& d = udpBatch[j];
      if (d.session->closed()) continue;
      vectors[n] = iovec{d.bytes.data(), d.bytes.size()};
      messages[n] = mmsghdr{};
      messages[n].msg_hdr.msg_name = d.to.data();
      messages[n].msg_hdr.msg_namelen = socklen_t(d.to.size());
      messages[n].msg_hdr.msg_iov = &vectors[n];
      messages[n].msg_hdr.msg_iovlen = 1;
      index[n++] = j;
    }
    if (n == 0) break;
    int sent = ::sendmmsg(fd, messages.data(), unsigned(n), MSG_DONTWAIT);
    if (sent < 0 && errno == EINTR) continue;
    if (sent <= 0) {
      udpBatch[index[0]].session->udpSent(0, false);
      sent = 1;
    } else {
      for (int m = 0; m < sent; ++m)
        udpBatch[index[m]].session->udpSent(udpBatch[index[m]].bytes.size(), true);
    }
    i = index[std::size_t(sent) - 1] + 1;
  }
  udpBatch.clear();
}

void NetServer::Impl::remove(std::uint32_t id, DisconnectCause cause) {
  auto it = sessions.find(id);
  if (it == sessions.end()) return;
  const NetClientInfo info = it->second->info(steadySeconds());
  totals.bytesSent += info.bytesSent;
  totals.bytesReceived += info.bytesReceived;
  totals.messagesReceived += info.messagesReceived;
  totals.datagrams += info.datagrams;
  totals.udpDropped += info.udpDropped;
  totals.resends += info.resends;
  totals.repairedFragments += info.repairedFragments;
  totals.tcpQueueFullPolls += it->second->tcpQueueFullPolls();
  ++totals.disconnected;
  ++totals.disconnects[std::size_t(cause)];
  if (it->second->welcomed()) --established;
  // The map's reference goes after this call returns: the session is still running code.
  asio::post(io, [s = it->second] {});
  sessions.erase(it);
}

void NetServer::Impl::publishStats(double pollSeconds) {
  const double now = steadySeconds();
  totals.senderPollSeconds += pollSeconds;
  NetServerStats s = totals;
  s.connections = sessions.size();
  for (auto& [id, session] : sessions) {
    const NetClientInfo c = session->info(now);
    s.bytesSent += c.bytesSent;
    s.bytesReceived += c.bytesReceived;
    s.messagesReceived += c.messagesReceived;
    s.datagrams += c.datagrams;
    s.udpDropped += c.udpDropped;
    s.resends += c.resends;
    s.repairedFragments += c.repairedFragments;
    s.tcpQueueFullPolls += session->tcpQueueFullPolls();
    if (session->welcomed()) s.clients.push_back(c);
  }
  std::lock_guard lock(statsMutex);
  snapshot = std::move(s);
}

std::string NetServer::Impl::renderMetrics() const {
  NetServerStats s;
  {
    std::lock_guard lock(statsMutex);
    s = snapshot;
  }
  MetricsText text;
  appendServerMetrics(text, s);
  std::lock_guard lock(extraMutex);
  if (extraMetrics) extraMetrics(text);
  return text.str();
}

void appendServerMetrics(MetricsText& m, const NetServerStats& s) {
  m.gauge("probecast_clients", "Clients past the handshake.", double(s.clients.size()));
  m.gauge("probecast_connections", "Open client connections, in the handshake or past it.",
          double(s.connections));
  m.counter("probecast_connections_accepted_total", "TCP connections accepted.",
            double(s.accepted));
  m.counter("probecast_sessions_total", "Handshakes completed (Welcome sent).", double(s.sessions));
  for (std::size_t c = 0; c < kRejectCauses; ++c) {
    m.counter("probecast_sessions_rejected_total", "Hellos answered with a Reject, by cause.",
              double(s.rejects[c]), {{"cause", causeName(RejectCause(c))}});
  }
  for (std::size_t c = 0; c < kDisconnectCauses; ++c) {
    m.counter("probecast_disconnects_total", "Connections ended, by cause.",
              double(s.disconnects[c]), {{"cause", causeName(DisconnectCause(c))}});
  }
  for (DisconnectCause c : kMessageCauses) {
    m.counter("probecast_rejected_messages_total",
              "Client messages refused (each ends its session), by cause.",
              double(s.rejectedMessages[std::size_t(c)]), {{"cause", causeName(c)}});
  }
  m.counter("probecast_sent_bytes_total", "Bytes sent to clients (TCP writes and UDP datagrams).",
            double(s.bytesSent));
  m.counter("probecast_received_bytes_total", "Bytes of messages received from clients.",
            double(s.bytesReceived));
  m.counter("probecast_received_messages_total", "Messages received from clients.",
            double(s.messagesReceived));
  m.counter("probecast_datagrams_sent_total", "Brick datagrams sent (over UDP or framed over TCP).",
            double(s.datagrams));
  m.counter("probecast_updates_resent_total",
            "Brick updates sent again whole (lost: not acknowledged within the resend timeout).",
            double(s.resends));
  m.counter("probecast_fragments_repaired_total",
            "Fragments sent again because a client reported them missing from a partial update.",
            double(s.repairedFragments));
  m.counter("probecast_udp_send_drops_total",
            "Datagrams dropped because the UDP socket's send buffer was full.",
            double(s.udpDropped));
  m.counter("probecast_tcp_queue_full_polls_total",
            "Sender polls skipped because a TCP-only client's write queue was full.",
            double(s.tcpQueueFullPolls));
  m.counter("probecast_sender_poll_seconds_total",
            "Network thread time in the client senders (choosing and encoding bricks).",
            s.senderPollSeconds);
  m.gauge("probecast_field_version", "Newest field version published.", double(s.fieldVersion));
  m.counter("probecast_encodes_total", "Brick updates encoded (encode cache misses).",
            double(s.encodes));
  m.counter("probecast_encode_seconds_total", "Time spent encoding brick updates.",
            s.encodeSeconds);
  m.gauge("probecast_encode_cache_bytes", "Heap bytes of the encoded updates the cache holds.",
          double(s.encodeCacheBytes));
  m.gauge("probecast_encode_cache_entries", "Encoded updates the cache holds.",
          double(s.encodeCacheEntries));
  m.gauge("probecast_encode_cache_bound_bytes",
          "Most bytes the encode cache can hold for this field (bricks x versions kept).",
          double(s.encodeCacheBoundBytes));
  m.gauge("probecast_brick_history_bytes",
          "Bytes of quantized brick versions kept beyond the current ones (residual bases).",
          double(s.historyBytes));
  m.gauge("probecast_brick_history_bound_bytes",
          "Most bytes the brick history can hold for this field (bricks x versions kept).",
          double(s.historyBoundBytes));
  m.gauge("probecast_current_bricks_bytes", "Bytes of the current quantized brick versions.",
          double(s.currentBricksBytes));
  m.gauge("probecast_change_cache_bytes",
          "Bytes held by the shared perceptual comparisons of brick versions (estimated).",
          double(s.changeCacheBytes));
  m.gauge("probecast_change_cache_entries", "Shared perceptual comparisons held.",
          double(s.changeCacheEntries));
}

NetServer::NetServer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

NetServer::~NetServer() { stop(); }

Result<std::unique_ptr<NetServer>> NetServer::create(FieldHub& hub, NetServerOptions options) {
  auto impl = std::make_unique<Impl>(hub, std::move(options));
  Impl& s = *impl;
  boost::system::error_code ec;
  const auto address = asio::ip::make_address(s.options.bindAddress, ec);
  if (ec) return Error{"bad bind address '" + s.options.bindAddress + "': " + ec.message()};
  const tcp::endpoint endpoint(address, s.options.port);
  // SO_REUSEADDR: a restarted server binds its port again while old connections linger.
  s.acceptor.open(endpoint.protocol(), ec);
  if (!ec) s.acceptor.set_option(tcp::acceptor::reuse_address(true), ec);
  if (!ec) s.acceptor.bind(endpoint, ec);
  if (!ec) s.acceptor.listen(asio::socket_base::max_listen_connections, ec);
  // Non-blocking, so acceptNext can drain the backlog without waiting.
  if (!ec) s.acceptor.non_blocking(true, ec);
  if (ec) {
    return Error{"cannot listen on TCP " + s.options.bindAddress + ":" +
                 std::to_string(s.options.port) + ": " + ec.message()};
  }
  s.tcpPort = s.acceptor.local_endpoint().port();
  // Datagrams leave from any free port: clients receive them wherever they come from (the
  // session id and CRC in each say whether to trust it).
  s.udpSocket.open(udp::v4(), ec);
  if (!ec) s.udpSocket.bind(udp::endpoint(address, 0), ec);
  if (ec) return Error{"cannot open the UDP socket: " + ec.message()};
  s.udpSocket.non_blocking(true, ec);
  s.udpSocket.set_option(asio::socket_base::send_buffer_size(4 << 20), ec);
  s.udpPortNumber = s.udpSocket.local_endpoint().port();
  // Session ids start at a random point, so a restarted server never reuses its old ids and
  // a client's stale datagrams from before the restart are refused.
  std::random_device rd;
  s.nextSessionId = (std::uint32_t(rd()) & 0x7FFF'FFFFu) | 1u;

  {
    auto lock = hub.lock();
    for (int k = 0; k < hub.publisher().cascadeCount(); ++k)
      s.fieldBricks += std::size_t(hub.publisher().brickCount(k));
  }
  s.maxMessageBytes =
      s.options.maxMessageBytes != 0
          ? s.options.maxMessageBytes
          : std::clamp<std::size_t>(32 * s.fieldBricks + 4096, 64u << 10, kMaxSessionMessageBytes);
  s.maxMessageBytes = std::min(s.maxMessageBytes, kMaxSessionMessageBytes);
  s.maxReceiveBytesPerSecond = s.options.maxReceiveBytesPerSecond > 0
                                   ? s.options.maxReceiveBytesPerSecond
                                   : std::max(double(1u << 20), 4.0 * double(s.maxMessageBytes));
  if (s.options.maxMessagesPerSecond < 1 ||
      s.maxReceiveBytesPerSecond < double(s.maxMessageBytes)) {
    return Error{"flood limits: at least 1 message and one largest message (" +
                 std::to_string(s.maxMessageBytes) + " bytes) per second"};
  }

  if (s.options.metricsPort) {
    MetricsHttpOptions mo;
    mo.bindAddress =
        s.options.metricsBindAddress.empty() ? s.options.bindAddress : s.options.metricsBindAddress;
    mo.port = *s.options.metricsPort;
    auto metrics = MetricsHttpServer::create(mo, [&s] { return s.renderMetrics(); });
    if (!metrics) return metrics.error();
    s.metrics = std::move(metrics).value();
  }
  return std::unique_ptr<NetServer>(new NetServer(std::move(impl)));
}

void NetServer::start() {
  Impl& s = *impl_;
  s.acceptNext();
  s.schedulePoll();
  s.thread = std::thread([&s] {
    // Named, so a profiler or the load benchmark can tell this thread's CPU time from the
    // field thread's (/proc/<pid>/task/<tid>/comm).
    pthread_setname_np(pthread_self(), "pc-net");
    s.io.run();
  });
}

void NetServer::stop() {
  Impl& s = *impl_;
  if (!s.thread.joinable()) return;
  asio::post(s.io, [&s] {
    s.stopped = true;
    boost::system::error_code ec;
    s.acceptor.close(ec);
    s.pollTimer.cancel();
    std::vector<std::shared_ptr<Session>> list;
    for (auto& [id, session] : s.sessions) list.push_back(session);
    for (auto& session : list) session->close(DisconnectCause::Shutdown, "server stopping");
    s.udpSocket.close(ec);
    s.publishStats();
  });
  s.thread.join();
  // The endpoint goes last, so a scrape during shutdown still sees the final counts.
  s.metrics.reset();
}

std::uint16_t NetServer::port() const { return impl_->tcpPort; }
std::uint16_t NetServer::udpPort() const { return impl_->udpPortNumber; }

std::uint16_t NetServer::metricsPort() const { return impl_->metrics ? impl_->metrics->port() : 0; }

void NetServer::setExtraMetrics(std::function<void(MetricsText&)> extra) {
  std::lock_guard lock(impl_->extraMutex);
  impl_->extraMetrics = std::move(extra);
}

NetServerStats NetServer::stats() const {
  std::lock_guard lock(impl_->statsMutex);
  return impl_->snapshot;
}

}  // namespace pc
