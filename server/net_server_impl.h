// Internal to the server's network layer (net_server.cpp, net_session.cpp): the state the
// network thread keeps for the listener, the UDP socket and every session.
#pragma once

// clang-format off
#include <utility>  // first: Boost.Asio 1.74 uses std::exchange without including it
// clang-format on
#include <array>
#include <boost/asio.hpp>
#include <map>
#include <memory>
#include <mutex>
#include <span>
#include <thread>
#include <vector>

#include "net/load_probe.h"
#include "net/tls_context.h"
#include "net_address_limits.h"
#include "net_server.h"
#include "net_workers.h"

namespace pc {

namespace asio = boost::asio;
using asio::ip::tcp;
using asio::ip::udp;
using Bytes = std::vector<std::uint8_t>;
using SharedBytes = std::shared_ptr<const Bytes>;

inline SharedBytes share(Bytes bytes) { return std::make_shared<const Bytes>(std::move(bytes)); }

class Session;

// A datagram of one poll, sealed, to be sent with the others (sendmmsg) once every session of
// its part was polled.
struct UdpOut {
  Session* session;  // kept alive by the poll's list of sessions
  udp::endpoint to;
  Bytes bytes;
  double queuedAt;  // steadySeconds() when the session queued it
};

struct NetServer::Impl {
  Impl(FieldHub& h, NetServerOptions o)
      : hub(h), options(std::move(o)), acceptor(io), udpSocket(io), loadSocket(io), pollTimer(io) {}

  void acceptNext();
  void onAccepted(tcp::socket socket);
  // A connection over a cap: closed at once, counted, logged (rate-limited per address).
  void refuseAccepted(tcp::socket socket, const std::string& key, DisconnectCause cause,
                      const std::string& detail);
  static constexpr int kAcceptBatch = 64;  // accepts per turn of the event loop, at most
  void schedulePoll();
  void poll();
  void remove(std::uint32_t id, DisconnectCause cause);
  void publishStats(double pollSeconds = 0);
  // Sends `batch` (and empties it), each datagram's queueing delay into `queueDelay`.
  void flushUdp(std::vector<UdpOut>& batch, Histogram& queueDelay);
  // The poll's work for datagram sessions, spread over the workers; what it measured.
  struct PartFigures {
    double pollSeconds = 0;  // under the hub lock
    Histogram queueDelay, updateLatency;
  };
  void pollDatagramSessions(std::span<const std::shared_ptr<Session>> list, double now,
                            std::span<SharedBytes> scenes, PartFigures& figures);
  // Client datagrams (acks and repair requests, PROTOCOL.md "Acks over UDP"): the socket is
  // read whenever it has some, in batches, on this thread.
  void receiveUdp();
  void drainUdp();
  void onUplink(std::span<const std::uint8_t> bytes, bool truncated, const udp::endpoint& from,
                double now);
  // Load queries (net/load_probe.h) on the UDP port of the session's number: each answered
  // with a datagram of the query's size, at most kLoadAnswersPerSecond of them.
  void receiveLoadQueries();
  void answerLoadQueries();
  // Answers `bytes` if they are a load query (within the cap); false if they are not one.
  bool answerLoadQuery(udp::socket& socket, std::span<const std::uint8_t> bytes,
                       const udp::endpoint& from);
  static constexpr double kLoadAnswersPerSecond = 2000;
  void dropUplink(UplinkDrop cause) { ++totals.uplinkDrops[std::size_t(cause)]; }
  std::string renderMetrics() const;

  FieldHub& hub;
  NetServerOptions options;
  asio::io_context io;
  tcp::acceptor acceptor;
  udp::socket udpSocket;
  udp::socket loadSocket;             // closed where the port could not be bound (no load answers)
  bool loadOnDatagramSocket = false;  // the datagram socket has the session port's number
  double loadTokens = kLoadAnswersPerSecond, loadTokensAt = 0;
  asio::steady_timer pollTimer;
  // TLS for every session stream, unless options.tls.enabled is false.
  std::unique_ptr<net::ssl::context> tls;
  std::string tlsFingerprint;
  TokenVerifier verifier;
  double revocationsCheckedAt = 0;
  void reloadRevocations(double now);
  std::thread thread;
  bool stopped = false;
  // Perceptual comparisons shared by every session's sender (used under the hub lock).
  BrickChangeCache changeCache;
  // Datagram sessions are polled, sealed and sent by these threads (this one among them),
  // NetServerOptions::sendThreads in all.
  std::unique_ptr<NetWorkers> workers;
  // UDP datagrams of the sessions polled on this thread alone (over TCP, or not yet welcomed).
  std::vector<UdpOut> udpBatch;
  // recvmmsg's buffers: one byte more than the largest uplink datagram, so that a larger one
  // shows as truncated.
  static constexpr std::size_t kUplinkBatch = 32;
  std::array<std::array<std::uint8_t, kMaxUplinkDatagramBytes + 1>, kUplinkBatch> uplinkBuffers{};
  std::array<udp::endpoint, kUplinkBatch> uplinkFrom{};

  std::map<std::uint32_t, std::shared_ptr<Session>> sessions;
  std::size_t established = 0;                         // sessions past the handshake
  AddressLimits addressLimits{AddressLimitOptions{}};  // set from the options by create()
  // Where viewer poses may be: the field's bounds and a margin (create()); poses beyond are
  // ignored, so a client cannot steer the probe scheduler with positions no one views from.
  glm::vec3 viewerMin{0.0f}, viewerMax{0.0f};
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

}  // namespace pc
