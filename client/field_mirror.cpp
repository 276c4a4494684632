#include "field_mirror.h"

#include <algorithm>
#include <cstring>

namespace pc::client {

std::vector<TileRun> brickTileRuns(const gpu::CascadeDesc& c, int brick) {
  std::vector<TileRun> runs;
  const int first = brick * gpu::PC_PROBES_PER_BRICK;
  const int end = first + gpu::PC_PROBES_PER_BRICK;
  for (int slot = first; slot < end;) {
    const int x = slot % gpu::PC_ATLAS_TILES_PER_ROW;
    const int n = std::min(end - slot, gpu::PC_ATLAS_TILES_PER_ROW - x);
    runs.push_back({x, c.atlasTileRow + slot / gpu::PC_ATLAS_TILES_PER_ROW, n});
    slot += n;
  }
  return runs;
}

namespace {

bool sameLayout(const Field& a, const Field& b) {
  if (a.desc.cascadeCount != b.desc.cascadeCount || a.desc.probeCount != b.desc.probeCount ||
      a.irradiance.width != b.irradiance.width || a.irradiance.height != b.irradiance.height ||
      a.depth.width != b.depth.width || a.depth.height != b.depth.height ||
      a.occlusion.width != b.occlusion.width || a.occlusion.height != b.occlusion.height) {
    return false;
  }
  for (int k = 0; k < a.desc.cascadeCount; ++k) {
    const gpu::CascadeDesc &x = a.desc.cascades[k], &y = b.desc.cascades[k];
    if (x.counts != y.counts || x.firstProbe != y.firstProbe || x.atlasTileRow != y.atlasTileRow)
      return false;
  }
  return true;
}

void copyTiles(Atlas& dst, const Atlas& src, const gpu::CascadeDesc& c, int brick, int tileSize) {
  for (const TileRun& run : brickTileRuns(c, brick)) {
    const std::size_t rowFloats = std::size_t(run.count) * tileSize * src.channels;
    for (int y = 0; y < tileSize; ++y) {
      const int px = run.tileX * tileSize, py = run.tileY * tileSize + y;
      std::memcpy(dst.at(px, py), src.at(px, py), rowFloats * sizeof(float));
    }
  }
}

}  // namespace

void FieldMirror::reset(Field field, double now) {
  std::lock_guard lock(mutex_);
  bricks_.assign(field.desc.cascadeCount, {});
  pending_.clear();
  for (int k = 0; k < field.desc.cascadeCount; ++k) {
    const int count = gpu::pcBrickCount(field.desc.cascades[k]);
    bricks_[k].resize(count);
    for (int b = 0; b < count; ++b) {
      const std::uint64_t v =
          std::size_t(b) < field.brickVersions[k].size() ? field.brickVersions[k][b] : 0;
      bricks_[k][b] = {v, now, true};
      pending_.push_back({k, b});
    }
  }
  field_ = std::move(field);
}

bool FieldMirror::applyBrick(const Field& source, BrickId id, std::uint64_t version, double now) {
  std::lock_guard lock(mutex_);
  if (!field_ || !sameLayout(*field_, source)) return false;
  if (id.cascade < 0 || id.cascade >= field_->desc.cascadeCount) return false;
  if (id.brick < 0 || std::size_t(id.brick) >= bricks_[id.cascade].size()) return false;
  BrickState& state = bricks_[id.cascade][id.brick];
  if (version <= state.version) return false;
  const gpu::CascadeDesc& c = field_->desc.cascades[id.cascade];
  copyTiles(field_->irradiance, source.irradiance, c, id.brick, gpu::PC_IRRADIANCE_TEXELS + 2);
  copyTiles(field_->depth, source.depth, c, id.brick, gpu::PC_DEPTH_TEXELS + 2);
  copyTiles(field_->occlusion, source.occlusion, c, id.brick, gpu::PC_OCCLUSION_TEXELS + 2);
  const int first = c.firstProbe + id.brick * gpu::PC_PROBES_PER_BRICK;
  std::copy_n(source.probes.begin() + first, gpu::PC_PROBES_PER_BRICK,
              field_->probes.begin() + first);
  field_->brickVersions[id.cascade][id.brick] = version;
  field_->version = std::max(field_->version, version);
  const bool wasPending = state.pending;
  state = {version, now, true};
  if (!wasPending) pending_.push_back(id);
  return true;
}

bool FieldMirror::movePlaces(const Field& source) {
  std::lock_guard lock(mutex_);
  if (!field_ || !sameLayout(*field_, source)) return false;
  bool moved = false;
  for (int k = 0; k < field_->desc.cascadeCount; ++k) {
    gpu::CascadeDesc& c = field_->desc.cascades[k];
    const gpu::CascadeDesc& from = source.desc.cascades[k];
    if (c.origin == from.origin && c.scroll == from.scroll) continue;
    c.origin = from.origin;
    c.scroll = from.scroll;
    const auto first = source.probes.begin() + c.firstProbe;
    std::copy(first, first + gpu::pcSlotCount(c), field_->probes.begin() + c.firstProbe);
    moved = true;
  }
  if (moved) ++placesSerial_;
  return moved;
}

std::uint64_t FieldMirror::placesSerial() const {
  std::lock_guard lock(mutex_);
  return placesSerial_;
}

bool FieldMirror::present() const {
  std::lock_guard lock(mutex_);
  return field_.has_value();
}

FieldAge FieldMirror::age(double now) const {
  std::lock_guard lock(mutex_);
  FieldAge a;
  if (!field_) return a;
  a.present = true;
  a.version = field_->version;
  a.pendingBricks = int(pending_.size());
  double newest = -1e300, oldest = 1e300;
  for (const auto& cascade : bricks_) {
    for (const BrickState& b : cascade) {
      newest = std::max(newest, b.arrived);
      oldest = std::min(oldest, b.arrived);
    }
  }
  if (newest > -1e300) {
    a.newestSeconds = now - newest;
    a.oldestSeconds = now - oldest;
  }
  return a;
}

std::uint64_t FieldMirror::brickVersion(BrickId id) const {
  std::lock_guard lock(mutex_);
  if (id.cascade < 0 || std::size_t(id.cascade) >= bricks_.size() || id.brick < 0 ||
      std::size_t(id.brick) >= bricks_[id.cascade].size()) {
    return 0;
  }
  return bricks_[id.cascade][id.brick].version;
}

std::vector<std::vector<std::uint64_t>> FieldMirror::brickVersions() const {
  std::lock_guard lock(mutex_);
  std::vector<std::vector<std::uint64_t>> out(bricks_.size());
  for (std::size_t k = 0; k < bricks_.size(); ++k) {
    out[k].reserve(bricks_[k].size());
    for (const BrickState& b : bricks_[k]) out[k].push_back(b.version);
  }
  return out;
}

void FieldMirror::markAllPending() {
  std::lock_guard lock(mutex_);
  pending_.clear();
  for (int k = 0; k < int(bricks_.size()); ++k) {
    for (int b = 0; b < int(bricks_[k].size()); ++b) {
      bricks_[k][b].pending = true;
      pending_.push_back({k, b});
    }
  }
}

std::vector<BrickId> FieldMirror::takePending(int maxBricks) {
  std::lock_guard lock(mutex_);
  const std::size_t n = std::min<std::size_t>(pending_.size(), std::size_t(std::max(0, maxBricks)));
  std::vector<BrickId> taken(pending_.begin(), pending_.begin() + std::ptrdiff_t(n));
  pending_.erase(pending_.begin(), pending_.begin() + std::ptrdiff_t(n));
  for (const BrickId& id : taken) bricks_[id.cascade][id.brick].pending = false;
  return taken;
}

void FieldMirror::read(const std::function<void(const Field&)>& read) const {
  std::lock_guard lock(mutex_);
  if (field_) read(*field_);
}

std::optional<gpu::FieldDesc> FieldMirror::desc() const {
  std::lock_guard lock(mutex_);
  if (!field_) return std::nullopt;
  return field_->desc;
}

}  // namespace pc::client
