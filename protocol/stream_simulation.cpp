#include "stream_simulation.h"

#include <algorithm>
#include <limits>

#include "protocol/client_session.h"

namespace pc {

namespace {

bool allVersionsMatch(const Field& server, const StreamReceiver& receiver) {
  for (int k = 0; k < server.cascadeCount(); ++k) {
    for (std::size_t b = 0; b < server.brickVersions[k].size(); ++b) {
      // The current version at the codec's own precision: a coarser one is not converged yet.
      if (receiver.brickVersion(k, int(b)) != server.brickVersions[k][b] ||
          receiver.brickPrecision(k, int(b)) != 0)
        return false;
    }
  }
  return true;
}

bool holdsEveryBrick(const Field& server, const StreamReceiver& receiver) {
  for (int k = 0; k < server.cascadeCount(); ++k) {
    for (std::size_t b = 0; b < server.brickVersions[k].size(); ++b) {
      if (server.brickVersions[k][b] != 0 && receiver.brickVersion(k, int(b)) == 0) return false;
    }
  }
  return true;
}

}  // namespace

StreamSimulationResult runStreamSimulation(Field& server, const FieldAdvance& advance,
                                           const StreamSimulationOptions& o) {
  StreamSimulationResult r;
  const std::uint32_t sessionId = 0x5e55'0000u + std::uint32_t(o.seed & 0xFFFF);
  FieldPublisher publisher(server, o.publisher);
  (void)publisher.publish(server, 0.0);
  StreamSender sender(publisher, sessionId, o.sender);

  // The client is the one every client runs, ClientSession, and learns its session through
  // the wire form of Welcome and SessionInfo, as it would over TCP. Its timeouts are off: the
  // fault phase may be longer than any of them, and what is measured here is the stream.
  ClientSessionOptions clientOptions;
  clientOptions.receiver = o.receiver;
  clientOptions.connectTimeout = std::numeric_limits<double>::infinity();
  clientOptions.silenceTimeout = std::numeric_limits<double>::infinity();
  ClientSession client(clientOptions);
  client.connecting(0.0);
  (void)client.connected(0.0, 1);  // the Hello: this server needs nothing from it
  std::vector<std::uint8_t> handshake = encodeMessage(WelcomeMsg{kProtocolVersion, sessionId});
  const std::vector<std::uint8_t> info = encodeMessage(publisher.sessionInfo());
  handshake.insert(handshake.end(), info.begin(), info.end());
  if (!client.onStreamBytes(handshake, 0.0) || !client.streaming()) return r;
  const StreamReceiver& receiver = *client.receiver();

  FaultLink link(o.seed);
  ReliableLink control;
  if (o.viewer) {
    ViewerPoseMsg pose;
    pose.position = *o.viewer;
    control.send(encodeMessage(pose), 0.0);
  }

  const double faultStart = o.warmupSeconds, faultEnd = o.warmupSeconds + o.faultSeconds;
  const double end = faultEnd + o.settleLimitSeconds;
  double nextTick = o.tickInterval;
  double nextHeldSample = faultStart;
  for (long i = 1;; ++i) {
    const double t = double(i) * o.step;
    if (t > end) break;
    const bool faulty = t >= faultStart && t < faultEnd;
    link.setProfile(faulty ? o.faults : o.calm);
    control.setDelay(faulty ? o.controlDelayDuringFaults : o.controlDelay);

    if (t >= nextTick) {
      nextTick += o.tickInterval;
      if (!(o.freezeAfterFaults && t >= faultEnd)) {
        advance(server, t);
        (void)publisher.publish(server, t);
        ++r.fieldUpdates;
        // The scene state a server sends with every update, announcing its field version.
        SceneStateMsg state;
        state.fieldVersion = server.version;
        state.cascadePlaces = cascadePlaces(server);
        (void)client.onStreamBytes(encodeMessage(state), t);
      }
    }

    auto datagrams = sender.poll(t);
    r.maxDatagramsPerPoll = std::max(r.maxDatagramsPerPoll, datagrams.size());
    for (auto& d : datagrams) {
      if (faulty) r.faultBytes += d.size();
      r.maxDatagramBytes = std::max(r.maxDatagramBytes, d.size());
      link.send(std::move(d), t);
    }
    for (auto& d : link.receive(t)) r.receiverErrors += !client.onDatagram(d, t).ok();
    (void)client.takeChangedBricks();
    if (auto frames = client.poll(t)) {  // never an Error: the timeouts are off
      for (auto& m : *frames) control.send(std::move(m), t);
    }
    for (auto& m : control.receive(t)) (void)sender.onMessage(m, t);

    r.maxReassemblyBytes = std::max(r.maxReassemblyBytes, receiver.reassembler().pendingBytes());
    r.maxReassemblyUpdates =
        std::max(r.maxReassemblyUpdates, receiver.reassembler().pendingUpdates());
    r.maxLinkInFlight = std::max(r.maxLinkInFlight, link.inFlight());
    r.maxControlInFlight = std::max(r.maxControlInFlight, control.inFlight());
    r.maxCacheBytes = std::max(r.maxCacheBytes, publisher.cache().bytes());
    r.maxHistoryBytes = std::max(r.maxHistoryBytes, publisher.historyBytes());
    r.seconds = t;
    if (t >= faultStart && t >= nextHeldSample) {
      // What the client holds while the field changes (the sender's own measure).
      nextHeldSample = t + 0.25;
      const HeldFieldReport held = sender.heldField(t);
      if (held.heldBricks > 0) {
        (faulty ? r.heldAges : r.settleHeldAges).push_back(held.oldestChangeSeconds);
        (faulty ? r.heldPsnrs : r.settleHeldPsnrs).push_back(held.psnrDb);
        (faulty ? r.qualityLevels : r.settleQualityLevels).push_back(sender.qualityLevel());
      }
    }
    if (r.heldEverySeconds < 0 && holdsEveryBrick(server, receiver)) r.heldEverySeconds = t;

    if (t >= faultEnd && allVersionsMatch(server, receiver)) {
      r.converged = true;
      r.convergeSeconds = t - faultEnd;
      break;
    }
  }
  r.sender = sender.stats();
  r.receiver = receiver.stats();
  r.link = link.stats();
  r.mirror = receiver.field();
  return r;
}

}  // namespace pc
