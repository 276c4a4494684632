#include "net_server.h"

#include <pthread.h>
#include <sys/socket.h>

#include <algorithm>
#include <array>
#include <boost/asio.hpp>
#include <cerrno>
#include <limits>
#include <map>
#include <mutex>
#include <random>
#include <thread>
#include <tuple>

#include "common/log.h"
#include "net_address_limits.h"
#include "net_server_impl.h"
#include "net_session.h"
#include "protocol/net_framing.h"
#include "protocol/session_messages.h"

namespace pc {

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
    case DisconnectCause::TlsHandshake:
      return "tls_handshake";
    case DisconnectCause::Rejected:
      return "rejected";
    case DisconnectCause::TooManyPending:
      return "too_many_pending";
    case DisconnectCause::AddressLimit:
      return "address_limit";
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
    case RejectCause::ClientLimit:
      return "client_limit";
    case RejectCause::AddressLimit:
      return "address_limit";
  }
  return "?";
}

namespace {

// The causes that refuse a message (Session::refuse), as opposed to timeouts and closes.
constexpr DisconnectCause kMessageCauses[] = {
    DisconnectCause::Malformed, DisconnectCause::Oversized, DisconnectCause::WrongDirection,
    DisconnectCause::Protocol,  DisconnectCause::Invalid,   DisconnectCause::Flood};

}  // namespace

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
  boost::system::error_code ec;
  const auto remote = socket.remote_endpoint(ec);
  if (ec) return;  // gone already
  const std::string key = addressKey(remote.address());
  std::optional<std::string> refusal;
  DisconnectCause cause = DisconnectCause::AddressLimit;
  if (sessions.size() - established >= options.maxPendingConnections) {
    // Too many connections still before their Hello: this one is not read at all (a full
    // server answers a Hello with a Reject, but only this many Hellos are awaited at once).
    cause = DisconnectCause::TooManyPending;
    refusal =
        std::to_string(options.maxPendingConnections) + " connections already awaiting their Hello";
  } else {
    refusal = addressLimits.admit(key, steadySeconds());
  }
  ++totals.accepted;
  if (refusal) return refuseAccepted(std::move(socket), key, cause, *refusal);
  const std::uint32_t id = nextSessionId++;
  auto session = std::make_shared<Session>(
      *this,
      tls ? net::SessionStream(std::move(socket), *tls) : net::SessionStream(std::move(socket)),
      id);
  session->setAddressKey(key);
  sessions[id] = session;
  session->start();
}

void NetServer::Impl::refuseAccepted(tcp::socket socket, const std::string& key,
                                     DisconnectCause cause, const std::string& detail) {
  ++totals.disconnected;
  ++totals.disconnects[std::size_t(cause)];
  boost::system::error_code ignored;
  socket.close(ignored);
  // One line per address every few seconds at most: refusals must not become a flood of log.
  std::uint64_t suppressed = 0;
  const std::string logKey = cause == DisconnectCause::TooManyPending ? "*" : key;
  if (!addressLimits.shouldLog(logKey, steadySeconds(), suppressed)) return;
  logEvent(
      LogLevel::Warn, "client disconnected",
      {{"peer", key}, {"cause", causeName(cause)}, {"detail", detail}, {"suppressed", suppressed}});
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

// An operator revokes a token by editing the list: read again within a second of a change.
void NetServer::Impl::reloadRevocations(double now) {
  if (options.revocationFile.empty() || now - revocationsCheckedAt < 1.0) return;
  revocationsCheckedAt = now;
  auto changed = verifier.reloadRevocations();
  if (!changed) {
    logWarn("revocation list: " + changed.error().message + " (the ids read before stay revoked)");
  } else if (*changed) {
    logInfo("revocation list " + options.revocationFile +
            " read again: " + std::to_string(verifier.revokedCount()) + " tokens revoked");
  }
}

// What a poll holds at once stays near this many bytes of datagrams (plus one session's burst)
// per polling thread, instead of every session's burst together: the datagrams of one slice of
// the sessions are built under the hub lock, then sent, before the next slice is polled. All
// senders' self-contained refreshes fall due in the same poll when clients joined together
// (every selfContainedInterval), and 100 clients then produced about 25 MB of datagrams at
// once; the heap kept that high-water mark, and the server's RSS stepped up every 30 s.
constexpr std::size_t kPollSliceBytes = 2u << 20;

void NetServer::Impl::poll() {
  const double now = steadySeconds();
  reloadRevocations(now);
  // Copies: a session may close (and leave the map) while sending.
  std::vector<std::shared_ptr<Session>> datagramSessions, others;
  for (auto& [id, s] : sessions) (s->overUdp() ? datagramSessions : others).push_back(s);
  double pollSeconds = 0;

  // Datagram sessions in parts, each polled, sealed and sent by one of the workers (this
  // thread among them) while the others do theirs: nothing of a session is shared with another
  // part but the publisher and the change cache, read under the hub's shared lock. More parts
  // than threads, because sessions differ in what they send and a thread that finishes its part
  // takes the next.
  if (!datagramSessions.empty()) {
    const std::size_t threads = std::size_t(workers->threads());
    const std::size_t parts = std::min(datagramSessions.size(), threads == 1 ? 1 : 4 * threads);
    std::vector<SharedBytes> scenes(datagramSessions.size());
    std::vector<PartFigures> figures;
    for (std::size_t p = 0; p < parts; ++p)
      figures.push_back({0, Histogram(sendQueueDelayBounds()), Histogram(updateLatencyBounds())});
    const std::span<const std::shared_ptr<Session>> all(datagramSessions);
    const std::span<SharedBytes> allScenes(scenes);
    workers->run(parts, [&](std::size_t p) {
      const std::size_t begin = all.size() * p / parts, end = all.size() * (p + 1) / parts;
      pollDatagramSessions(all.subspan(begin, end - begin), now,
                           allScenes.subspan(begin, end - begin), figures[p]);
    });
    for (const PartFigures& f : figures) {
      pollSeconds += f.pollSeconds;
      totals.sendQueueDelay.merge(f.queueDelay);
      totals.updateLatency.merge(f.updateLatency);
    }
    // Scene states and reports go on each session's stream, from this thread (the streams'
    // own).
    for (std::size_t i = 0; i < datagramSessions.size(); ++i)
      datagramSessions[i]->send(now, {}, scenes[i]);
  }

  // The other sessions (over TCP, or before their Welcome) on this thread alone.
  std::vector<std::vector<Bytes>> datagrams(others.size());
  std::vector<SharedBytes> scenes(others.size());
  std::size_t next = 0;
  while (next < others.size()) {
    const std::size_t first = next;
    {
      const double sliceStart = steadySeconds();
      auto lock = hub.lock();
      const std::uint64_t serial = hub.sceneSerial();
      const SharedBytes frame = hub.sceneFrame();
      std::size_t sliceBytes = 0;
      for (; next < others.size() && sliceBytes < kPollSliceBytes; ++next) {
        others[next]->pollLocked(now, serial, frame, datagrams[next], scenes[next]);
        for (const Bytes& d : datagrams[next]) sliceBytes += d.size();
      }
      pollSeconds += steadySeconds() - sliceStart;
    }
    // send() takes the datagrams and flushUdp() frees them, before the next slice is built.
    for (std::size_t i = first; i < next; ++i)
      others[i]->send(now, std::move(datagrams[i]), scenes[i]);
    flushUdp(udpBatch, totals.sendQueueDelay);
    // The slice's updates have left for their sockets (or write queues): their latency.
    const double sent = steadySeconds();
    for (std::size_t i = first; i < next; ++i) others[i]->observeSent(sent, totals.updateLatency);
  }

  {
    // The publisher's figures for the metrics, read while no sender runs.
    auto lock = hub.lock();
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
    totals.encodeTimes = publisher.encodeTimes();
  }
  publishStats(pollSeconds);
}

void NetServer::Impl::pollDatagramSessions(std::span<const std::shared_ptr<Session>> list,
                                           double now, std::span<SharedBytes> scenes,
                                           PartFigures& figures) {
  const std::size_t sliceBytes =
      std::max<std::size_t>(kPollSliceBytes / std::size_t(workers->threads()), 256u << 10);
  std::vector<std::vector<Bytes>> datagrams(list.size());
  std::vector<UdpOut> batch;
  std::size_t next = 0;
  while (next < list.size()) {
    const std::size_t first = next;
    {
      const double sliceStart = steadySeconds();
      auto lock = hub.sharedLock();
      const std::uint64_t serial = hub.sceneSerial();
      const SharedBytes frame = hub.sceneFrame();
      std::size_t bytes = 0;
      for (; next < list.size() && bytes < sliceBytes; ++next) {
        list[next]->pollLocked(now, serial, frame, datagrams[next], scenes[next]);
        for (const Bytes& d : datagrams[next]) bytes += d.size();
      }
      figures.pollSeconds += steadySeconds() - sliceStart;
    }
    for (std::size_t i = first; i < next; ++i) list[i]->sealDatagrams(now, datagrams[i], batch);
    flushUdp(batch, figures.queueDelay);
    const double sent = steadySeconds();
    for (std::size_t i = first; i < next; ++i) list[i]->observeSent(sent, figures.updateLatency);
  }
}

void NetServer::Impl::flushUdp(std::vector<UdpOut>& batch, Histogram& queueDelay) {
  // One system call per batch instead of one per datagram. A datagram the socket refuses (its
  // buffer is full) is dropped and the rest of the batch is tried, as a send_to per datagram
  // would. Several threads may send on the socket at once; each datagram goes whole.
  constexpr std::size_t kBatch = 256;
  std::array<mmsghdr, kBatch> messages;
  std::array<iovec, kBatch> vectors;
  const int fd = udpSocket.native_handle();
  std::size_t i = 0;
  while (i < batch.size()) {
    std::size_t n = 0;
    std::array<std::size_t, kBatch> index;
    for (std::size_t j = i; j < batch.size() && n < kBatch; ++j) {
      UdpOut& d = batch[j];
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
      batch[index[0]].session->udpSent(0, false);
      sent = 1;
    } else {
      const double at = steadySeconds();
      for (int m = 0; m < sent; ++m) {
        const UdpOut& d = batch[index[m]];
        d.session->udpSent(d.bytes.size(), true);
        queueDelay.observe(at - d.queuedAt);
      }
    }
    i = index[std::size_t(sent) - 1] + 1;
  }
  batch.clear();
}

void NetServer::Impl::receiveUdp() {
  udpSocket.async_wait(udp::socket::wait_read, [this](boost::system::error_code ec) {
    if (ec || stopped) return;
    drainUdp();
    receiveUdp();
  });
}

void NetServer::Impl::receiveLoadQueries() {
  if (!loadSocket.is_open()) return;
  loadSocket.async_wait(udp::socket::wait_read, [this](boost::system::error_code ec) {
    if (ec || stopped) return;
    answerLoadQueries();
    receiveLoadQueries();
  });
}

void NetServer::Impl::answerLoadQueries() {
  // A few per turn of the event loop, as drainUdp reads: a flood of queries waits in the
  // socket's buffer (or is lost there) rather than holding up the sessions.
  constexpr int kPerTurn = 64;
  for (int i = 0; i < kPerTurn && !stopped; ++i) {
    std::array<std::uint8_t, 2 * net::kLoadQueryBytes> in{};
    udp::endpoint from;
    boost::system::error_code ec;
    const std::size_t n = loadSocket.receive_from(asio::buffer(in), from, 0, ec);
    if (ec) return;  // nothing more now
    if (!answerLoadQuery(loadSocket, std::span(in.data(), n), from)) ++totals.loadMalformed;
  }
}

bool NetServer::Impl::answerLoadQuery(udp::socket& socket, std::span<const std::uint8_t> bytes,
                                      const udp::endpoint& from) {
  const auto nonce = net::decodeLoadQuery(bytes);
  if (!nonce) return false;
  // The answer is no larger than the query, and their number is capped: a forged source
  // address turns this into neither an amplifier nor a flood.
  const double now = steadySeconds();
  loadTokens =
      std::min(kLoadAnswersPerSecond, loadTokens + (now - loadTokensAt) * kLoadAnswersPerSecond);
  loadTokensAt = now;
  if (loadTokens < 1) {
    ++totals.loadLimited;
    return true;
  }
  loadTokens -= 1;
  net::EndpointLoad load;
  load.clients = std::uint32_t(sessions.size());
  load.maxClients = std::uint32_t(options.maxClients);
  load.ready = options.ready ? options.ready() : true;
  const net::LoadDatagram reply = net::encodeLoadReply(*nonce, load);
  boost::system::error_code ec;
  socket.send_to(asio::buffer(reply), from, 0, ec);
  ++totals.loadAnswered;
  return true;
}

void NetServer::Impl::drainUdp() {
  // recvmmsg: one system call per batch of datagrams. A few batches per turn of the event
  // loop at most, so that a flood of datagrams cannot hold up the sessions' streams and polls
  // (the rest wait in the socket's buffer, or are lost there, as UDP may be).
  constexpr int kBatchesPerTurn = 8;
  std::array<mmsghdr, kUplinkBatch> messages;
  std::array<iovec, kUplinkBatch> vectors;
  const int fd = udpSocket.native_handle();
  for (int turn = 0; turn < kBatchesPerTurn && !stopped; ++turn) {
    for (std::size_t i = 0; i < kUplinkBatch; ++i) {
      vectors[i] = iovec{uplinkBuffers[i].data(), uplinkBuffers[i].size()};
      messages[i] = mmsghdr{};
      messages[i].msg_hdr.msg_name = uplinkFrom[i].data();
      messages[i].msg_hdr.msg_namelen = socklen_t(uplinkFrom[i].capacity());
      messages[i].msg_hdr.msg_iov = &vectors[i];
      messages[i].msg_hdr.msg_iovlen = 1;
    }
    const int n = ::recvmmsg(fd, messages.data(), unsigned(kUplinkBatch), MSG_DONTWAIT, nullptr);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return;  // would block (or an error the next wait reports)
    const double now = steadySeconds();
    for (int i = 0; i < n; ++i) {
      uplinkFrom[i].resize(messages[i].msg_hdr.msg_namelen);
      const bool truncated = (messages[i].msg_hdr.msg_flags & MSG_TRUNC) != 0;
      onUplink(std::span<const std::uint8_t>(uplinkBuffers[i].data(), messages[i].msg_len),
               truncated, uplinkFrom[i], now);
    }
    if (std::size_t(n) < kUplinkBatch) return;
  }
}

void NetServer::Impl::onUplink(std::span<const std::uint8_t> bytes, bool truncated,
                               const udp::endpoint& from, double now) {
  // Where the datagram socket has the session port's number, load queries come to it too.
  if (loadOnDatagramSocket && answerLoadQuery(udpSocket, bytes, from)) return;
  // Before authentication a datagram costs a header check, a lookup and a counter.
  ++totals.uplinkDatagrams;
  if (truncated || bytes.size() > kMaxUplinkDatagramBytes) return dropUplink(UplinkDrop::Oversized);
  const std::optional<UplinkHeader> header = peekUplink(bytes);
  if (!header) return dropUplink(UplinkDrop::Malformed);
  const auto it = sessions.find(header->sessionId);
  if (it == sessions.end()) return dropUplink(UplinkDrop::UnknownSession);
  // The session may close while handling it: held until it returns.
  const std::shared_ptr<Session> session = it->second;
  if (const std::optional<UplinkDrop> drop = session->onUplink(bytes, from, now)) dropUplink(*drop);
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
  totals.acksTcp += info.acksTcp;
  totals.acksUdp += info.acksUdp;
  totals.repairsTcp += info.repairsTcp;
  totals.repairsUdp += info.repairsUdp;
  totals.tcpQueueFullPolls += it->second->tcpQueueFullPolls();
  ++totals.disconnected;
  ++totals.disconnects[std::size_t(cause)];
  const bool welcomed = it->second->welcomed();
  if (welcomed) --established;
  addressLimits.release(it->second->addressKey(), welcomed);
  if (welcomed) addressLimits.releaseClient(it->second->clientKey());
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
    s.acksTcp += c.acksTcp;
    s.acksUdp += c.acksUdp;
    s.repairsTcp += c.repairsTcp;
    s.repairsUdp += c.repairsUdp;
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
  appendBuildInfo(text, options.buildInfo);
  appendServerMetrics(text, s);
  appendProcessMetrics(text);
  std::lock_guard lock(extraMutex);
  if (extraMetrics) extraMetrics(text);
  return text.str();
}

namespace {

// Mean of a histogram's observations between two snapshots, in ms; 0 without any.
double meanMsBetween(const Histogram& now, const Histogram& before) {
  const std::uint64_t n = now.count() - std::min(now.count(), before.count());
  return n > 0 ? (now.sum() - before.sum()) / double(n) * 1e3 : 0.0;
}

}  // namespace

std::vector<LogField> statisticsFields(const NetServerStats& now, const NetServerStats& before,
                                       double seconds) {
  const double s = std::max(seconds, 1e-9);
  const auto perSecond = [s](std::uint64_t a, std::uint64_t b) {
    return double(a - std::min(a, b)) / s;
  };
  return {{"interval_s", seconds},
          {"clients", now.clients.size()},
          {"connections", now.connections},
          {"sent_kbit_s", perSecond(now.bytesSent, before.bytesSent) * 8 / 1e3},
          {"received_kbit_s", perSecond(now.bytesReceived, before.bytesReceived) * 8 / 1e3},
          {"datagrams_s", perSecond(now.datagrams, before.datagrams)},
          {"update_latency_mean_ms", meanMsBetween(now.updateLatency, before.updateLatency)},
          {"send_queue_delay_mean_ms", meanMsBetween(now.sendQueueDelay, before.sendQueueDelay)},
          {"encodes_s", perSecond(now.encodes, before.encodes)},
          {"field_version", now.fieldVersion},
          {"accepted_total", now.accepted},
          {"sessions_total", now.sessions},
          {"rejected_total", now.rejected},
          {"disconnected_total", now.disconnected},
          {"resends_total", now.resends},
          {"udp_send_drops_total", now.udpDropped}};
}

std::vector<LogField> clientStatisticsFields(const NetClientInfo& c) {
  return {{"session", c.sessionId},
          {"name", escapeUntrusted(c.name, 64)},
          {"peer", c.peer},
          {"transport", c.udp ? "udp" : "tcp"},
          {"connected_s", c.connectedSeconds},
          {"sent_bytes", c.bytesSent},
          {"datagrams", c.datagrams},
          {"pending_bricks", c.pendingBricks},
          {"resends", c.resends},
          {"held_psnr_db", double(c.report.heldPsnrDb)},
          {"send_rate_kbit_s", double(c.report.rate) * 8 / 1e3},
          {"queue_delay_ms", double(c.report.queueDelayMs)},
          {"loss", double(c.report.loss)},
          {"quality_level", double(c.report.qualityLevel)}};
}

void appendBuildInfo(MetricsText& m, const BuildInfo& info) {
  if (info.version.empty()) return;
  m.gauge("probecast_build_info", "What the program was built from (always 1).", 1.0,
          {{"version", info.version}, {"revision", info.revision}, {"build_type", info.buildType}});
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
  for (std::size_t c = 0; c < kTokenErrorCount; ++c) {
    m.counter("probecast_token_rejections_total",
              "Hellos rejected for their connect token, by cause.", double(s.tokenRejects[c]),
              {{"cause", std::string(tokenErrorName(TokenError(c)))}});
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
  for (const auto& [transport, acks, repairs] :
       {std::tuple{"tcp", s.acksTcp, s.repairsTcp}, std::tuple{"udp", s.acksUdp, s.repairsUdp}}) {
    m.counter("probecast_acks_received_total", "Acks taken from clients, by transport.",
              double(acks), {{"transport", transport}});
    m.counter("probecast_repair_requests_received_total",
              "Repair requests taken from clients, by transport.", double(repairs),
              {{"transport", transport}});
  }
  for (const auto& [outcome, n] :
       {std::pair{"resumed", s.resumes}, std::pair{"other_field", s.resumeMismatches}}) {
    m.counter("probecast_resumes_total",
              "Resume messages of clients moving from another endpoint, by outcome: the claim "
              "taken, or of another field (a full resync).",
              double(n), {{"outcome", outcome}});
  }
  for (const auto& [outcome, n] :
       {std::pair{"held", s.resumedBricks}, std::pair{"refused", s.resumeRefusedBricks}}) {
    m.counter("probecast_resume_bricks_total",
              "Bricks resuming clients claimed, by outcome: taken as held, or refused for a "
              "version past this server's newest (sent whole).",
              double(n), {{"outcome", outcome}});
  }
  for (const auto& [outcome, n] :
       {std::pair{"applied", s.editsApplied}, std::pair{"invalid", s.editsInvalid},
        std::pair{"denied", s.editsDenied}}) {
    m.counter("probecast_edits_total",
              "Edit messages of clients, by outcome: applied, refused for their values (or on an "
              "endpoint that takes none), refused for a token without the editor role.",
              double(n), {{"outcome", outcome}});
  }
  m.counter("probecast_uplink_datagrams_total",
            "Datagrams received on the UDP port (client acks and repair requests, and anything "
            "else sent there).",
            double(s.uplinkDatagrams));
  for (auto [outcome, n] :
       {std::pair{"answered", s.loadAnswered}, std::pair{"limited", s.loadLimited},
        std::pair{"malformed", s.loadMalformed}}) {
    m.counter("probecast_load_queries_total",
              "Load queries on UDP at the session port, by outcome: answered, left unanswered "
              "for the cap on answers per second, or not a query.",
              double(n), {{"outcome", outcome}});
  }
  for (std::size_t c = 0; c < kUplinkDropCount; ++c) {
    m.counter("probecast_uplink_dropped_total",
              "Datagrams on the UDP port dropped unanswered, by cause.", double(s.uplinkDrops[c]),
              {{"cause", std::string(uplinkDropName(UplinkDrop(c)))}});
  }
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
  m.histogram("probecast_update_latency_seconds",
              "From a brick version's publish to its first datagram to a client leaving for the "
              "socket (UDP) or the write queue (TCP), per update and client.",
              s.updateLatency);
  m.histogram("probecast_encode_duration_seconds", "Encode time of each brick update.",
              s.encodeTimes);
  m.histogram("probecast_send_queue_delay_seconds",
              "Time a datagram or frame waited between being queued for a client and its socket "
              "taking it (a poll's UDP batch; the TCP write queue to a completed write).",
              s.sendQueueDelay);
}

namespace {

// The box of every cascade's probe grid, grown by half its largest side: a viewer that far
// outside the field still sees into it, one farther away gains nothing from probes near it.
void setViewerBounds(NetServer::Impl& s, const SessionInfoMsg& info) {
  glm::vec3 lo(std::numeric_limits<float>::max()), hi(std::numeric_limits<float>::lowest());
  for (const gpu::CascadeDesc& c : info.cascades) {
    const glm::vec3 far = c.origin + c.spacing * glm::vec3(c.counts - 1);
    lo = glm::min(lo, glm::min(c.origin, far));
    hi = glm::max(hi, glm::max(c.origin, far));
  }
  if (info.cascades.empty()) lo = hi = glm::vec3(0.0f);
  const glm::vec3 extent = hi - lo;
  const float margin = 0.5f * std::max({extent.x, extent.y, extent.z, 1.0f});
  s.viewerMin = lo - margin;
  s.viewerMax = hi + margin;
}

}  // namespace

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
  // Datagrams leave from the UDP port (any free one by default), and clients' acks come to it
  // (SessionInfo names it): clients receive datagrams wherever they come from (the seal says
  // whether to trust one).
  s.udpSocket.open(udp::v4(), ec);
  if (!ec) s.udpSocket.bind(udp::endpoint(address, s.options.udpPort), ec);
  if (ec) {
    return Error{"cannot open the UDP socket on " + s.options.bindAddress + ":" +
                 std::to_string(s.options.udpPort) + ": " + ec.message()};
  }
  s.udpSocket.non_blocking(true, ec);
  s.udpSocket.set_option(asio::socket_base::send_buffer_size(4 << 20), ec);
  // Room for every client's acks of a few polls while the thread is busy (about 50 a second
  // per client, each under 100 bytes of payload).
  s.udpSocket.set_option(asio::socket_base::receive_buffer_size(1 << 20), ec);
  s.udpPortNumber = s.udpSocket.local_endpoint().port();
  // Load queries come to the session's port number over UDP: to the datagram socket where it
  // has that number (--udp-port the same as --port, as containers publish it), else to a socket
  // of their own. A port that is taken by another program costs only the answers: clients then
  // rank this server as silent.
  s.loadOnDatagramSocket = s.options.answerLoadQueries && s.udpPortNumber == s.tcpPort;
  if (s.options.answerLoadQueries && !s.loadOnDatagramSocket) {
    boost::system::error_code loadError;
    s.loadSocket.open(udp::v4(), loadError);
    if (!loadError) s.loadSocket.bind(udp::endpoint(address, s.tcpPort), loadError);
    if (!loadError) s.loadSocket.non_blocking(true, loadError);
    if (loadError) {
      logWarn("load queries: cannot bind UDP " + s.options.bindAddress + ":" +
              std::to_string(s.tcpPort) + " (" + loadError.message() +
              "); clients will not see this server's load");
      s.loadSocket.close(loadError);
    }
  }
  // Session ids start at a random point, so a restarted server never reuses its old ids and
  // a client's stale datagrams from before the restart are refused.
  std::random_device rd;
  s.nextSessionId = (std::uint32_t(rd()) & 0x7FFF'FFFFu) | 1u;

  {
    auto lock = hub.lock();
    for (int k = 0; k < hub.publisher().cascadeCount(); ++k)
      s.fieldBricks += std::size_t(hub.publisher().brickCount(k));
    setViewerBounds(s, hub.publisher().sessionInfo());
  }
  const int sendThreads = s.options.sendThreads > 0
                              ? std::min(s.options.sendThreads, 64)
                              : std::clamp(int(std::thread::hardware_concurrency()) / 2, 1, 8);
  // Named as the network thread: CPU figures by thread name (probecast-bench load) count them
  // together.
  s.workers = std::make_unique<NetWorkers>(sendThreads, "pc-net");
  AddressLimitOptions limits;
  limits.maxPendingPerAddress = s.options.maxPendingPerAddress;
  limits.maxSessionsPerAddress = s.options.maxSessionsPerAddress;
  limits.handshakesPerSecond = s.options.handshakesPerSecondPerAddress;
  limits.handshakeBurst = std::max(1.0, 2 * s.options.handshakesPerSecondPerAddress);
  limits.maxSessionsPerClient = s.options.maxSessionsPerClient;
  s.addressLimits = AddressLimits(limits);
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

  if (s.options.tokenKeys.empty())
    return Error{"no token verify key: clients could not authenticate (see probecast-token)"};
  for (const VerifyKey& key : s.options.tokenKeys) s.verifier.addKey(key);
  if (!s.options.revocationFile.empty()) {
    if (Status st = s.verifier.loadRevocations(s.options.revocationFile); !st)
      return Error{"revocation list: " + st.error().message};
  }

  if (s.options.tls.enabled) {
    net::TlsServerSettings settings;
    settings.certificateFile = s.options.tls.certificateFile;
    settings.keyFile = s.options.tls.keyFile;
    settings.devSelfSigned = s.options.tls.devSelfSigned;
    settings.devCertificateOut = s.options.tls.devCertificateOut;
    settings.devCertificate = s.options.tls.devCertificate;
    auto tls = net::makeTlsServer(settings);
    if (!tls) return Error{"TLS: " + tls.error().message};
    s.tls = std::move(tls->context);
    s.tlsFingerprint = tls->fingerprint;
  }

  if (s.options.metricsPort) {
    MetricsHttpOptions mo;
    mo.bindAddress =
        s.options.metricsBindAddress.empty() ? "127.0.0.1" : s.options.metricsBindAddress;
    mo.bearerToken = s.options.metricsToken;
    mo.port = *s.options.metricsPort;
    mo.ready = s.options.ready;
    auto metrics = MetricsHttpServer::create(mo, [&s] { return s.renderMetrics(); });
    if (!metrics) return metrics.error();
    s.metrics = std::move(metrics).value();
  }
  return std::unique_ptr<NetServer>(new NetServer(std::move(impl)));
}

void NetServer::start() {
  Impl& s = *impl_;
  s.acceptNext();
  s.receiveUdp();
  s.receiveLoadQueries();
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
    s.loadSocket.close(ec);
    s.publishStats();
  });
  s.thread.join();
  // The endpoint goes last, so a scrape during shutdown still sees the final counts.
  s.metrics.reset();
}

std::uint16_t NetServer::port() const { return impl_->tcpPort; }
const std::string& NetServer::tlsFingerprint() const { return impl_->tlsFingerprint; }

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
