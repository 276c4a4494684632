// The client's network side: the sockets of a session with the server (TCP, and UDP for brick
// datagrams) on its own thread running a Boost.Asio io_context, around a ClientSession
// (protocol/client_session.h), which holds the session's rules: hello, session info and its
// memory cap, scene-state clock, acks, repair requests, viewer poses, timeouts. Received bricks
// go from the session's receiver into the FieldMirror (which is thread-safe); the frame loop
// only reads the mirror and the synced animation clock, so it never waits for the network.
// When the server goes away the client keeps its mirror, reconnects with exponential backoff
// and resyncs in a new session. Asio stays inside net_client.cpp.
#pragma once

#include <cstdint>
#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "field_mirror.h"
#include "protocol/client_session.h"
#include "protocol/stream_receiver.h"

namespace pc::client {

struct NetEndpoint {
  std::string host;
  std::uint16_t port = 0;
};

struct NetClientOptions {
  std::string host = "127.0.0.1";
  std::uint16_t port = 7450;
  // Further endpoints serving the same field (relays). Before each connection every address of
  // every endpoint (a host name with several DNS records gives several) is asked for its load
  // (PROTOCOL.md "Choosing an endpoint by load") and the least loaded that takes clients is
  // chosen; a connection that is lost or fails moves on to the least loaded other one, in
  // order where none answers; the mirror is kept throughout.
  std::vector<NetEndpoint> alternates;
  // How long the load queries wait for answers (s); 0: no queries, the endpoints in order.
  double loadProbeTimeout = 0.2;
  std::string token;
  std::string name = ClientSessionOptions{}.name;
  // TLS 1.3 to the server, verified by a pinned certificate fingerprint ("sha256:<hex>") or
  // else by caFile (or the system's trust store) and the host name. Off only against a
  // server that runs without TLS too (its datagrams then travel unsealed).
  bool tls = true;
  std::string serverFingerprint;
  std::string caFile;
  bool tcpOnly = false;  // ask for datagrams over TCP
  // A new session resumes from what the mirror holds (ClientSessionOptions::resume).
  bool resume = true;
  std::uint16_t udpAdvertisePort = 0;  // port the server should send datagrams to (a relay in
                                       // front of this client); 0: this client's own port
  // Port to send acks and repair requests to as datagrams, at the server's address, instead of
  // the one the server names (a relay in front of the server's UDP port); 0: the server's.
  std::uint16_t udpServerPort = 0;
  double backoffInitial = 0.05;  // s before the first reconnect attempt
  double backoffMax = 0.4;       // s: the cap keeps a returning server found within it
  // The session's (ClientSessionOptions), with its defaults:
  double connectTimeout = ClientSessionOptions{}.connectTimeout;  // s: resolve, connect, handshake
  double silenceTimeout = ClientSessionOptions{}.silenceTimeout;  // s without bytes: server gone
  double pollInterval = 0.005;                                    // s between session polls
  double poseInterval = ClientSessionOptions{}.poseInterval;      // s between viewer poses
  // The most memory a server's field layout (SessionInfo) may make this client allocate for
  // its copies of the field (mirrorMemoryBytes, protocol/client_session.h); a larger layout
  // ends the session with an error naming both sizes. The shared scenes need under 200 MiB.
  std::uint64_t maxMirrorBytes = ClientSessionOptions{}.maxMirrorBytes;
  ReceiverOptions receiver;
};

struct NetClientStats {
  bool connected = false;  // a session is established (Welcome and SessionInfo received)
  bool synced = false;     // this session's receiver holds every brick
  std::uint64_t connectAttempts = 0, sessions = 0, rejects = 0;
  std::uint64_t endpointSwitches = 0;  // moves to another endpoint (NetClientOptions::alternates)
  std::string endpoint;                // host:port of the current or latest attempt
  std::uint64_t tcpBytes = 0, udpBytes = 0;  // received
  std::uint64_t udpDatagrams = 0, tcpDatagrams = 0, badDatagrams = 0;
  std::uint64_t unsealedRefused = 0;  // UDP datagrams that did not open with the session's key
  // Acks and repair requests sent as datagrams (PROTOCOL.md "Acks over UDP").
  std::uint64_t uplinkDatagrams = 0;
  // UDP datagrams from another source than the server (ClientSessionStats), dropped unread.
  std::uint64_t foreignDatagrams = 0;
  // Log lines about the connection left out: a server that rejects or drops this client over
  // and over gets a few lines every few seconds, not one per attempt.
  std::uint64_t suppressedLogLines = 0;
  std::uint64_t bricksApplied = 0;  // handed to the mirror
  std::uint64_t layoutResets = 0;   // mirror reset to the server's layout
  std::uint64_t serverFieldVersion = 0;
  // The newest field version of a brick this session handed to the mirror (0: none yet).
  std::uint64_t heldFieldVersion = 0;
  int bricksHeld = 0, bricksTotal = 0;  // this session
  double lastResyncSeconds = -1;        // connect -> every brick held, for the latest session
  double lastSyncedAt = -1;             // steady seconds when the latest session became synced
  std::string lastError;
  ReceiverStats receiver;
};

// A scene state with newer runtime edits than any before it, and when it arrived
// (netClockSeconds()).
struct EditArrival {
  std::uint64_t editVersion = 0;
  double at = 0;
};
// Edit results and arrivals kept until taken; later ones are dropped.
inline constexpr std::size_t kMaxKeptEditEvents = 4096;

class NetClient {
 public:
  NetClient(FieldMirror& mirror, NetClientOptions options);
  ~NetClient();  // stop()
  NetClient(const NetClient&) = delete;
  NetClient& operator=(const NetClient&) = delete;

  void start();
  void stop();

  // The server's animation clock, extrapolated from the last scene-state messages at the rate
  // they advanced; nothing before the first one.
  std::optional<double> animationTime() const;
  // The viewer for the server's scheduler and sender priorities (sent every poseInterval).
  void setViewer(glm::vec3 position, glm::quat orientation);
  NetClientStats stats() const;
  // Update latencies (ms) measured since the last call: a field version's publish to its
  // bricks' arrival (update_latency.h).
  std::vector<float> takeLatencySamples();
  // Changes whenever the mirror was reset to a new layout: a renderer made for the old one
  // must be rebuilt.
  std::uint64_t layoutGeneration() const;
  // The local UDP port datagrams are received on (0 before start or in TCP-only mode).
  std::uint16_t udpPort() const;

  // Runtime edits (PROTOCOL.md "Runtime edits"): sent at the next poll of the session; the
  // server applies them only for a token with the editor role. Every edit gets one result
  // (takeEditResults), the server's, or a local refusal when there is no session to send it in.
  void sendEdit(const EditMsg& edit);
  std::vector<EditResultMsg> takeEditResults();
  // The newest scene state with runtime edits in force: while there is one, frames take their
  // lights, instance transforms and emission from it (applySceneState) instead of replaying
  // the animation. Nothing while no edit is in force.
  std::optional<SceneStateMsg> editedScene() const;
  // Each newer edit version's first arrival, since the last call.
  std::vector<EditArrival> takeEditArrivals();

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

// Steady-clock seconds, the client's clock for the mirror and the session.
double netClockSeconds();

}  // namespace pc::client
