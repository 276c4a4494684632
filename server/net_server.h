// The server's network layer: a TCP listener for sessions (hello with a shared-secret token,
// session info, scene-state sync, acks, repair requests and viewer poses from clients) and one
// UDP socket for brick datagrams, all on one network thread running a Boost.Asio io_context.
// Every client has its own StreamSender (reading the hub's shared publisher) and a bounded TCP
// write queue; a client that sends anything malformed, or stops reading, is disconnected with
// the cause logged, and no other client notices. Asio stays inside net_server.cpp.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "common/result.h"
#include "net_hub.h"
#include "protocol/stream_sender.h"

namespace pc {

struct NetServerOptions {
  std::string bindAddress = "0.0.0.0";
  std::uint16_t port = 7450;  // TCP; 0 picks a free one (see NetServer::port)
  std::string token;          // shared secret every Hello must carry
  bool tcpOnly = false;       // datagrams framed over TCP for every client
  SenderOptions sender;
  std::size_t maxClients = 64;
  // A client's queued TCP bytes beyond this, or a write that makes no progress for this long,
  // means it is not reading: it is disconnected rather than buffered for.
  std::size_t maxWriteQueueBytes = 4u << 20;
  double writeStallSeconds = 5.0;
  // TCP-only mode polls a client's sender only while less than this is queued, so a slow
  // client gets the newest state instead of a backlog (the sender keeps one entry per brick).
  std::size_t tcpDatagramQueueBytes = 256u << 10;
  double helloTimeout = 5.0;    // s from accept to a Hello
  double silenceTimeout = 10.0;  // s without any message from a client (full acks come every 1 s)
  double pollInterval = 0.005;  // s between sender polls
};

struct NetClientInfo {
  std::uint32_t sessionId = 0;
  std::string name, peer;
  bool udp = false;
  double connectedSeconds = 0;
  std::uint64_t bytesSent = 0, datagrams = 0, udpDropped = 0;
  std::size_t pendingBricks = 0;
};

struct NetServerStats {
  std::uint64_t accepted = 0, rejected = 0, disconnected = 0;
  std::uint64_t bytesSent = 0, bytesReceived = 0;
  std::vector<NetClientInfo> clients;
};

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
  NetServerStats stats() const;

  struct Impl;

 private:
  explicit NetServer(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace pc
