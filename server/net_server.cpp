#include "net_server.h"

#include <array>
#include <boost/asio.hpp>
#include <deque>
#include <map>
#include <mutex>
#include <optional>
#include <random>
#include <thread>

#include "common/log.h"
#include "protocol/net_framing.h"
#include "protocol/session_messages.h"

namespace pc {

namespace asio = boost::asio;
using asio::ip::tcp;
using asio::ip::udp;
using Bytes = std::vector<std::uint8_t>;
using SharedBytes = std::shared_ptr<const Bytes>;

namespace {

// Before a client has shown a valid token it may send one small Hello, nothing bigger: an
// unauthenticated peer never makes the server allocate the full message limit.
constexpr std::size_t kMaxHelloFrameBytes = 4096;

SharedBytes share(Bytes bytes) { return std::make_shared<const Bytes>(std::move(bytes)); }

}  // namespace

class Session;

struct NetServer::Impl {
  Impl(FieldHub& h, NetServerOptions o)
      : hub(h), options(std::move(o)), acceptor(io), udpSocket(io), pollTimer(io) {}

  void acceptNext();
  void schedulePoll();
  void poll();
  void remove(std::uint32_t id, const std::string& cause);
  void publishStats();

  FieldHub& hub;
  NetServerOptions options;
  asio::io_context io;
  tcp::acceptor acceptor;
  udp::socket udpSocket;
  asio::steady_timer pollTimer;
  std::thread thread;
  bool stopped = false;
  std::map<std::uint32_t, std::shared_ptr<Session>> sessions;
  std::uint32_t nextSessionId = 0;
  std::uint16_t tcpPort = 0, udpPortNumber = 0;

  // Totals of sessions that have ended, plus a snapshot for stats() from other threads.
  NetServerStats totals;
  mutable std::mutex statsMutex;
  NetServerStats snapshot;
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
    peer_ = ec ? std::string("?") : remote.address().to_string() + ":" + std::to_string(remote.port());
    acceptedAt_ = lastHeard_ = steadySeconds();
    socket_.set_option(tcp::no_delay(true), ec);
  }

  void start() { readPrefix(); }

  // Ends the session now: the socket closes, pending operations complete with errors and
  // find the session closed. The cause is logged once.
  void close(const std::string& cause) {
    if (closed_) return;
    closed_ = true;
    logInfo("client " + describe() + " disconnected: " + cause);
    boost::system::error_code ec;
    socket_.shutdown(tcp::socket::shutdown_both, ec);
    socket_.close(ec);
    {
      auto lock = server_.hub.lock();
      sender_.reset();
    }
    server_.hub.removeViewer(id_);
    server_.remove(id_, cause);
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
    if (!udpTarget_ && queuedBytes_ >= server_.options.tcpDatagramQueueBytes) return;
    datagrams = sender_->poll(now);
    pendingBricks_ = sender_->pendingBricks();
  }

  // Called by the server's poll without the hub lock.
  void send(double now, std::vector<Bytes> datagrams, const SharedBytes& scene) {
    if (closed_) return;
    if (scene) enqueue(scene);
    for (Bytes& d : datagrams) {
      if (closed_) return;
      if (udpTarget_) {
        boost::system::error_code ec;
        server_.udpSocket.send_to(asio::buffer(d), *udpTarget_, 0, ec);
        // A full socket buffer drops the datagram: UDP loss, which the protocol repairs.
        if (ec) {
          ++udpDropped_;
          continue;
        }
        bytesSent_ += d.size();
      } else {
        enqueue(share(datagramFrame(d)));
      }
      ++datagrams_;
    }
    checkTimeouts(now);
  }

  void checkTimeouts(double now) {
    if (closed_) return;
    if (!sender_ && now - acceptedAt_ > server_.options.helloTimeout) {
      close("no Hello within " + std::to_string(server_.options.helloTimeout) + " s");
    } else if (writing_ && now - writeStartedAt_ > server_.options.writeStallSeconds) {
      close("not reading: no write progress for " +
            std::to_string(server_.options.writeStallSeconds) + " s");
    } else if (sender_ && now - lastHeard_ > server_.options.silenceTimeout) {
      close("silent for " + std::to_string(server_.options.silenceTimeout) + " s");
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
    c.pendingBricks = pendingBricks_;
    return c;
  }
  std::uint64_t bytesReceived() const { return bytesReceived_; }

 private:
  std::string describe() const {
    return std::to_string(id_) + " (" + peer_ + (name_.empty() ? "" : ", " + name_) + ")";
  }

  void readPrefix() {
    auto self = shared_from_this();
    asio::async_read(socket_, asio::buffer(prefix_),
                     [self](boost::system::error_code ec, std::size_t) { self->onPrefix(ec); });
  }

  void onPrefix(boost::system::error_code ec) {
    if (closed_) return;
    if (ec) return close(ec == asio::error::eof ? "connection closed by the client"
                                                : "read failed: " + ec.message());
    const std::size_t limit = sender_ ? kMaxSessionMessageBytes : kMaxHelloFrameBytes;
    auto size = frameSize(prefix_, limit);
    if (!size) return close("bad frame: " + size.error().message);
    frame_.assign(prefix_.begin(), prefix_.end());
    frame_.resize(*size);
    auto self = shared_from_this();
    asio::async_read(socket_, asio::buffer(frame_.data() + kFramePrefixBytes, *size - kFramePrefixBytes),
                     [self](boost::system::error_code ec2, std::size_t) { self->onFrame(ec2); });
  }

  void onFrame(boost::system::error_code ec) {
    if (closed_) return;
    if (ec) return close("read failed: " + ec.message());
    bytesReceived_ += frame_.size();
    lastHeard_ = steadySeconds();
    if (classifyFrame(frame_) != FrameKind::SessionMessage)
      return close("malformed frame: not a session message");
    auto message = decodeMessage(frame_);
    if (!message) return close("malformed message: " + message.error().message);
    if (!handle(*message)) return;
    readPrefix();
  }

  // False when the session ended.
  bool handle(const SessionMessage& message) {
    if (!sender_) {
      const HelloMsg* hello = std::get_if<HelloMsg>(&message);
      if (!hello) {
        close("expected Hello as the first message");
        return false;
      }
      return onHello(*hello);
    }
    if (std::holds_alternative<HelloMsg>(message)) {
      close("a second Hello");
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
      close("bad message: " + status.error().message);
      return false;
    }
    return true;
  }

  bool onHello(const HelloMsg& hello) {
    name_ = hello.clientName.substr(0, 64);
    if (auto reject = checkHello(hello, server_.options.token)) {
      logWarn("client " + describe() + " rejected: " + reject->reason);
      ++server_.totals.rejected;
      // Nothing but the Reject goes out; the connection closes once it is written.
      closeAfterFlush_ = true;
      enqueue(share(encodeMessage(*reject)));
      return false;
    }
    const bool useUdp = !server_.options.tcpOnly && hello.wantsUdp && hello.udpPort != 0;
    if (useUdp) {
      boost::system::error_code ec;
      udpTarget_ = udp::endpoint(socket_.remote_endpoint(ec).address(), hello.udpPort);
      if (ec) {
        close("no remote address: " + ec.message());
        return false;
      }
    }
    SessionInfoMsg info;
    SharedBytes scene;
    {
      auto lock = server_.hub.lock();
      info = server_.hub.publisher().sessionInfo();
      sender_ = std::make_unique<StreamSender>(server_.hub.publisher(), id_, server_.options.sender);
      scene = server_.hub.sceneFrame();
      sceneSerialSent_ = server_.hub.sceneSerial();
    }
    logInfo("client " + describe() + " joined, session " + std::to_string(id_) +
            (useUdp ? ", datagrams over UDP to port " + std::to_string(hello.udpPort)
                 : ", datagrams over TCP"));
    enqueue(share(encodeMessage(WelcomeMsg{kProtocolVersion, id_})));
    enqueue(share(encodeMessage(info)));
    if (scene) enqueue(scene);
    return !closed_;
  }

  void enqueue(SharedBytes bytes) {
    if (closed_) return;
    if (queuedBytes_ + bytes->size() > server_.options.maxWriteQueueBytes) {
      return close("not reading: write queue over " +
                   std::to_string(server_.options.maxWriteQueueBytes) + " bytes");
    }
    queuedBytes_ += bytes->size();
    writes_.push_back(std::move(bytes));
    if (!writing_) writeNext();
  }

  void writeNext() {
    writing_ = true;
    writeStartedAt_ = steadySeconds();
    auto self = shared_from_this();
    asio::async_write(socket_, asio::buffer(*writes_.front()),
                      [self](boost::system::error_code ec, std::size_t n) { self->onWritten(ec, n); });
  }

  void onWritten(boost::system::error_code ec, std::size_t n) {
    if (closed_) return;
    if (ec) return close("write failed: " + ec.message());
    bytesSent_ += n;
    queuedBytes_ -= writes_.front()->size();
    writes_.pop_front();
    if (!writes_.empty()) return writeNext();
    writing_ = false;
    if (closeAfterFlush_) close("rejected");
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
  std::size_t pendingBricks_ = 0;
};

void NetServer::Impl::acceptNext() {
  acceptor.async_accept([this](boost::system::error_code ec, tcp::socket socket) {
    if (stopped) return;
    if (ec) {
      logWarn("accept: " + ec.message());
    } else if (sessions.size() >= options.maxClients) {
      logWarn("refusing a connection: " + std::to_string(options.maxClients) + " clients already");
    } else {
      const std::uint32_t id = nextSessionId++;
      auto session = std::make_shared<Session>(*this, std::move(socket), id);
      sessions[id] = session;
      ++totals.accepted;
      session->start();
    }
    acceptNext();
  });
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
  const double now = steadySeconds();
  // Copies: a session may close (and leave the map) while sending.
  std::vector<std::shared_ptr<Session>> list;
  for (auto& [id, s] : sessions) list.push_back(s);
  std::vector<std::vector<Bytes>> datagrams(list.size());
  std::vector<SharedBytes> scenes(list.size());
  {
    auto lock = hub.lock();
    const std::uint64_t serial = hub.sceneSerial();
    const SharedBytes frame = hub.sceneFrame();
    for (std::size_t i = 0; i < list.size(); ++i)
      list[i]->pollLocked(now, serial, frame, datagrams[i], scenes[i]);
  }
  for (std::size_t i = 0; i < list.size(); ++i)
    list[i]->send(now, std::move(datagrams[i]), scenes[i]);
  publishStats();
}

void NetServer::Impl::remove(std::uint32_t id, const std::string&) {
  auto it = sessions.find(id);
  if (it == sessions.end()) return;
  const NetClientInfo info = it->second->info(steadySeconds());
  totals.bytesSent += info.bytesSent;
  totals.bytesReceived += it->second->bytesReceived();
  ++totals.disconnected;
  // The map's reference goes after this call returns: the session is still running code.
  asio::post(io, [s = it->second] {});
  sessions.erase(it);
}

void NetServer::Impl::publishStats() {
  const double now = steadySeconds();
  NetServerStats s = totals;
  for (auto& [id, session] : sessions) {
    s.clients.push_back(session->info(now));
    s.bytesSent += s.clients.back().bytesSent;
    s.bytesReceived += session->bytesReceived();
  }
  std::lock_guard lock(statsMutex);
  snapshot = std::move(s);
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
  return std::unique_ptr<NetServer>(new NetServer(std::move(impl)));
}

void NetServer::start() {
  Impl& s = *impl_;
  s.acceptNext();
  s.schedulePoll();
  s.thread = std::thread([&s] { s.io.run(); });
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
    for (auto& session : list) session->close("server shutting down");
    s.udpSocket.close(ec);
    s.publishStats();
  });
  s.thread.join();
}

std::uint16_t NetServer::port() const { return impl_->tcpPort; }
std::uint16_t NetServer::udpPort() const { return impl_->udpPortNumber; }

NetServerStats NetServer::stats() const {
  std::lock_guard lock(impl_->statsMutex);
  return impl_->snapshot;
}

}  // namespace pc
