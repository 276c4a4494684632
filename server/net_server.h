// The server's network layer: a TCP listener for sessions (hello with a shared-secret token,
// session info, scene-state sync, acks, repair requests and viewer poses from clients) and one
// UDP socket for brick datagrams, all on one network thread running a Boost.Asio io_context.
// Every client has its own StreamSender (reading the hub's shared publisher) and a bounded TCP
// write queue. Every client is held to limits (NetServerOptions): a client that sends anything
// malformed, oversized, in the wrong direction or out of order, floods, or stops reading, is
// disconnected with its cause logged and counted (NetServerStats), and no other client
// notices. Optionally Prometheus metrics over HTTP (net_metrics.h). Asio stays inside the
// network layer's sources and its internal headers (net_server_impl.h, net_session.h).
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/histogram.h"
#include "common/log.h"
#include "common/result.h"
#include "common/scene_edits.h"
#include "net_hub.h"
#include "net_metrics.h"
#include "protocol/stream_sender.h"
#include "protocol/uplink_datagram.h"

namespace pc::net {
struct DevCertificate;  // net/tls_certificate.h
}

namespace pc {

// Why a connection ended: the label of probecast_disconnects_total and the `cause` field of
// the "client disconnected" log event (causeName).
enum class DisconnectCause {
  ClientClosed,  // the client closed the connection, or it broke (read or write error)
  HelloTimeout,  // no Hello within helloTimeout
  Silent,        // no message within silenceTimeout
  NotReading,    // write queue over maxWriteQueueBytes, or no write progress for writeStallSeconds
  Malformed,     // a frame or message that does not decode
  Oversized,     // a frame announcing more than the cap (refused before it is read)
  WrongDirection,  // a message only the server sends (Welcome, Reject, SessionInfo,
                   // SceneState), or a datagram frame
  Protocol,        // out of order: something else before the Hello, or a second Hello
  Invalid,         // decodes, but names bricks outside the field or more bricks than it holds
  Flood,           // more messages or bytes per second than the caps allow
  Rejected,        // the handshake was refused (see RejectCause); the Reject was written
  TlsHandshake,    // the TLS handshake failed (not TLS, no common cipher, a bad certificate)
  TooManyPending,  // accepted over maxPendingConnections: closed at once
  AddressLimit,    // over a cap of its remote address (pending, sessions, handshake rate):
                   // closed at once, nothing read
  Shutdown,        // the server stopped
};
inline constexpr std::size_t kDisconnectCauses = std::size_t(DisconnectCause::Shutdown) + 1;
const char* causeName(DisconnectCause cause);

// Why a Hello was answered with a Reject: the label of probecast_sessions_rejected_total.
// ClientLimit: the client identity already holds maxSessionsPerClient sessions.
enum class RejectCause { Auth, Version, ServerFull, ClientLimit, AddressLimit };
inline constexpr std::size_t kRejectCauses = std::size_t(RejectCause::AddressLimit) + 1;
const char* causeName(RejectCause cause);

// TLS 1.3 on every session stream (net/tls_context.h); the datagram keys come from it. Off
// only where both ends are told so (benchmarks of its cost, a trusted loopback): then
// datagrams travel unsealed too.
struct ServerTlsOptions {
  bool enabled = true;
  std::string certificateFile, keyFile;  // PEM
  bool devSelfSigned = false;            // a certificate made at start (tests, development)
  std::string devCertificateOut;         // where to write it as PEM, for clients' --ca-file
  // That certificate, made by the caller; null: one made by create().
  std::shared_ptr<const net::DevCertificate> devCertificate;
};

// What the running program was built from: the probecast_build_info metric's labels.
struct BuildInfo {
  std::string version, revision, buildType;
};

struct NetServerOptions {
  std::string bindAddress = "0.0.0.0";
  std::uint16_t port = 7450;  // TCP; 0 picks a free one (see NetServer::port)
  // The UDP socket's port: datagrams leave from it and clients' acks come to it (SessionInfo
  // names it). 0: a free one (NetServer::udpPort); a fixed one where a firewall or a
  // container's published ports must name it.
  std::uint16_t udpPort = 0;
  // Answer load queries on UDP at the session port's number (net/load_probe.h), so that
  // clients given several endpoints pick the least loaded.
  bool answerLoadQueries = true;
  // Connect tokens (protocol/connect_token.h): a Hello must carry a token signed by one of
  // these verify keys, not expired, not on the revocation list (re-read while serving when
  // the file changes), naming sceneName or any scene.
  std::vector<VerifyKey> tokenKeys;
  std::string revocationFile;
  std::string sceneName = "builtin";
  ServerTlsOptions tls;
  bool tcpOnly = false;  // datagrams framed over TCP for every client
  // Per-client send rate: sender.bytesPerSecond (token bucket, datagram bytes).
  SenderOptions sender;
  // Sessions past the handshake; a Hello beyond this gets a Reject ("server full").
  std::size_t maxClients = 64;
  // Connections still before their Hello; one more is closed as soon as it is accepted, so
  // unauthenticated peers never hold more than this many sockets and 4 KiB buffers (for at
  // most helloTimeout each). Generous: many clients joining at once are all pending for a
  // moment.
  std::size_t maxPendingConnections = 256;
  // Per remote address (an IPv4 address, an IPv6 /64), so that one address cannot take the
  // places every other client needs: connections before their Hello, sessions, and handshakes
  // started per second (a token bucket holding two seconds' worth). A connection over a cap
  // is closed as soon as it is accepted, nothing read (DisconnectCause::AddressLimit), and
  // logged at most once per address every few seconds. 0 turns a cap off.
  std::size_t maxPendingPerAddress = 8;
  std::size_t maxSessionsPerAddress = 16;
  double handshakesPerSecondPerAddress = 4;
  // Sessions one client identity (the Hello's client name) may hold at once; a Hello beyond
  // it gets a Reject (RejectCause::ClientLimit). 0: no cap.
  std::size_t maxSessionsPerClient = 4;
  // Largest frame an authenticated client may send, checked on the 4-byte prefix before
  // anything is allocated. 0: derived from the field, room for a full ack or repair request
  // naming every brick (32 bytes a brick + 4 KiB, at least 64 KiB, at most the protocol's
  // 4 MiB). Before the Hello the cap is 4 KiB.
  std::size_t maxMessageBytes = 0;
  // Flood: a client may send this many messages, and bytes, per second, with a burst of one
  // second's worth. A well-behaved client sends about 60 messages a second (acks every 20 ms,
  // poses every 100 ms, a full ack every second) plus repair requests under loss.
  double maxMessagesPerSecond = 1000;
  double maxReceiveBytesPerSecond = 0;  // 0: max(1 MiB, 4 x the message cap)
  // A client's queued TCP bytes beyond this, or a write that makes no progress for this long,
  // means it is not reading: it is disconnected rather than buffered for.
  std::size_t maxWriteQueueBytes = 4u << 20;
  double writeStallSeconds = 5.0;
  // TCP-only mode polls a client's sender only while less than this is queued, so a slow
  // client gets the newest state instead of a backlog (the sender keeps one entry per brick).
  std::size_t tcpDatagramQueueBytes = 256u << 10;
  double helloTimeout = 5.0;     // s from accept to a Hello
  double silenceTimeout = 10.0;  // s without any message from a client (full acks come every 1 s)
  double pollInterval = 0.005;   // s between sender polls
  // Threads that poll, seal and send the datagram sessions (the network thread among them);
  // 0: half the cores, 1 to 8. One thread's share of a 1 Mbit/s client is about 1 ms of CPU a
  // second (probecast-bench load), so one thread serves several hundred at most.
  int sendThreads = 0;
  // Prometheus metrics (GET /metrics over HTTP) on this port; nothing: no endpoint; 0: any
  // free port (NetServer::metricsPort). Bound on metricsBindAddress, else on loopback only
  // (127.0.0.1): the figures name clients and their addresses. With a metricsToken, a
  // request must carry `Authorization: Bearer <token>` (else 401).
  std::optional<std::uint16_t> metricsPort;
  std::string metricsBindAddress;
  std::string metricsToken;
  // What the endpoint's GET /readyz answers: 200 when this returns true, else 503 (empty:
  // always ready); GET /healthz answers 200 (MetricsHttpOptions). Called on the metrics thread.
  std::function<bool()> ready;
  // Labels of probecast_build_info (the tools pass theirs: tools/build_info.h); empty: the
  // metric is left out.
  BuildInfo buildInfo;
  // Runtime edits (PROTOCOL.md "Runtime edits"): called on the network thread with an Edit of
  // a session whose token has the editor role; it applies the edit or returns an Error naming
  // what was wrong, which the client hears in its EditResult. Empty: this endpoint takes no
  // edits (a relay), and every Edit is refused.
  std::function<Result<EditOutcome>(const SceneEdit&)> edits;
};

struct NetClientInfo {
  std::uint32_t sessionId = 0;
  std::string name, peer;
  bool udp = false;
  double connectedSeconds = 0;
  std::uint64_t bytesSent = 0, datagrams = 0, udpDropped = 0;
  std::uint64_t bytesReceived = 0, messagesReceived = 0;
  std::size_t pendingBricks = 0;
  // Loss recovery by the sender: whole updates sent again, and fragments sent again on the
  // client's report of what a partial update lacks (PROTOCOL.md, "Fragment gaps").
  std::uint64_t resends = 0, repairedFragments = 0;
  // Acks and repair requests taken, by the way they came: the session stream, or datagrams
  // to the UDP port (protocol version 6, PROTOCOL.md "Acks over UDP").
  std::uint64_t acksTcp = 0, acksUdp = 0, repairsTcp = 0, repairsUdp = 0;
  // The latest StreamReport (send rate, quality level, held field); zeros for clients of
  // protocol version 2 and before the first one.
  StreamReportMsg report;
};

// Histogram buckets: 1 ms to 4.1 s for latency (the sender's age bound is 1 s), 10 us to
// 1.3 s for queueing (a loopback datagram waits microseconds, a stalled TCP client seconds).
inline std::vector<double> updateLatencyBounds() { return exponentialBounds(0.001, 2.0, 13); }
inline std::vector<double> sendQueueDelayBounds() { return exponentialBounds(1e-5, 2.0, 18); }

struct NetServerStats {
  std::uint64_t accepted = 0;      // TCP connections accepted
  std::uint64_t sessions = 0;      // handshakes completed (Welcome sent)
  std::uint64_t rejected = 0;      // Hellos answered with a Reject (sum of rejects)
  std::uint64_t disconnected = 0;  // connections ended (sum of disconnects)
  std::array<std::uint64_t, kRejectCauses> rejects{};
  // Hellos rejected for their connect token, by TokenError (in rejects as Auth too).
  std::array<std::uint64_t, kTokenErrorCount> tokenRejects{};
  std::array<std::uint64_t, kDisconnectCauses> disconnects{};
  // Messages refused (each ends its session), by the cause it was disconnected with.
  std::array<std::uint64_t, kDisconnectCauses> rejectedMessages{};
  std::uint64_t bytesSent = 0, bytesReceived = 0, messagesReceived = 0;
  std::uint64_t datagrams = 0, udpDropped = 0;
  std::uint64_t resends = 0, repairedFragments = 0;  // NetClientInfo's, summed
  std::uint64_t acksTcp = 0, acksUdp = 0, repairsTcp = 0, repairsUdp = 0;  // likewise
  // Resume messages (PROTOCOL.md "Resuming a session"): claims taken, claims of another field,
  // bricks taken as held, bricks refused for a version past the newest.
  std::uint64_t resumes = 0, resumeMismatches = 0, resumedBricks = 0, resumeRefusedBricks = 0;
  // Edit messages (PROTOCOL.md "Runtime edits"): applied; refused for their values (or on an
  // endpoint that takes none); refused because the session's token is not an editor's.
  std::uint64_t editsApplied = 0, editsInvalid = 0, editsDenied = 0;
  // Datagrams to the UDP port that were dropped unanswered, by UplinkDrop.
  std::array<std::uint64_t, kUplinkDropCount> uplinkDrops{};
  std::uint64_t uplinkDatagrams = 0;  // received on the UDP port, dropped or not
  // Load queries (PROTOCOL.md "Choosing an endpoint by load"): answered, not answered for the
  // cap on answers per second, not a query.
  std::uint64_t loadAnswered = 0, loadLimited = 0, loadMalformed = 0;
  // Sender polls skipped because a TCP-only client's write queue was full (the client gets
  // the newest state later instead of a backlog).
  std::uint64_t tcpQueueFullPolls = 0;
  double senderPollSeconds = 0;  // network thread time in the senders (picking, encoding)
  std::size_t connections = 0;   // open, handshake or not
  // From the publisher, read while polling: newest field version, encoded updates and the
  // time spent on them, encode cache size.
  std::uint64_t fieldVersion = 0, encodes = 0;
  double encodeSeconds = 0;
  // Memory the publisher and the senders share, in bytes (see FieldPublisher): encoded
  // updates, the brick history beyond the current versions, the current versions, and the
  // shared perceptual comparisons (estimated); the bounds the first two stay within.
  std::size_t encodeCacheBytes = 0, encodeCacheEntries = 0, encodeCacheBoundBytes = 0;
  std::size_t historyBytes = 0, historyBoundBytes = 0, currentBricksBytes = 0;
  std::size_t changeCacheBytes = 0, changeCacheEntries = 0;
  // Seconds from a brick version's publish (the field version's publish time, which clients
  // measure their latency from) to its first datagram to a client leaving for the socket
  // (UDP) or the session's write queue (TCP); one observation per brick update and client.
  Histogram updateLatency{updateLatencyBounds()};
  // Seconds a datagram or session frame waited between being queued for a client and its
  // socket taking it (the UDP batch of a poll; the TCP write queue to a completed write).
  Histogram sendQueueDelay{sendQueueDelayBounds()};
  // Seconds of each brick update's encode (the publisher's cache misses).
  Histogram encodeTimes{encodeTimeBounds()};
  std::vector<NetClientInfo> clients;  // sessions past the handshake

  std::uint64_t disconnectsBy(DisconnectCause c) const { return disconnects[std::size_t(c)]; }
  std::uint64_t rejectsBy(RejectCause c) const { return rejects[std::size_t(c)]; }
};

// Appends the server's metrics (probecast_*) to `out`.
void appendServerMetrics(MetricsText& out, const NetServerStats& stats);
// The periodic statistics as named fields (the "statistics" record of a JSON log): the
// interval's rates from two snapshots `seconds` apart, and the totals of `now`.
std::vector<LogField> statisticsFields(const NetServerStats& now, const NetServerStats& before,
                                       double seconds);
// One client's figures (the "client statistics" record).
std::vector<LogField> clientStatisticsFields(const NetClientInfo& client);
// probecast_build_info{version,revision,build_type} 1, where `info` names a version.
void appendBuildInfo(MetricsText& out, const BuildInfo& info);

class NetServer {
 public:
  // Binds the listener and the UDP socket; an Error says what could not be bound.
  static Result<std::unique_ptr<NetServer>> create(FieldHub& hub, NetServerOptions options);
  ~NetServer();  // stop()
  NetServer(const NetServer&) = delete;
  NetServer& operator=(const NetServer&) = delete;

  // Runs the network thread. Times are on steadySeconds(), which the field thread publishes with.
  void start();
  // Closes every session and the sockets, joins the thread. Idempotent.
  void stop();
  std::uint16_t port() const;
  std::uint16_t udpPort() const;
  // "sha256:<hex>" of the server's TLS certificate, for clients to pin; empty without TLS.
  const std::string& tlsFingerprint() const;
  // The metrics endpoint's port; 0 without one.
  std::uint16_t metricsPort() const;
  NetServerStats stats() const;
  // More metrics for every scrape (the field thread's, say): called on the metrics thread.
  void setExtraMetrics(std::function<void(MetricsText&)> extra);

  struct Impl;

 private:
  explicit NetServer(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace pc
