// Client side of a session, without sockets or clocks: the one state machine behind
// probecast-client (client/net_client.cpp), probecast-loadgen (loadgen/load_generator.cpp) and
// the in-memory stream simulation. Fed the bytes of the TCP stream, the UDP datagrams and the
// time, it says what to send (Hello, acks, repair requests, viewer poses) and what happened
// (events, state), and it holds every rule of the client's side: the handshake and its order,
// the checks of SessionInfo including the memory cap, the animation clock, the cadence of acks,
// repairs and poses, the connect and silence timeouts, and the caps on what a server can make
// it hold. The caller owns the sockets, retries and what it does with the bricks.
//
// One ClientSession serves a client's whole life, one session after another:
//   connecting(now)            the caller starts opening a connection
//   connected(now, udpPort)    it is open: send the returned Hello first
//   onStreamBytes / onDatagram bytes as they arrive; events() says what each call did
//   poll(now)                  often (every few ms): frames to send, or an Error (a timeout)
//   close()                    the connection is gone, whatever the reason
// Any Error from onStreamBytes or poll ends the session (phase() Rejected or Failed, error()
// says why); the caller closes the connection, calls close() and may connect again. The
// animation clock and the counters carry over from one session to the next.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "common/result.h"
#include "protocol/datagram_seal.h"
#include "protocol/session_messages.h"
#include "protocol/stream_receiver.h"
#include "protocol/uplink_datagram.h"

namespace pc {

// What a session with this layout makes a client hold on the CPU: the receiver's field and a
// renderer's copy of it (atlases with borders, probe records) and the receiver's quantized
// codes per brick. Counts per axis are clamped to 1..1024 (mirrorField refuses anything else).
std::uint64_t mirrorMemoryBytes(const SessionInfoMsg& info);

// A client sends only small messages: more than this queued for the server means the server
// is not reading, and the caller ends the session.
inline constexpr std::size_t kMaxClientQueuedBytes = 1u << 20;
// The largest Resume a client sends (half its queue): a claim over it is sent as holding
// nothing. A Resume takes about 2 bytes per brick, at most 16 (8 of versions that do not
// compress, 8 of a precision exception).
inline constexpr std::size_t kMaxResumeFrameBytes = kMaxClientQueuedBytes / 2;
// UDP datagrams that arrive between the Hello and SessionInfo (the server sends them as soon
// as the Hello is in, while Welcome and SessionInfo are still on their way over TCP) are kept
// for the session's receiver, this many at most.
inline constexpr std::size_t kMaxEarlyDatagrams = 64;
// Acks sent as datagrams repeat what the acks before them said (ReceiverOptions::ackRepeats):
// two, so that a third of them lost still leaves 1 in 27 of an ack's news to the full ack.
inline constexpr int kUplinkAckRepeats = 2;
// A Reject's reason is quoted in the error up to this many bytes: a server could send 4 MiB.
inline constexpr std::size_t kMaxQuotedReasonBytes = 200;

// Where a UDP datagram came from, as far as the session needs to know: whether its source
// address is the server's (the address the TCP session is connected to), and its source port.
// The default is a datagram from the server (in-memory links, TCP-framed datagrams).
struct DatagramSource {
  bool serverAddress = true;
  std::uint16_t port = 0;  // 0: not known
};

struct ClientSessionOptions {
  std::string token;  // the server's shared secret, sent in the Hello
  std::string name = "probecast-client";
  double connectTimeout = 2.0;  // s from connecting() to SessionInfo
  double silenceTimeout = 2.0;  // s without any bytes from the server, once connected
  double poseInterval = 0.1;    // s between viewer poses
  // The most a SessionInfo may make this client allocate (mirrorMemoryBytes); a larger layout
  // ends the session with an error naming both sizes. The shared scenes need under 200 MiB.
  std::uint64_t maxMirrorBytes = std::uint64_t(1) << 30;
  // Acks and repair requests as datagrams to the server's uplink port (protocol version 6)
  // once the session's datagrams arrive over UDP: the caller then sends what
  // takeUplinkDatagrams() returns to uplinkPort() at the server's address. False: always over
  // the session stream (callers without a UDP socket).
  bool uplinkDatagrams = false;
  // The next session resumes from what this one held (protocol version 7, PROTOCOL.md
  // "Resuming a session"): a server of the same field sends only what is newer. The previous
  // receiver is kept between sessions for it (the memory a session holds anyway).
  bool resume = true;
  ReceiverOptions receiver;
};

enum class SessionPhase {
  Idle,             // no connection: before the first, or after close()
  Connecting,       // the caller is opening a connection
  AwaitingWelcome,  // Hello sent
  AwaitingLayout,   // Welcome received, SessionInfo not yet
  Streaming,        // SessionInfo taken: receiver() holds the session's field
  Rejected,         // ended by the server's Reject
  Failed,           // ended by an error or a timeout
};

struct SessionEvent {
  enum class Kind {
    Welcomed,      // the server took the Hello (sessionId())
    Layout,        // SessionInfo taken: receiver() holds the new session's empty field
    SceneState,    // a scene state arrived (scene); clock() has taken it
    Datagram,      // a datagram was handled (either transport); status says whether it was refused
    StreamReport,  // the server's report on this client's stream (report())
    EditResult,    // the server's answer to an edit this client sent (edit)
  };
  Kind kind;
  SceneStateMsg scene;  // Kind::SceneState
  Status status;        // Kind::Datagram
  EditResultMsg edit;   // Kind::EditResult
};

// Edits sendEdit holds until the next poll; more are refused.
inline constexpr std::size_t kMaxQueuedEdits = 64;

struct ClientSessionStats {
  std::uint64_t connectAttempts = 0;  // connecting() calls
  std::uint64_t sessions = 0;         // SessionInfo taken
  std::uint64_t rejects = 0;
  std::uint64_t tcpBytes = 0, udpBytes = 0;  // received
  std::uint64_t udpDatagrams = 0, tcpDatagrams = 0;
  std::uint64_t badDatagrams = 0;           // refused by the receiver (or a fragment of them)
  std::uint64_t droppedEarlyDatagrams = 0;  // past kMaxEarlyDatagrams before SessionInfo
  // UDP datagrams not from the server: another source address, or another port than the one
  // the session's first accepted datagram came from. Dropped unread.
  std::uint64_t foreignDatagrams = 0;
  std::uint64_t streamReports = 0;
  // UDP datagrams that failed to open with the session's key (forged, corrupted, replayed,
  // or for another session): dropped, and never taken as a sign of the server's life.
  std::uint64_t unsealedRefused = 0;
  // Acks and repair requests handed out as datagrams (takeUplinkDatagrams), and those that
  // went over the stream instead for their size (over kMaxUplinkFrameBytes).
  std::uint64_t uplinkDatagrams = 0, uplinkTooLarge = 0;
  std::uint64_t resumes = 0;  // sessions that took the previous session's bricks
};

// The server's animation clock as a client sees it: the latest scene state's time, run on at
// the rate the states advanced (0 when the server's clock stands still).
class AnimationClock {
 public:
  void update(double animationTime, double now);
  // Nothing before the first scene state.
  std::optional<double> at(double now) const;

 private:
  bool known_ = false;
  double animation_ = 0, wall_ = 0, rate_ = 1.0;
};

class ClientSession {
 public:
  explicit ClientSession(ClientSessionOptions options);

  // The caller starts opening a connection; the connect timeout runs from here. Ends whatever
  // session there was.
  void connecting(double now);
  // The keys of this connection's datagrams (from its TLS session, deriveDatagramKeys), set
  // after connecting() and before connected(): the server->client key opens what arrives, the
  // client->server key seals acks sent as datagrams. Without them (a connection without TLS)
  // datagrams are taken and sent unsealed.
  void setDatagramKeys(const DatagramKeys& keys) {
    datagramKey_ = keys.serverToClient;
    uplinkKey_ = keys.clientToServer;
  }
  // The connection is open: the Hello frame, to send before anything else. udpPort 0 asks for
  // datagrams over the TCP stream.
  std::vector<std::uint8_t> connected(double now, std::uint16_t udpPort);
  // The connection is gone or was closed: the session's receiver is released, or kept for the
  // next session to resume from (ClientSessionOptions::resume).
  void close();
  // The next session starts from nothing, as a new client's (a kept receiver is released).
  void forgetHeld() { keptReceiver_.reset(); }

  // Bytes read from the TCP stream, in any pieces: each frame is handled once it is whole,
  // its size checked from its prefix before the body is awaited. An Error ends the session.
  Status onStreamBytes(std::span<const std::uint8_t> bytes, double now);
  // One UDP datagram. Its status (also in its Datagram event) never ends the session. Only a
  // datagram from the server (`source`: its address, and once the session accepted one, the
  // same port) that the receiver accepts counts as a sign of the server's life for the
  // silence timeout: junk or a replay from elsewhere cannot keep a dead server looking alive.
  Status onDatagram(std::span<const std::uint8_t> bytes, double now, DatagramSource source = {});
  // What the latest onStreamBytes or onDatagram call did, in order; the next call replaces
  // them. Kept here rather than handed over, so that a datagram's event allocates nothing.
  const std::vector<SessionEvent>& events() const { return events_; }

  // Frames to send now over the session stream (acks, repair requests, the viewer pose), or
  // an Error when a timeout ended the session. Acks and repair requests that travel as
  // datagrams (ClientSessionOptions::uplinkDatagrams) wait in takeUplinkDatagrams() instead.
  Result<std::vector<std::vector<std::uint8_t>>> poll(double now);
  // Datagrams for the server's uplink port that poll() made, each once.
  std::vector<std::vector<std::uint8_t>> takeUplinkDatagrams();
  // The server's UDP port for them (0: the session sends none).
  std::uint16_t uplinkPort() const { return uplink_ ? info_.uplinkPort : 0; }

  // The viewer sent to the server every poseInterval while streaming; its time is the clock's.
  void setViewer(glm::vec3 position, glm::quat orientation);
  // Whether poll would send a pose now (for callers that compute it only when it is due).
  bool poseDue(double now) const;
  // A runtime edit (protocol version 8), sent with the next poll; the server answers with an
  // EditResult event. An Error when no session streams, the server takes no edits, or too many
  // wait already. Only a token with the editor role gets an edit applied.
  Status sendEdit(const EditMsg& edit);
  // The newest scene state that includes runtime edits (SceneStateMsg::editVersion > 0): while
  // there is one, it is the scene (lights, transforms, emission), not the local animation.
  const std::optional<SceneStateMsg>& editedScene() const { return edited_; }

  // Bricks (cascade, brick) changed since the previous call, each once, for the caller to
  // read from receiver()->field() or brickVersion().
  std::vector<std::pair<int, int>> takeChangedBricks();

  SessionPhase phase() const { return phase_; }
  bool streaming() const { return phase_ == SessionPhase::Streaming; }
  // Why the latest session ended (empty while none did).
  const std::string& error() const { return error_; }
  std::uint32_t sessionId() const { return sessionId_; }
  // The session's receiver from SessionInfo until close() or the next connecting().
  const StreamReceiver* receiver() const { return receiver_ ? &*receiver_ : nullptr; }
  const SessionInfoMsg& info() const { return info_; }
  int bricksHeld() const { return bricksHeld_; }
  int bricksTotal() const { return bricksTotal_; }
  // The session holds a version of every brick; syncSeconds: connecting() -> that moment.
  bool synced() const { return synced_; }
  double syncSeconds() const { return syncSeconds_; }
  const AnimationClock& clock() const { return clock_; }
  // The server's latest report on this session's stream (protocol version 3 servers send one
  // about twice a second: send rate, quality level, the held field's error and age).
  const std::optional<StreamReportMsg>& report() const { return report_; }
  double reportAt() const { return reportAt_; }
  const ClientSessionStats& stats() const { return stats_; }
  const ClientSessionOptions& options() const { return options_; }

 private:
  Error fail(std::string why, SessionPhase phase = SessionPhase::Failed);
  Status onFrame(std::span<const std::uint8_t> frame, double now);
  Status onMessage(SessionMessage& message, double now);
  Status onSessionInfo(const SessionInfoMsg& info, double now);
  // `port`: the UDP source port of a datagram the session has not taken yet (0: over TCP, or
  // not known), pinned as the server's once the datagram is accepted.
  Status handleDatagram(std::span<const std::uint8_t> bytes, double now, std::uint16_t port = 0);
  // `port`: the datagram's source port, pinned once one opens (0: not known).
  Status openDatagram(std::span<const std::uint8_t> sealed, double now, std::uint16_t port);
  void collectChanges(double now);
  bool connectedPhase() const;
  // Starts sending acks as datagrams once the session may (see uplinkDatagrams).
  void startUplink();
  // After SessionInfo: takes the previous session's bricks where the field is the same, and
  // makes the Resume a version 7 server waits for.
  void resume();

  ClientSessionOptions options_;
  SessionPhase phase_ = SessionPhase::Idle;
  std::string error_;
  double connectStartedAt_ = 0, lastHeard_ = 0, lastPoseAt_ = -1e30;
  std::uint32_t sessionId_ = 0;
  std::uint16_t serverUdpPort_ = 0;  // source port of the first datagram accepted; 0: none yet
  SessionInfoMsg info_;
  std::optional<StreamReceiver> receiver_;
  // The previous session's receiver and layout, until the next SessionInfo resumes from it;
  // the epoch the Hello named; the Resume to send first.
  std::optional<StreamReceiver> keptReceiver_;
  SessionInfoMsg keptInfo_;
  std::uint64_t heldEpoch_ = 0;
  std::vector<std::uint8_t> resumeFrame_;
  std::vector<std::uint8_t> frame_;  // the TCP frame being read, prefix first
  std::size_t frameBytes_ = 0;       // its whole size, once the prefix is in
  std::deque<std::pair<std::vector<std::uint8_t>, std::uint16_t>> early_;  // with source port
  // Sealed datagrams: the key of this connection, its opener once the Welcome names the
  // session, and sealed datagrams that came before the Welcome.
  std::optional<DatagramKey> datagramKey_;
  std::optional<DatagramOpener> opener_;
  std::deque<std::pair<std::vector<std::uint8_t>, std::uint16_t>> earlySealed_;  // with port
  // Acks as datagrams: the client->server key, the version the Welcome named, and once the
  // session's UDP path works, the writer and what it made since takeUplinkDatagrams.
  std::optional<DatagramKey> uplinkKey_;
  std::uint32_t spokenVersion_ = 0;
  std::optional<UplinkWriter> uplink_;
  std::vector<std::vector<std::uint8_t>> uplinkOut_;
  std::vector<SessionEvent> events_;
  // Per brick: held at any version this session; changed since takeChangedBricks.
  std::vector<std::vector<bool>> held_, changed_;
  std::vector<std::pair<int, int>> changedList_;
  std::uint64_t lastApplied_ = 0;
  int bricksHeld_ = 0, bricksTotal_ = 0;
  bool synced_ = false;
  double syncSeconds_ = -1;
  std::optional<ViewerPoseMsg> viewer_;
  AnimationClock clock_;
  std::optional<StreamReportMsg> report_;
  double reportAt_ = 0;
  std::optional<SceneStateMsg> edited_;
  std::vector<std::vector<std::uint8_t>> editsOut_;
  ClientSessionStats stats_;
};

}  // namespace pc
