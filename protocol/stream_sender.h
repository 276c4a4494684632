// Server side of one client's stream, without sockets or clocks: fed the client's session
// messages (acks, repair requests, viewer poses) and the time, it produces the datagrams to
// send now. One per client; all of them read one shared FieldPublisher.
//
// What it sends, per brick: nothing while the client has acknowledged the brick's current
// version, or while any version of the brick is in flight (sent less than a resend timeout
// ago and not acknowledged). Otherwise
// the current version, as a residual on the version the client acknowledged (when that is
// still in the publisher's history) or self-contained, unless the change since the version the
// client has or is receiving is below the perceptual thresholds, the version is younger than
// the settle time, and the brick was sent within the refresh interval. There is no queue beyond
// one entry per brick, always for the newest version: a lagging client gets the newest state,
// never a backlog. Bricks the client lacks go before newer versions of bricks it holds; among
// them, bricks near the viewer go first, and waiting (since the brick was last sent) raises a
// brick's priority.
//
// Loss: the client's acks name the fragments a partial update lacks, and those are sent again
// first (selective repair, PROTOCOL.md "Fragment gaps"). And one exception: a brick the client
// holds nothing of, whose self-contained update of
// several fragments was not acknowledged in time, is sent again as the same update (same
// version, id and bytes) while the publisher holds that version, ahead of other bricks. The
// receiver keeps the fragments that arrived and each resend fills in what the last one lost,
// so a brick of n fragments arrives after a few sends even where a whole send arrives with
// probability (1 - loss)^n: a brick of a real scene is 30-80 fragments self-contained, and with
// a newer version in every send it would almost never arrive at 10% loss. A brick the client
// holds gets the newest version after a timeout, as before: resending an older one after an
// ack that was only late held loaded clients back (probecast-bench load: 231-290 of 1000
// clients stale for over 2 s). While the lost updates held open reach half the receiver's
// reassembly caps (SenderOptions::maxLostUpdates, maxLostBytes), no new update of several
// fragments starts.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <glm/glm.hpp>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <unordered_map>
#include <vector>

#include "common/result.h"
#include "protocol/brick_precision.h"
#include "protocol/field_publisher.h"
#include "protocol/rate_controller.h"
#include "protocol/session_messages.h"

namespace pc {

struct SenderOptions {
  // The most this client is sent, datagram bytes per second (the server's --rate-limit). With
  // congestion control the sender sends at the controller's rate below it; without, at it.
  double bytesPerSecond = 4e6;
  double burstBytes = 256 * 1024;  // bucket size without congestion control
  // Congestion control (RateController) from the client's arrival reports. Off for clients
  // that do not report arrivals (protocol version 2).
  bool congestionControl = true;
  RateControlOptions rateControl;
  // With congestion control the bucket holds this much sending time at the rate (at least
  // three datagrams): pacing, so that a poll never puts a burst into a router's queue.
  double pacingBurstSeconds = 0.01;
  // Every brick the client holds is brought up to date within this long of its first change
  // it does not hold, at whatever quality the rate allows (the thresholds do not hold it back
  // past then). The sender aims to send it ageLead before the bound.
  double ageBound = 1.0;
  double ageLead = 0.25;
  // The quality ladder: while the client's rate is short of what the field's changes need
  // (the sender spent its rate and changes at the age bound still waited) and changes get old,
  // each level up doubles the perceptual thresholds, so the client holds a coarser but current
  // field rather than an exact but old one; levels come down again when the rate has room (the
  // sender was not short of it for a while). 0 keeps full quality.
  int maxQualityLevel = 4;
  // Short of rate needs at least this share of the rate spent over a ladder interval (pacing
  // leaves some change waiting in most polls whatever the rate, so waiting alone says nothing).
  double fullUse = 0.85;
  // s without being short before a level comes down; doubled (up to maxDescentHold) each time
  // the level must go up again soon after, back to descentHold once a level held for 2 s.
  double descentHold = 1.0;
  double maxDescentHold = 4.0;
  // Each level also sends coarser precision (brick_precision.h): versions are rounded to
  // min(level, maxPrecision), so that the changes the age bound forces out cost fewer bits.
  // Bricks held coarser than the level allows are refined once the level comes down. 0: the
  // codec's own precision always (clients of protocol version 4).
  int maxPrecision = kMaxPrecision;
  double qualityInterval = 0.25;   // s between ladder decisions
  double minResendTimeout = 0.05;  // s; the timeout is max(this, 2 x smoothed round trip)
  double initialRtt = 0.1;         // s, until acks give samples
  double settleTime = 0.2;         // s: a version this old is sent even below the thresholds
  double refreshInterval = 1.0;    // s: an unacknowledged brick is sent at least this often
  // s: a brick is sent self-contained at least this often even while the client acknowledges
  // versions that residuals could build on. Residuals on an acknowledged version are always
  // safe (the client applies them only on that exact version and asks for repair otherwise),
  // so this is a safety net, and a long one: a self-contained brick costs several times a
  // residual. A brick the client does not hold, or whose acknowledged version the publisher
  // no longer has, is always sent self-contained.
  double selfContainedInterval = 30.0;
  float irradianceThreshold = 0.004f;  // max |delta e| (gamma-encoded irradiance)
  // When > 0, a version also counts as below the thresholds only while the mean |delta e| over
  // the brick's irradiance is below this. Set irradianceThreshold well above it: with ray
  // noise some texel always moves past a small maximum, while a moving light moves the mean.
  float irradianceMeanThreshold = 0.0f;
  float depthThreshold = 0.005f;  // max |delta mean depth| / maxRayDistance
  float occlusionThreshold = 0.02f;
  // max |delta| of a relocation offset component, x the spacing. Relocation jitters with ray
  // noise by a few percent of the spacing, which moves the sampled light very little; a probe
  // state change (to or from inside geometry) always counts.
  float offsetThreshold = 0.01f;
  // Lost updates of several fragments resent as they were (see above) that may be held open at
  // once, in updates and payload bytes: half the receiver's default reassembly caps, so that
  // updates in flight fit beside them.
  std::size_t maxLostUpdates = ReassemblyOptions{}.maxUpdates / 2;
  std::size_t maxLostBytes = ReassemblyOptions{}.maxBytes / 2;
  double heartbeatInterval = 0.25;  // s: an empty datagram when nothing else was sent
  double agingBricksPerSecond =
      8;  // priority: each second waiting counts as this many bricks nearer
  std::size_t maxDatagramsPerPoll = 4096;
};

struct SenderStats {
  std::uint64_t datagrams = 0, bytes = 0;
  std::uint64_t updates = 0, residualUpdates = 0, resends = 0, fragments = 0;
  std::uint64_t repairedFragments = 0;  // fragments sent again on a client's report of gaps
  std::uint64_t skipped = 0;            // brick-polls held back by the perceptual thresholds
  // Why each update was sent (they add up to `updates`): the client held nothing of the brick
  // (or the sender knew of nothing it held); the change passed a threshold (by quantity:
  // irradiance maximum, irradiance mean, depth, occlusion, relocation offset, probe state); the
  // version was older than the settle time; the brick had not been sent for the refresh interval;
  // the client asked for a repair; or the version was sent before and not acknowledged in time.
  struct Reasons {
    std::uint64_t first = 0, irradiance = 0, irradianceMean = 0, depth = 0, occlusion = 0,
                  offset = 0, state = 0, settled = 0, refresh = 0, repair = 0, timeout = 0,
                  refine = 0;  // the version held, again at a finer precision
  } reasons;
  std::uint64_t coarseUpdates = 0;  // updates sent at a precision level above 0
  std::uint64_t badMessages = 0;
  std::uint64_t aged = 0;  // updates sent because a change reached the age bound's lead
  // Resume (protocol version 7): claims of this field taken, claims of another field (taken
  // as holding nothing), bricks taken as held, and bricks refused for a version past the
  // newest here.
  std::uint64_t resumes = 0, resumeMismatches = 0, resumedBricks = 0, resumeRefusedBricks = 0;
  double srtt = 0, rttvar = 0;  // smoothed round trip and its mean deviation, s
};

// What the client holds, as the sender knows it from acks, against the current field.
struct HeldFieldReport {
  // PSNR of the irradiance (gamma-encoded e, peak 1) of every brick the client holds against
  // the brick's current version, over all their codes; kHeldPsnrCap when they are equal.
  double psnrDb = 0;
  double oldestChangeSeconds = 0;  // age of the oldest change it does not hold
  std::size_t heldBricks = 0, currentBricks = 0, pendingBricks = 0;
  std::size_t unknownBricks = 0;  // held versions no longer in the history (not in the PSNR)
};
inline constexpr double kHeldPsnrCap = 99.0;

// How two versions of a brick differ (brickChange), shared by the senders of one publisher.
// A brick version's content never changes, so the comparison of (version, reference) is the
// same for every client, and clients that acknowledged the same versions ask for the same
// pairs: comparing once per pair instead of once per client keeps the perceptual skip's cost
// from growing with the client count. Senders on several threads may share it (the server
// polls them in parallel); the figures are read while none of them runs.
class BrickChangeCache {
 public:
  explicit BrickChangeCache(std::size_t maxEntries = 16384)
      : maxEntries_(maxEntries), pruneAt_(std::min(kMinPruneAt, maxEntries)) {}
  // The change from `ref` to `version` of the brick; nullopt when either version has left the
  // publisher's history.
  // `refPrecision`: the level `ref` is held at (brick_precision.h).
  std::optional<BrickChange> get(const FieldPublisher& publisher, int cascade, int brick,
                                 std::uint64_t version, std::uint64_t ref, int refPrecision = 0);
  std::uint64_t computed() const { return computed_; }
  std::size_t entries() const { return entries_.size(); }
  // Heap bytes held, estimated: a node per entry (key, value, next pointer, cached hash) and
  // the bucket array. At most maxEntries entries (about 1.3 MB at the default 16,384); in
  // practice about twice the live pairs (get() drops pairs of versions no longer current).
  std::size_t bytes() const {
    return entries_.size() *
               (sizeof(Key) + sizeof(std::optional<BrickChange>) + 2 * sizeof(void*)) +
           entries_.bucket_count() * sizeof(void*);
  }
  std::uint64_t hits() const { return hits_; }

 private:
  struct Key {
    int cascade, brick;
    std::uint64_t version, ref;
    int refPrecision;
    bool operator==(const Key&) const = default;
  };
  struct KeyHash {
    std::size_t operator()(const Key& k) const {
      std::uint64_t h = k.version * 0x9E3779B97F4A7C15ull ^ k.ref * 0xC2B2AE3D27D4EB4Full;
      h ^= std::uint64_t(k.cascade) << 48 ^ std::uint64_t(k.brick) << 20 ^
           std::uint64_t(k.refPrecision) << 8;
      return std::size_t(h ^ (h >> 29));
    }
  };
  static constexpr std::size_t kMinPruneAt = 256;
  std::size_t maxEntries_;
  std::size_t pruneAt_;  // entries at which pairs of old versions are dropped
  // nullopt: a version was missing from the history (it never comes back).
  std::unordered_map<Key, std::optional<BrickChange>, KeyHash> entries_;
  std::uint64_t computed_ = 0, hits_ = 0;
  std::mutex mutex_;  // guards the above; comparisons run outside it
};

class StreamSender {
 public:
  // `changes`, when given, is shared with the other senders of `publisher` and must outlive
  // this sender; without one the sender compares versions itself.
  StreamSender(FieldPublisher& publisher, std::uint32_t sessionId, SenderOptions options = {},
               BrickChangeCache* changes = nullptr);

  // A session message frame from the client. Acks, repair requests and viewer poses are used;
  // anything else, or a frame that fails decoding, is an Error and changes nothing.
  Status onMessage(std::span<const std::uint8_t> frame, double now);
  Status onMessage(const SessionMessage& message, double now);

  // The client will say what it holds (a Resume): until then, or `until`, only heartbeats.
  void awaitResume(double until) { awaitResumeUntil_ = until; }

  // Datagrams to send now (each at most kMaxDatagramBytes), within the rate limit.
  std::vector<std::vector<std::uint8_t>> poll(double now);

  const SenderStats& stats() const { return stats_; }
  // The brick versions the last poll() sent this client for the first time (not resends nor
  // refinements), for the server's publish-to-send latency.
  const std::vector<std::uint64_t>& firstSends() const { return firstSends_; }
  // Bricks whose current version the client has not acknowledged.
  std::size_t pendingBricks() const;
  double resendTimeout() const;
  // The held field's error and age, computed now (one pass over the bricks).
  HeldFieldReport heldField(double now);
  // The report the server sends the client (StreamReport), from heldField and the controller.
  StreamReportMsg report(double now);
  // The rate the sender sends at now, bytes/s (the controller's, within the ceiling).
  double sendRate() const;
  const RateEstimate& rateEstimate() const { return rate_.estimate(); }
  int qualityLevel() const { return level_; }

 private:
  enum class Reason : std::uint8_t {
    First,
    Irradiance,
    IrradianceMean,
    Depth,
    Occlusion,
    Offset,
    State,
    Settled,
    Refresh,
    Repair,
    Timeout,
    Aged,
    Refine
  };
  struct Track {
    std::uint64_t acked = 0;  // what the client holds, from acks and repair requests
    int ackedPrecision = 0;   // the precision level it holds `acked` at
    std::uint64_t sent = 0;   // newest version sent
    int sentPrecision = 0, sentBasePrecision = 0;  // its level, and its base's
    std::uint32_t sentBytes = 0;                   // its payload
    double sentAt = -1e30;
    bool resent = false;  // sent more than once: no round-trip sample (Karn)
    double selfContainedAt = -1e30;
    double pendingSince = -1;
    // When the oldest change the client lacks was published (changedAfter(acked)), for
    // `changedFor` = the acked version it was looked up for; < 0: not known yet.
    double changedAt = -1;
    std::uint64_t changedFor = ~std::uint64_t(0);
    bool repair = false;  // the client asked: bypass the thresholds
    // Cached perceptual decision for (current version, reference version).
    std::uint64_t skipVersion = 0, skipRef = 0;
    int skipRefPrecision = 0;
    bool skipBelow = false;
    Reason skipReason = Reason::First;  // which threshold the change passed, when not below
    int skipLevel = 0;                  // the quality level the decision was taken at
    float skipChange = 0;               // the change's mean |delta e|, its perceptual value
  };
  struct Candidate {
    int cascade;
    int brick;
    double key;
    Reason reason;
    bool again;    // the lost update, resent as it was
    bool missing;  // the client holds no version of the brick
    bool aged;     // its oldest change nears the age bound
  };
  // Fragments a client asked for again (an Ack's gaps), sent first at the next poll. At most
  // one per brick: a newer report replaces the older one.
  struct Repair {
    int cascade;
    int brick;
    std::shared_ptr<const EncodedUpdate> update;
    std::vector<std::uint16_t> fragments;
  };
  Status onAck(const AckMsg& ack, double now);
  void queueRepair(const FragmentGapMsg& gap);
  Status onRepair(const RepairRequestMsg& repair);
  // What the client holds, from the endpoint it left: versions of this field up to the newest
  // here become its acknowledged versions (PROTOCOL.md "Resuming a session").
  Status onResume(const ResumeMsg& resume, double now);
  // Whether the change from `ref` (at `refPrecision`) to `version` is below every threshold; if
  // not, t.skipReason names the first threshold it passed.
  bool belowThresholds(Track& t, int k, int b, std::uint64_t version, std::uint64_t ref,
                       int refPrecision);
  // The change from `ref` held at `refPrecision` to `version` (from the shared cache when there
  // is one); nullopt when either version left the history.
  std::optional<BrickChange> changeOf(int k, int b, std::uint64_t version, std::uint64_t ref,
                                      int refPrecision);
  // The precision level versions are sent at now: the quality level's, within maxPrecision.
  int precisionNow() const { return std::min(level_, options_.maxPrecision); }
  // The client acknowledged what was last sent, at the level it was sent at.
  static bool heldAsSent(const Track& t) {
    return t.acked == t.sent && t.ackedPrecision == t.sentPrecision;
  }
  // Datagrams packed but not sent yet. A poll packs whole updates, and an update of many
  // fragments would enter a router's queue at once; they leave from here at the pacing rate,
  // so that no more than the bucket (pacingBurstSeconds) leaves in one poll whatever an
  // update's size (a drop-tail queue of 100 ms at 0.5 Mbit/s holds 5 datagrams).
  struct Paced {
    std::vector<std::uint8_t> datagram;
    std::uint32_t sequence;
    // Bricks whose update (or repair) ends in this datagram: sent when it leaves, which is
    // when their resend timeouts and round-trip samples count from; and the versions among
    // them sent for the first time.
    std::vector<std::pair<int, int>> completes;
    std::vector<std::uint64_t> firstSends;
  };
  // Chooses repairs and updates for the bucket's tokens and packs them into paced_; says
  // whether bricks waited for tokens and whether changes at the age bound did.
  void pack(double now, bool& waited, bool& changesWaited);
  // Sends from paced_ while the bucket has tokens.
  void release(double now, std::vector<std::vector<std::uint8_t>>& out);
  void count(Reason reason);
  double distanceInBricks(int k, int b) const;
  void adjustQuality(double now);
  // Age of the oldest change of the brick the client does not hold (0 when it holds the
  // current version); for a brick it holds nothing of, since the sender first saw it pending.
  double changeAge(Track& t, int k, int b, double now);

  FieldPublisher& publisher_;
  std::uint32_t sessionId_;
  SenderOptions options_;
  BrickChangeCache* changes_ = nullptr;
  std::vector<std::vector<Track>> tracks_;
  std::optional<glm::vec3> viewer_;
  double tokens_ = 0, lastPoll_ = -1, lastDatagramAt_ = -1e30;
  std::uint32_t sequence_ = 0;
  std::vector<Repair> repairs_;
  std::deque<Paced> paced_;
  bool lastChangesWaited_ = false;  // from the last poll that packed
  RateController rate_;
  // Polls since the last arrival report whose bucket had more than it could spend (the sender
  // had less to send than the rate allowed), of all polls then.
  std::uint32_t appLimitedPolls_ = 0, reportPolls_ = 0;
  // The quality ladder: the level, and over the current interval the polls that left bricks
  // waiting for tokens and the oldest change seen.
  int level_ = 0;
  double levelAt_ = 0, roomySince_ = -1;
  std::uint32_t shortPolls_ = 0, levelPolls_ = 0;
  // Over the current interval: the bytes the rate allowed and the bytes that left.
  double levelAllowed_ = 0, levelSent_ = 0;
  double levelDownAt_ = -1e30, levelUpAt_ = -1e30;
  double descentHold_ = 1.0;  // options_.descentHold, set in the constructor
  double oldestPending_ = 0;
  SenderStats stats_;
  std::vector<std::uint64_t> firstSends_;
  double awaitResumeUntil_ = -1;
  bool resumeHeard_ = false;
};

}  // namespace pc
