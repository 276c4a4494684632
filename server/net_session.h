// One client's connection on the server's network thread (internal to the server's network
// layer): the handshake, the limits every client is held to, and its bounded write queue.
#pragma once

#include <array>
#include <deque>
#include <optional>
#include <string>

#include "net/session_stream.h"
#include "net_server_impl.h"
#include "protocol/datagram_seal.h"
#include "protocol/net_framing.h"
#include "protocol/session_messages.h"
#include "protocol/uplink_datagram.h"

namespace pc {

inline constexpr double kStreamReportInterval = 0.5;  // s
// s a sender waits for the Resume of a client that holds this field before it sends bricks.
inline constexpr double kResumeWaitSeconds = 1.0;

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

// One client's connection: reads frames, answers the handshake, feeds its StreamSender, and
// writes through a bounded queue. Lives on the network thread only; async handlers hold a
// shared_ptr so it outlives any operation still in flight after close().
class Session : public std::enable_shared_from_this<Session> {
 public:
  Session(NetServer::Impl& server, net::SessionStream stream, std::uint32_t id);

  // The TLS handshake (where the stream has TLS), then the first frame.
  void start();
  bool welcomed() const { return sender_ != nullptr; }
  // The keys this session is counted under in the server's AddressLimits: its remote address
  // (set on accept), and its client identity (set once the Hello is accepted).
  void setAddressKey(std::string key) { addressKey_ = std::move(key); }
  const std::string& addressKey() const { return addressKey_; }
  const std::string& clientKey() const { return clientKey_; }

  // Ends the session now: the socket closes, pending operations complete with errors and
  // find the session closed. The cause is logged (one structured event) and counted once.
  void close(DisconnectCause cause, const std::string& detail);

  // A message this client must not have sent: counted by cause, then the session ends.
  void refuse(DisconnectCause cause, const std::string& detail);

  // Called by the server's poll with the hub locked (shared, for a datagram session: several
  // threads poll theirs at once, and nothing of this session is touched by another thread
  // meanwhile): datagrams and scene state to send.
  void pollLocked(double now, std::uint64_t sceneSerial, const SharedBytes& sceneFrame,
                  std::vector<Bytes>& datagrams, SharedBytes& scene);

  // A datagram session's datagrams of one poll, sealed and added to `out` for flushUdp: the
  // part of sending that runs on any of the polling threads. A failure to seal closes the
  // session at its next send().
  void sealDatagrams(double now, std::vector<Bytes>& datagrams, std::vector<UdpOut>& out);

  // Called by the server's poll on the network thread, without the hub lock: the scene state
  // and report go out on the session's stream, and over TCP the datagrams too.
  void send(double now, std::vector<Bytes> datagrams, const SharedBytes& scene);

  // After the poll's datagrams left (flushUdp): the publish-to-send latency of the brick
  // versions pollLocked sent for the first time, into `latency`.
  void observeSent(double now, Histogram& latency);

  // Datagrams go over UDP, so the session is polled with the others of its kind in parallel.
  bool overUdp() const { return udpTarget_.has_value() && sender_ != nullptr; }

  bool closed() const { return closed_; }
  // What became of a datagram of flushUdp: a full socket buffer drops it (UDP loss, which the
  // protocol repairs).
  void udpSent(std::size_t bytes, bool ok);

  void checkTimeouts(double now);

  // A datagram to the server's UDP port that names this session: an ack or repair request
  // (PROTOCOL.md "Acks over UDP"). Handled as from the stream once it opened; otherwise the
  // cause it was dropped for, and nothing changed.
  std::optional<UplinkDrop> onUplink(std::span<const std::uint8_t> bytes, const udp::endpoint& from,
                                     double now);

  NetClientInfo info(double now) const;
  std::uint64_t tcpQueueFullPolls() const { return tcpQueueFullPolls_; }

 private:
  void onHandshake(boost::system::error_code ec);
  void readMore();
  void onRead(boost::system::error_code ec, std::size_t n);
  // False when the session ended (the frame was refused, or handling it closed the session).
  bool acceptPrefix();
  bool onFrame();
  // Takes one message of `bytes` from the flood limits; false when the session was refused.
  bool withinFloodLimits(std::size_t bytes, double now);

  // False when the session ended. A client changes nothing but its own pose and acks: the
  // session is the connection, so nothing it sends can name another session.
  // `overUdp`: it came as a datagram (counted apart).
  bool handle(const SessionMessage& message, bool overUdp = false);

  // What an ack or repair request may make the sender do is bounded by the field: a valid ack
  // lists each brick at most once, a repair request need not name one twice. Beyond that it is
  // work (and log lines) a client could multiply at will.
  std::optional<std::string> checkSize(const SessionMessage& message) const;

  bool onHello(const HelloMsg& hello);
  // Whether any cascade of the field moves with the viewers (takes the hub's shared lock).
  bool followsViewers() const;
  // Writes the Reject and closes once it is out. Before its Hello is accepted a peer never
  // gets more bytes than it sent: the reason is cut to fit, and nothing is written when not
  // even an empty reason fits.
  void sendReject(RejectMsg reject);
  // An Edit: applied through the server's edit handler where this session's token has the
  // editor role; answered with an EditResult either way, logged, and the session goes on.
  void onEdit(const EditMsg& edit);
  // Applies a viewer pose to the probe scheduler's viewer set, within the field's bounds.
  void setViewer(const ViewerPoseMsg& pose);
  void enqueue(SharedBytes bytes);
  void writeNext();
  void onWritten(boost::system::error_code ec, std::size_t n);

  NetServer::Impl& server_;
  net::SessionStream stream_;
  std::uint32_t id_;
  // Seals this session's UDP datagrams with the key from its TLS session; none without TLS.
  std::optional<DatagramSealer> sealer_;
  std::string sealFailure_;  // why sealDatagrams failed; send() closes the session
  // Opens this session's acks sent as datagrams (protocol version 6 clients with UDP), with
  // the client->server key from its TLS session (none without TLS: the plain form, taken only
  // from peerAddress_).
  std::optional<DatagramKey> uplinkKey_;
  std::optional<UplinkOpener> uplink_;
  asio::ip::address peerAddress_;
  std::uint64_t acksTcp_ = 0, acksUdp_ = 0, repairsTcp_ = 0, repairsUdp_ = 0;
  std::string peer_, name_;
  TokenClaims claims_;  // the connect token's, once the Hello is accepted
  std::string addressKey_, clientKey_;
  bool closed_ = false, closeAfterFlush_ = false;
  std::array<std::uint8_t, 4096> input_{};  // what one read takes from the stream
  Bytes frame_;                             // the frame being put together, prefix first
  std::size_t frameBytes_ = 0;              // its whole size once its prefix passed; 0 before
  // Queued writes, each with the frames it holds (several once batched), and when each of
  // those frames was queued, oldest first: the send-queue delay of each frame.
  struct Write {
    SharedBytes bytes;
    std::size_t frames;
  };
  std::deque<Write> writes_;
  std::deque<double> frameQueuedAt_;
  std::size_t queuedBytes_ = 0;
  std::vector<double> sentPublishTimes_;  // of the versions the last poll sent first
  std::uint64_t joinedAtVersion_ = 0;     // the field version when the Hello was accepted
  bool writing_ = false;
  double writeStartedAt_ = 0, acceptedAt_ = 0, lastHeard_ = 0;
  std::optional<udp::endpoint> udpTarget_;
  std::unique_ptr<StreamSender> sender_;  // created and used with the hub locked
  // StreamReport for clients of protocol version 3 and later, every kStreamReportInterval.
  bool reports_ = false;
  double lastReportAt_ = -1e30;
  Bytes report_;  // encoded by pollLocked, written by send()
  StreamReportMsg lastReport_;
  std::uint64_t sceneSerialSent_ = 0;
  std::uint64_t bytesSent_ = 0, bytesReceived_ = 0, datagrams_ = 0, udpDropped_ = 0;
  std::uint64_t messagesReceived_ = 0, tcpQueueFullPolls_ = 0;
  std::size_t pendingBricks_ = 0;
  std::uint64_t resends_ = 0, repairedFragments_ = 0;
  Bucket messageBucket_, byteBucket_;
  // What this session's viewer counts for in the probe scheduler's viewer set (FieldHub):
  // 1, the same for every client.
  int viewerWeight_ = 1;
};

}  // namespace pc
