// The server's side of streaming that every client shares: after each field update, the bricks
// whose version changed are quantized once and kept in a short per-brick history (the bases a
// residual may refer to); encoded updates come from one EncodeCache. Each client's StreamSender
// reads from here. Senders may read it from several threads at once (encoded(), find() and the
// const accessors; the encode cache and the coarse versions have their own mutex), but
// commit() must not run beside any of them: FieldHub holds a shared lock around the senders'
// polls and an exclusive one around commit(). prepare() may run outside that lock on the thread
// that commits.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <utility>
#include <vector>

#include "common/field.h"
#include "common/histogram.h"
#include "common/result.h"
#include "protocol/brick_codec.h"
#include "protocol/brick_precision.h"
#include "protocol/encode_cache.h"
#include "protocol/session_messages.h"

namespace pc {

struct PublisherOptions {
  int historyVersions = 4;  // newest quantized versions kept per brick
  // Older versions that were sent to a client, kept beyond historyVersions: what clients hold
  // and acknowledge is a version that was sent, often many versions back when the sender holds
  // small changes back, and residuals need it as their base. Many clients hold many different
  // versions: the age bound sends each of them a brick about once a second, each at whatever
  // version was current then, so at 10 updates/s their bases spread over about ten versions.
  // With 2 kept, most of them had left and bricks went self-contained (probecast-bench load,
  // 20 clients, 32 rays, 10 updates/s: 1,100 kbit/s per client, oldest change p95 5.46 s;
  // with 16: 397 kbit/s and 0.80 s).
  int sentVersions = 16;
  // Caps on all bricks' histories together (beyond the current versions) and on the encoded
  // updates. Both are also bounded by the field itself (FieldPublisher::historyBoundBytes,
  // cacheBoundBytes), which for a small field is far below these: the caps bind only from
  // about 110 bricks (cache) and 540 bricks (history) with the default versions kept.
  std::size_t maxHistoryBytes = 256u << 20;
  std::size_t maxCacheBytes = 64u << 20;
  int zstdLevel = 3;
  // Cap on the coarsened copies of versions (find() at a precision level) kept for reuse.
  // Every client at a coarse level compares against and encodes on top of its base at that
  // level; coarsening it afresh for each of them was the network thread's largest cost with
  // many clients. Past the cap every kept copy is dropped and coarsened again when asked for.
  std::size_t maxCoarseBytes = 64u << 20;
  // Codes that moved less than this since the brick's previous version keep their previous
  // value (see holdSmallChanges); zero (the default) quantizes every version exactly.
  DeadZone deadZone;
  // The run's field epoch (SessionInfoMsg::fieldEpoch); 0: drawn at random. A relay passes on
  // its field server's, so that clients resume across the endpoints of one run.
  std::uint64_t epoch = 0;
};

// Bricks of one field update, quantized (and held by the dead zone) but not yet published.
struct PreparedBricks {
  struct Brick {
    int cascade;
    std::size_t brick;
    std::uint64_t version;
    std::shared_ptr<const QuantizedBrick> content;
  };
  std::uint64_t fieldVersion = 0;
  std::vector<Brick> bricks;
  std::uint64_t quantizedCodes = 0, heldCodes = 0;
};

// Buckets of the encode-time histogram: 10 us to 0.33 s, doubling (one brick's zstd encode
// takes tens of microseconds to a few milliseconds).
inline std::vector<double> encodeTimeBounds() { return exponentialBounds(1e-5, 2.0, 16); }

struct BrickVersion {
  std::uint64_t version = 0;
  double publishedAt = 0;  // time publish() first saw this version
  std::shared_ptr<const QuantizedBrick> content;
  bool sent = false;  // encoded for a client at least once (see PublisherOptions::sentVersions)
  // The content at precision levels 1..kMaxPrecision, once asked for (FieldPublisher::find).
  mutable std::array<std::shared_ptr<const QuantizedBrick>, kMaxPrecision> coarse{};
};

class FieldPublisher {
 public:
  // Takes the field's layout (cascades, brick counts); publish() must get fields of this layout.
  explicit FieldPublisher(const Field& layout, PublisherOptions options = {});

  // Quantizes every brick whose version differs from the one held (version 0: no data yet).
  // The same as commit(prepare(field), now).
  Status publish(const Field& field, double now);
  // The expensive half: quantizes the changed bricks. It reads only what commit() changes, so
  // the thread that publishes may run it without the lock that guards the senders (FieldHub),
  // which then wait only for commit().
  Result<PreparedBricks> prepare(const Field& field) const;
  // Makes prepared bricks the current versions. `prepared` must come from prepare() on this
  // publisher with no commit in between.
  void commit(PreparedBricks prepared, double now);

  std::uint64_t fieldVersion() const { return fieldVersion_; }
  const SessionInfoMsg& sessionInfo() const { return info_; }
  // Cascades that follow the viewers moved (SceneStateMsg::cascadePlaces, one per cascade;
  // empty changes nothing): SessionInfo and the senders' brick positions use the new places.
  void moveCascades(const std::vector<CascadePlaceMsg>& places);
  int cascadeCount() const { return int(bricks_.size()); }
  int brickCount(int cascade) const { return int(bricks_[cascade].size()); }
  const gpu::CascadeDesc& cascade(int k) const { return info_.cascades[k]; }
  // The newest version of a brick (version 0 and no content when never published).
  const BrickVersion& current(int cascade, int brick) const {
    return bricks_[cascade][brick].back();
  }
  // When the brick first changed after `version`: the publish time of its oldest version newer
  // than that (of the last kPublishTimesKept versions: past them, the oldest kept, which makes
  // the change at least that old); nullopt when `version` is current or newer.
  std::optional<double> changedAfter(int cascade, int brick, std::uint64_t version) const;
  static constexpr std::size_t kPublishTimesKept = 64;
  // Content of an older (or the current) version, while it is in the history; else null.
  std::shared_ptr<const QuantizedBrick> find(int cascade, int brick, std::uint64_t version) const;
  // Encoded update for `version` on top of `base` (0: self-contained), from the cache or
  // encoded now. Null when either version is no longer in the history. `precision` rounds the
  // version's codes (brick_precision.h); `basePrecision` is the level the base is held at.
  std::shared_ptr<const EncodedUpdate> encoded(int cascade, int brick, std::uint64_t version,
                                               std::uint64_t base, int precision = 0,
                                               int basePrecision = 0);
  // Content of a version at a precision level (find() at level 0); null when not in the
  // history.
  std::shared_ptr<const QuantizedBrick> find(int cascade, int brick, std::uint64_t version,
                                             int precision) const;

  const EncodeCache& cache() const { return cache_; }
  // Bytes of the quantized versions held beyond each brick's current one (an upper bound:
  // versions with unchanged content share it).
  std::size_t historyBytes() const { return historyBytes_; }
  // Bytes of the current versions (every brick that has data).
  std::size_t currentBytes() const { return currentBytes_; }

  // Upper bounds on what the publisher holds, from the field's brick count B and the versions
  // kept per brick V = historyVersions + sentVersions (the current one included), after every
  // commit whatever the clients do:
  //   history (beyond current): min(maxHistoryBytes, B x (V - 1) x brick bytes);
  //   encode cache: min(maxCacheBytes, B x V x maxEncodedBrickBytes()) plus one entry, because
  //   senders only ever send a brick's current version, so once a brick has a newer version
  //   its older entries are dropped, and the current version has at most V bases (0 or a
  //   version in the history).
  // The built-in scene (9 bricks, V = 20, 98,816-byte bricks): 16.90 MB and 17.96 MB.
  std::size_t historyBoundBytes() const;
  std::size_t cacheBoundBytes() const;
  // The figures below are read while no sender runs (with FieldHub's lock held).
  std::uint64_t encodes() const { return encodes_; }
  // Seconds spent encoding those updates (cache misses), for the server's metrics.
  double encodeSeconds() const { return encodeSeconds_; }
  // The same encodes by duration, seconds (encodeTimeBounds), for the server's histogram.
  const Histogram& encodeTimes() const { return encodeTimes_; }
  // Bytes of the coarsened copies kept (at most PublisherOptions::maxCoarseBytes plus one).
  std::size_t coarseBytes() const { return coarseBytes_; }
  // Codes the dead zone held at their previous value, and codes quantized, in all.
  std::uint64_t heldCodes() const { return heldCodes_; }
  std::uint64_t quantizedCodes() const { return quantizedCodes_; }

 private:
  PublisherOptions options_;
  SessionInfoMsg info_;
  std::uint64_t fieldVersion_ = 0;
  // [cascade][brick]: oldest first; back() is the current version (a zero entry at start).
  std::vector<std::vector<std::deque<BrickVersion>>> bricks_;
  // [cascade][brick]: (version, publish time) of the latest versions, oldest first. Without
  // content, so kept far longer than the history: the age of what a client lacks needs them.
  std::vector<std::vector<std::deque<std::pair<std::uint64_t, double>>>> published_;
  std::size_t totalBricks_ = 0;
  std::size_t historyBytes_ = 0, currentBytes_ = 0;
  // Guards what readers change: the encode cache, the sent flags, the coarse copies and the
  // encode figures. Encoding and coarsening run outside it.
  mutable std::mutex readersMutex_;
  EncodeCache cache_;
  mutable std::size_t coarseBytes_ = 0;
  void dropCoarse(const BrickVersion& v) const;  // with readersMutex_ held
  std::uint64_t encodes_ = 0;
  double encodeSeconds_ = 0;
  Histogram encodeTimes_{encodeTimeBounds()};
  std::uint64_t heldCodes_ = 0, quantizedCodes_ = 0;

  void trim(std::deque<BrickVersion>& history);
};

}  // namespace pc
