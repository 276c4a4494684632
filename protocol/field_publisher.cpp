#include "field_publisher.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <random>
#include <string>

#include "protocol/brick_precision.h"

namespace pc {

namespace {
constexpr std::size_t kBrickBytes = brick_layout::kCodes * sizeof(std::uint16_t);

std::size_t totalBrickCount(const Field& layout) {
  std::size_t n = 0;
  for (int k = 0; k < layout.cascadeCount(); ++k) n += gpu::pcBrickCount(layout.cascade(k));
  return n;
}

PublisherOptions checked(PublisherOptions o) {
  if (o.historyVersions < 1) o.historyVersions = 1;
  if (o.sentVersions < 0) o.sentVersions = 0;
  return o;
}

std::size_t versionsKept(const PublisherOptions& o) {
  return std::size_t(o.historyVersions) + std::size_t(o.sentVersions);
}

std::size_t cacheBound(const PublisherOptions& o, std::size_t bricks) {
  return std::min(o.maxCacheBytes, bricks * versionsKept(o) * maxEncodedBrickBytes());
}

// A fresh run's epoch: random, never 0 (which means "not stated").
std::uint64_t drawEpoch() {
  std::random_device rd;
  return (std::uint64_t(rd()) << 32 | rd()) | 1u;
}
}  // namespace

FieldPublisher::FieldPublisher(const Field& layout, PublisherOptions options)
    : options_(checked(options)),
      info_(sessionInfoFor(layout)),
      totalBricks_(totalBrickCount(layout)),
      cache_(cacheBound(options_, totalBricks_)) {
  bricks_.resize(layout.cascadeCount());
  published_.resize(layout.cascadeCount());
  for (int k = 0; k < layout.cascadeCount(); ++k) {
    bricks_[k].resize(gpu::pcBrickCount(layout.cascade(k)));
    for (auto& h : bricks_[k]) h.push_back(BrickVersion{});
    published_[k].resize(bricks_[k].size());
  }
  info_.fieldEpoch = options_.epoch != 0 ? options_.epoch : drawEpoch();
}

std::size_t FieldPublisher::historyBoundBytes() const {
  return std::min(options_.maxHistoryBytes,
                  totalBricks_ * (versionsKept(options_) - 1) * kBrickBytes);
}

std::size_t FieldPublisher::cacheBoundBytes() const {
  // One entry beyond the cap: the cache keeps its newest entry even when that alone is over.
  return cacheBound(options_, totalBricks_) + maxEncodedBrickBytes();
}

Result<PreparedBricks> FieldPublisher::prepare(const Field& field) const {
  if (field.cascadeCount() != cascadeCount()) return Error{"publish: field layout changed"};
  for (int k = 0; k < cascadeCount(); ++k) {
    if (field.brickVersions[k].size() != bricks_[k].size()) {
      return Error{"publish: cascade " + std::to_string(k) + " changed its brick count"};
    }
  }
  PreparedBricks p;
  p.fieldVersion = field.version;
  for (int k = 0; k < cascadeCount(); ++k) {
    for (std::size_t b = 0; b < bricks_[k].size(); ++b) {
      const std::uint64_t v = field.brickVersions[k][b];
      if (v == 0 || v == bricks_[k][b].back().version) continue;
      p.bricks.push_back(PreparedBricks::Brick{k, b, v, nullptr});
    }
  }
  // Bricks quantize independently, on every core: a GPU tracer changes every brick of a
  // 300-brick field in a few milliseconds, and quantizing them one after another took 80 ms
  // of the field thread's tick.
  std::vector<std::uint64_t> held(p.bricks.size(), 0);
  tbb::parallel_for(std::size_t(0), p.bricks.size(), [&](std::size_t i) {
    PreparedBricks::Brick& item = p.bricks[i];
    const BrickVersion& current = bricks_[item.cascade][item.brick].back();
    QuantizedBrick fresh = quantizeBrick(field, item.cascade, int(item.brick));
    if (current.version != 0) {
      const std::shared_ptr<const QuantizedBrick>& previous = current.content;
      if (options_.deadZone.active())
        held[i] = holdSmallChanges(fresh, *previous, options_.deadZone);
      // Unchanged content shares the previous version's codes instead of a copy.
      if (fresh == *previous) item.content = previous;
    }
    if (!item.content) item.content = std::make_shared<const QuantizedBrick>(std::move(fresh));
  });
  for (std::size_t i = 0; i < p.bricks.size(); ++i) {
    p.quantizedCodes += p.bricks[i].content->codes.size();
    p.heldCodes += held[i];
  }
  return p;
}

Status FieldPublisher::publish(const Field& field, double now) {
  auto p = prepare(field);
  if (!p) return p.error();
  commit(std::move(p).value(), now);
  return Status::success();
}

std::optional<double> FieldPublisher::changedAfter(int cascade, int brick,
                                                   std::uint64_t version) const {
  const auto& times = published_[cascade][brick];
  if (times.empty() || times.back().first <= version) return std::nullopt;
  // The oldest version newer than `version`; past the kept times, the oldest kept (a change at
  // least that old).
  for (const auto& [v, at] : times)
    if (v > version) return at;
  return times.front().second;
}

void FieldPublisher::moveCascades(const std::vector<CascadePlaceMsg>& places) {
  if (places.size() != info_.cascades.size()) return;
  for (std::size_t k = 0; k < places.size(); ++k) {
    info_.cascades[k].origin = places[k].origin;
    info_.cascades[k].scroll = places[k].scroll;
  }
}

void FieldPublisher::commit(PreparedBricks prepared, double now) {
  info_.fieldVersion = prepared.fieldVersion;
  fieldVersion_ = prepared.fieldVersion;
  quantizedCodes_ += prepared.quantizedCodes;
  heldCodes_ += prepared.heldCodes;
  for (PreparedBricks::Brick& item : prepared.bricks) {
    auto& h = bricks_[item.cascade][item.brick];
    if (h.back().version != 0) {
      historyBytes_ += kBrickBytes;  // the old current joins history
    } else {
      h.pop_back();
      currentBytes_ += kBrickBytes;
    }
    h.push_back(BrickVersion{item.version, now, std::move(item.content), false});
    trim(h);
    auto& times = published_[item.cascade][item.brick];
    times.emplace_back(item.version, now);
    if (times.size() > kPublishTimesKept) times.pop_front();
    // Senders only ever send a brick's current version (a lagging client gets the newest,
    // never a backlog), so the updates encoded for its older versions can no longer be sent.
    cache_.eraseBrickIf(item.cascade, std::uint32_t(item.brick),
                        [&](const EncodeKey& key) { return key.version != item.version; });
  }
  // Over the byte cap: trim every brick's history to its current version. Only with fields of
  // more than about 540 bricks (historyBoundBytes), and only costs residual opportunities;
  // residuals on the dropped bases go too, which keeps the cache within cacheBoundBytes.
  if (historyBytes_ > options_.maxHistoryBytes) {
    for (int k = 0; k < cascadeCount(); ++k) {
      for (std::size_t b = 0; b < bricks_[k].size(); ++b) {
        auto& h = bricks_[k][b];
        while (h.size() > 1) {
          dropCoarse(h.front());
          h.pop_front();
          historyBytes_ -= kBrickBytes;
        }
        cache_.eraseBrickIf(k, std::uint32_t(b),
                            [](const EncodeKey& key) { return key.base != 0; });
      }
    }
  }
}

void FieldPublisher::trim(std::deque<BrickVersion>& h) {
  // Keep the newest historyVersions versions, and before them the newest sentVersions versions
  // that were sent; drop the rest.
  const std::size_t recent = std::size_t(options_.historyVersions);
  if (h.size() <= recent) return;
  int sentKept = 0;
  std::deque<BrickVersion> kept;
  for (std::size_t i = h.size(); i-- > 0;) {
    const bool isRecent = h.size() - 1 - i < recent;
    if (isRecent || (h[i].sent && sentKept < options_.sentVersions)) {
      sentKept += !isRecent;
      kept.push_front(std::move(h[i]));
    } else {
      dropCoarse(h[i]);
      historyBytes_ -= kBrickBytes;
    }
  }
  h = std::move(kept);
}

std::shared_ptr<const QuantizedBrick> FieldPublisher::find(int cascade, int brick,
                                                           std::uint64_t version) const {
  if (version == 0) return nullptr;
  for (const BrickVersion& v : bricks_[cascade][brick]) {
    if (v.version == version) return v.content;
  }
  return nullptr;
}

std::shared_ptr<const QuantizedBrick> FieldPublisher::find(int cascade, int brick,
                                                           std::uint64_t version,
                                                           int precision) const {
  if (precision <= 0) return find(cascade, brick, version);
  precision = std::min(precision, kMaxPrecision);
  const BrickVersion* held = nullptr;
  for (const BrickVersion& v : bricks_[cascade][brick])
    if (v.version == version && version != 0) held = &v;
  if (!held) return nullptr;
  auto& slot = held->coarse[std::size_t(precision - 1)];
  {
    std::lock_guard lock(readersMutex_);
    if (slot) return slot;
  }
  auto coarse = std::make_shared<const QuantizedBrick>(coarsenBrick(*held->content, precision));
  std::lock_guard lock(readersMutex_);
  if (slot) return slot;  // another sender coarsened it meanwhile
  if (coarseBytes_ + kBrickBytes > options_.maxCoarseBytes) {
    for (const auto& cascadeBricks : bricks_)
      for (const auto& h : cascadeBricks)
        for (const BrickVersion& v : h) dropCoarse(v);
  }
  slot = coarse;
  coarseBytes_ += kBrickBytes;
  return coarse;
}

void FieldPublisher::dropCoarse(const BrickVersion& v) const {
  for (auto& c : v.coarse) {
    if (!c) continue;
    c.reset();
    coarseBytes_ -= kBrickBytes;
  }
}

std::shared_ptr<const EncodedUpdate> FieldPublisher::encoded(int cascade, int brick,
                                                             std::uint64_t version,
                                                             std::uint64_t base, int precision,
                                                             int basePrecision) {
  precision = std::clamp(precision, 0, kMaxPrecision);
  basePrecision = base != 0 ? std::clamp(basePrecision, 0, kMaxPrecision) : 0;
  const EncodeKey key{cascade, std::uint32_t(brick),    version,
                      base,    std::uint8_t(precision), std::uint8_t(basePrecision)};
  {
    std::lock_guard lock(readersMutex_);
    // A version asked for is about to reach a client, which may later name it as its base.
    for (BrickVersion& v : bricks_[cascade][brick]) {
      if (v.version == version) v.sent = true;
    }
    if (auto hit = cache_.find(key)) return hit;
  }
  auto content = find(cascade, brick, version, precision);
  if (!content) return nullptr;
  std::shared_ptr<const QuantizedBrick> baseContent;
  if (base != 0) {
    baseContent = find(cascade, brick, base, basePrecision);
    if (!baseContent) return nullptr;
  }
  const auto start = std::chrono::steady_clock::now();
  std::vector<std::uint8_t> payload = encodeBrick(*content, baseContent.get(), options_.zstdLevel);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::lock_guard lock(readersMutex_);
  ++encodes_;
  encodeSeconds_ += seconds;
  encodeTimes_.observe(seconds);
  // Two senders may have encoded the same update at once: the first one stored is kept.
  if (auto hit = cache_.find(key)) return hit;
  return cache_.insert(key, kCodecQuantZstd, std::move(payload));
}

}  // namespace pc
