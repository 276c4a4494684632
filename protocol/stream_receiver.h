// Client side of the stream, without sockets or clocks: fed datagrams and the time, it keeps a
// mirror of the server's field and says what to send back (acks, repair requests).
//
// An update is applied only when it is newer than the brick's version (or the same version at
// a finer precision level) and either self-contained or a residual on exactly the version and
// precision held; otherwise the brick keeps what it
// has and a repair request goes out (at most one per brick per repair interval). Duplicated,
// reordered, stale, corrupt or foreign datagrams therefore change nothing. Acks report the
// versions held: changes at most every ack interval, the whole state every full-ack interval.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "common/field.h"
#include "common/result.h"
#include "protocol/brick_codec.h"
#include "protocol/datagram.h"
#include "protocol/resume_state.h"
#include "protocol/session_messages.h"

namespace pc {

// Turns an update's payload into the brick's codes. The default decodes every payload; a
// process holding many receivers (probecast-loadgen) may share decoded codes between them,
// since the same payload on the same base always decodes to the same codes.
class BrickDecoder {
 public:
  virtual ~BrickDecoder() = default;
  // `base` is null for a self-contained payload, else the codes of the version held.
  virtual Result<std::shared_ptr<const QuantizedBrick>> decode(
      const UpdateHeader& update, std::span<const std::uint8_t> payload,
      const std::shared_ptr<const QuantizedBrick>& base) = 0;
};

struct ReceiverOptions {
  double ackInterval = 0.02;     // s: changes are acknowledged at most this often
  double fullAckInterval = 1.0;  // s: every held version is acknowledged this often
  double repairInterval = 0.2;   // s: per brick, at most one repair request this often
  // Acks name the fragments that partial updates lack (ReassemblyOptions: gapReorder, gapRepeat),
  // and the sender sends those again. False only to measure what that brings.
  bool reportGaps = true;
  // Acks list every datagram's arrival (sequence, time) for the sender's congestion control;
  // an ack goes out every ack interval while datagrams arrive. False for a version 2 server's
  // acks (it ignores them) only to save their bytes.
  bool reportArrivals = true;
  // Each ack lists again the bricks that changed, and the arrivals it reported, in this many
  // acks before it (the arrivals: the newest kMaxRepeatedArrivals of them). Over the session
  // stream nothing is lost (0); acks sent as datagrams may be, and then the next one carries
  // what the lost one said: a lost ack costs a delay, and the sender never reads the arrivals
  // it reported as lost datagrams (ClientSession sets it to kUplinkAckRepeats).
  int ackRepeats = 0;
  ReassemblyOptions reassembly;
  // False: only each brick's codes (the residual bases) are kept, not the decoded field: the
  // atlases are released and field() holds the layout, probe records and brick versions only.
  // For clients that never render (probecast-loadgen): a decoded field costs megabytes.
  bool keepField = true;
  BrickDecoder* decoder = nullptr;  // null: decodeBrick for every payload; must outlive this
};

struct ReceiverStats {
  std::uint64_t datagrams = 0, rejectedDatagrams = 0, fragments = 0, rejectedFragments = 0;
  std::uint64_t applied = 0, appliedResidual = 0;
  std::uint64_t stale = 0;        // not newer than what is held (duplicates, reordering)
  std::uint64_t missingBase = 0;  // residual on a version not held
  std::uint64_t decodeErrors = 0;
  std::uint64_t repairBricks = 0;  // bricks named in repair requests
  std::uint64_t acks = 0;
  std::uint64_t gapReports = 0;  // partial updates whose missing fragments were asked for
  // Datagrams and fragments refused for a field version beyond what the server announced
  // over the session (plus kFieldVersionSlack): forged, or from another server.
  std::uint64_t refusedVersions = 0;
  std::string lastError;
};

// How far a datagram's field version (and a brick update's version) may run ahead of the
// newest one the server announced over the session (SessionInfo, SceneState, StreamReport).
// Datagrams overtake the TCP stream, so a datagram may carry a version whose SceneState is
// still on its way, but only by what the server publishes in that time: one version per
// field update, 30 updates a second by default, and a SceneState follows every one. 1024
// versions are over half a minute at that rate, and over 4 s even at the server's highest rate
// (240 a second), while a forged version of 2^63 (which would hold a brick against every real
// update) is refused.
inline constexpr std::uint64_t kFieldVersionSlack = 1024;
// At most this many arrivals of earlier acks are repeated in an ack (ReceiverOptions::
// ackRepeats): 512 bytes, so that an ack stays within one datagram at a few Mbit/s.
inline constexpr std::size_t kMaxRepeatedArrivals = 64;

class StreamReceiver {
 public:
  // Builds the empty mirror from the session info (see mirrorField).
  static Result<StreamReceiver> create(const SessionInfoMsg& info, std::uint32_t sessionId,
                                       ReceiverOptions options = {});

  // One datagram (or a TCP-framed datagram in TCP-only mode). An Error says why it or one of
  // its fragments was rejected; the rest of the state is unchanged and consistent either way.
  Status onDatagram(std::span<const std::uint8_t> bytes, double now);

  // Session message frames to send to the server now (Ack, RepairRequest).
  std::vector<std::vector<std::uint8_t>> poll(double now);
  // Takes what `previous` (a receiver of an earlier session) holds, when its layout is this
  // one's: the atlases, and per brick the version, precision and codes (the bases of
  // residuals), except versions past the field version this server announced, which it would
  // not take as held. False (nothing taken) for another layout.
  bool adoptHeld(StreamReceiver&& previous);
  // Every brick's version and precision, for a Resume.
  HeldBricks heldBricks() const;
  // ReceiverOptions::ackRepeats from now on (acks that start to travel as datagrams).
  void setAckRepeats(int repeats) { options_.ackRepeats = std::max(0, repeats); }

  const Field& field() const { return field_; }
  std::uint64_t brickVersion(int cascade, int brick) const {
    return bricks_[cascade][brick].version;
  }
  // The precision level the brick's version is held at (0: the codec's own).
  int brickPrecision(int cascade, int brick) const { return bricks_[cascade][brick].precision; }
  // Seconds since the brick last changed here; infinity while it holds nothing.
  double brickAge(int cascade, int brick, double now) const;
  // Newest field version the server announced.
  std::uint64_t serverFieldVersion() const { return serverVersion_; }
  // The server announced `version` over the session (a SceneState, a StreamReport): versions
  // up to it plus kFieldVersionSlack are accepted from now on. Versions never go back.
  void announceFieldVersion(std::uint64_t version);
  // The newest version a datagram or brick update may carry now.
  std::uint64_t newestAcceptedVersion() const;
  // A SceneState's cascade places (protocol version 9): each cascade that moved takes its new
  // origin and scroll, and the slots of its held bricks are shown or hidden again by their
  // layout stamps (brick_codec.h); bricks whose records changed count as changed. An Error
  // names a place that does not fit the layout (count, scroll out of range, an origin not a
  // whole number of spacings away), and nothing moves.
  Status moveCascades(const std::vector<CascadePlaceMsg>& places);
  // (cascade, brick) of every brick changed since the previous call, for tile uploads.
  std::vector<std::pair<int, int>> takeChangedBricks();

  const ReceiverStats& stats() const { return stats_; }
  const Reassembler& reassembler() const { return reassembler_; }

 private:
  struct BrickState {
    std::uint64_t version = 0;
    int precision = 0;  // the level `content` is rounded to (brick_precision.h)
    double appliedAt = 0;
    std::shared_ptr<const QuantizedBrick> content;  // codes of `version`: residuals' base
    // The version held before `version`, also a base: the server sends one version of a brick
    // at a time, but when an ack is late it sends the next one on the version acknowledged,
    // which this client may just have replaced.
    std::uint64_t previousVersion = 0;
    int previousPrecision = 0;
    std::shared_ptr<const QuantizedBrick> previous;
    double repairAt = -1e30;
    bool wantRepair = false;
    std::uint8_t acksLeft = 0;  // acks that still list this brick's change
    bool changed = false;
  };
  StreamReceiver(Field field, std::uint32_t sessionId, ReceiverOptions options);
  Status apply(const CompletedUpdate& u, double now);
  void requestRepair(BrickState& b);

  Field field_;
  std::uint32_t sessionId_;
  ReceiverOptions options_;
  std::vector<std::vector<BrickState>> bricks_;
  Reassembler reassembler_;
  std::uint32_t newestSequence_ = 0;          // of the datagrams received (wrapping)
  std::vector<DatagramArrivalMsg> arrivals_;  // since the last ack, kMaxAckArrivals at most
  // The arrivals of the last ackRepeats acks, oldest first, repeated in the next.
  std::deque<std::vector<DatagramArrivalMsg>> reportedArrivals_;
  std::uint64_t serverVersion_ = 0;
  std::uint64_t announcedVersion_ = 0;  // over the session only: datagrams never raise it
  double lastAckAt_ = -1e30, lastFullAckAt_ = -1e30;
  ReceiverStats stats_;
};

}  // namespace pc
