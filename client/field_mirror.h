// The client's copy of the probe field: the CPU atlases and probe records (common/field.h),
// plus per brick the version held, when it arrived and whether the GPU has it yet. Whoever
// receives field data (the baked file now, the network later, on its own thread) writes here;
// the frame loop takes the bricks the GPU lacks, a bounded number per frame, and never waits.
#pragma once

#include <cstdint>
#include <functional>
#include <mutex>
#include <optional>
#include <vector>

#include "common/field.h"

namespace pc::client {

struct BrickId {
  int cascade = 0;
  int brick = 0;
  bool operator==(const BrickId&) const = default;
};

struct FieldAge {
  bool present = false;      // any field at all
  double newestSeconds = 0;  // age of the most recent brick
  double oldestSeconds = 0;  // age of the stalest brick
  std::uint64_t version = 0;
  int pendingBricks = 0;  // received, not yet on the GPU
};

class FieldMirror {
 public:
  // Replaces everything with `field` (a baked file, a full snapshot); every brick becomes
  // pending. `now` is in seconds on the caller's clock.
  void reset(Field field, double now);
  // Copies one brick (its probe records and tiles, borders included) from `source`, which must
  // have the same layout, and marks it pending. Returns false (and changes nothing) when the
  // layout differs or the brick does not exist, or when `version` is not newer than the one held.
  bool applyBrick(const Field& source, BrickId id, std::uint64_t version, double now);

  // Cascades that follow the viewers moved (common/field_scroll.h): takes each moved cascade's
  // origin and scroll from `source` (of the same layout otherwise) with all its probe records
  // at once, so that no frame shows the new places with the old records. True when a cascade
  // moved; placesSerial() then counts one more.
  bool movePlaces(const Field& source);
  // Bumped by every movePlaces that moved a cascade: the GPU copy re-reads the places and the
  // records of the moved cascades.
  std::uint64_t placesSerial() const;

  bool present() const;
  FieldAge age(double now) const;
  std::uint64_t brickVersion(BrickId id) const;
  // Every brick's version, [cascade][brick], read under one lock (the probe view's flashes).
  std::vector<std::vector<std::uint64_t>> brickVersions() const;

  // Makes every brick pending again: a new GPU copy of the field needs all of them.
  void markAllPending();
  // Pending bricks, oldest arrival first, at most `maxBricks`; they stop being pending. The
  // GPU side uploads them and calls this again next frame for more.
  std::vector<BrickId> takePending(int maxBricks);
  // Runs `read` with the field under the mirror's lock (for copying tiles into staging).
  void read(const std::function<void(const Field&)>& read) const;
  // The layout (cascades, atlas sizes), or nothing before the first reset.
  std::optional<gpu::FieldDesc> desc() const;

 private:
  struct BrickState {
    std::uint64_t version = 0;
    double arrived = 0;
    bool pending = false;
  };
  mutable std::mutex mutex_;
  std::optional<Field> field_;
  std::uint64_t placesSerial_ = 0;
  std::vector<std::vector<BrickState>> bricks_;  // [cascade][brick]
  std::vector<BrickId> pending_;                 // arrival order
};

// Tile rectangles (in tiles) of a brick in an atlas: runs of consecutive slots in one tile
// row. A brick's 64 slots are contiguous, so this is one rectangle unless the run wraps a row.
struct TileRun {
  int tileX = 0, tileY = 0, count = 0;
};
std::vector<TileRun> brickTileRuns(const gpu::CascadeDesc& cascade, int brick);

}  // namespace pc::client
