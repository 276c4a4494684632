// A whole stream in memory: a server field that changes, a FieldPublisher and StreamSender on
// one side, a ClientSession (with its StreamReceiver) on the other, datagrams over a FaultLink
// and session messages over a ReliableLink. Runs a calm warm-up, a fault phase, then calm again
// until the receiver holds every brick's current version; reports how long that took and the peak
// sizes of every queue and buffer. Used by the protocol tests and `probecast-bench faults`.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <glm/glm.hpp>
#include <optional>
#include <vector>

#include "common/field.h"
#include "protocol/fault_link.h"
#include "protocol/field_publisher.h"
#include "protocol/stream_receiver.h"
#include "protocol/stream_sender.h"

namespace pc {

struct StreamSimulationOptions {
  double step = 0.005;               // s between network events (polls, deliveries)
  double tickInterval = 1.0 / 30.0;  // s between field updates
  double warmupSeconds = 0.5;        // calm, field changing
  double faultSeconds = 3.0;         // faults on, field changing
  double settleLimitSeconds = 5.0;   // calm; give up after this long
  bool freezeAfterFaults = true;     // the field stops changing when the faults stop
  FaultProfile faults;
  FaultProfile calm;           // after the faults (and during warm-up)
  double controlDelay = 0.01;  // s, one way, session messages
  double controlDelayDuringFaults = 0.05;
  SenderOptions sender;
  ReceiverOptions receiver;
  PublisherOptions publisher;
  std::uint64_t seed = 1;
  std::optional<glm::vec3> viewer;  // sent as a ViewerPose at the start
};

struct StreamSimulationResult {
  bool converged = false;
  double convergeSeconds = 0;    // after the faults stopped
  double heldEverySeconds = -1;  // when the receiver first held a version of every brick
  SenderStats sender;
  ReceiverStats receiver;
  LinkStats link;
  std::uint64_t receiverErrors = 0;
  std::size_t maxReassemblyBytes = 0, maxReassemblyUpdates = 0;
  std::size_t maxLinkInFlight = 0, maxControlInFlight = 0;
  std::size_t maxDatagramsPerPoll = 0, maxDatagramBytes = 0;
  std::size_t maxCacheBytes = 0, maxHistoryBytes = 0;
  std::uint64_t fieldUpdates = 0;
  double seconds = 0;  // simulated, in all
  // The sender's held-field measures (HeldFieldReport) every 0.25 s of the fault phase: the
  // age of the oldest change the client lacked, and the held field's PSNR.
  std::vector<double> heldAges, heldPsnrs;
  std::vector<int> qualityLevels;  // the sender's quality level at the same samples
  // The same measures every 0.25 s after the fault phase, while the settle phase runs.
  std::vector<double> settleHeldAges, settleHeldPsnrs;
  std::vector<int> settleQualityLevels;
  // The sender's bytes (datagrams) in the fault phase.
  std::uint64_t faultBytes = 0;
  Field mirror;  // the receiver's field at the end
};

// `advance` applies one field update at time t (bumping versions as the tracer does).
using FieldAdvance = std::function<void(Field& field, double t)>;

StreamSimulationResult runStreamSimulation(Field& server, const FieldAdvance& advance,
                                           const StreamSimulationOptions& options);

}  // namespace pc
