#include "stream_receiver.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "common/field_scroll.h"

namespace pc {

namespace {
// Arrivals one ack sent as a datagram carries at most: 8 bytes each on the wire, 768 of the
// 1200 bytes a datagram's frame may have, the rest for the ranges and gaps of a few bricks.
constexpr std::size_t kMaxArrivalsPerDatagramAck = 96;
}  // namespace

Result<StreamReceiver> StreamReceiver::create(const SessionInfoMsg& info, std::uint32_t sessionId,
                                              ReceiverOptions options) {
  auto field = mirrorField(info);
  if (!field) return field.error();
  StreamReceiver receiver(std::move(field.value()), sessionId, options);
  receiver.announceFieldVersion(info.fieldVersion);
  return receiver;
}

StreamReceiver::StreamReceiver(Field field, std::uint32_t sessionId, ReceiverOptions options)
    : field_(std::move(field)),
      sessionId_(sessionId),
      options_(options),
      reassembler_(options.reassembly) {
  bricks_.resize(field_.cascadeCount());
  for (int k = 0; k < field_.cascadeCount(); ++k) bricks_[k].resize(field_.brickVersions[k].size());
  if (!options_.keepField) {
    for (Atlas* a : {&field_.irradiance, &field_.depth, &field_.occlusion}) {
      a->texels.clear();
      a->texels.shrink_to_fit();
    }
  }
}

double StreamReceiver::brickAge(int cascade, int brick, double now) const {
  const BrickState& b = bricks_[cascade][brick];
  return b.version == 0 ? std::numeric_limits<double>::infinity() : now - b.appliedAt;
}

std::vector<std::pair<int, int>> StreamReceiver::takeChangedBricks() {
  std::vector<std::pair<int, int>> out;
  for (int k = 0; k < int(bricks_.size()); ++k) {
    for (int b = 0; b < int(bricks_[k].size()); ++b) {
      if (bricks_[k][b].changed) {
        bricks_[k][b].changed = false;
        out.emplace_back(k, b);
      }
    }
  }
  return out;
}

void StreamReceiver::requestRepair(BrickState& b) { b.wantRepair = true; }

Status StreamReceiver::moveCascades(const std::vector<CascadePlaceMsg>& places) {
  if (places.empty()) return Status::success();
  if (int(places.size()) != field_.cascadeCount())
    return Error{"scene state: " + std::to_string(places.size()) +
                 " cascade places for a field of " + std::to_string(field_.cascadeCount()) +
                 " cascades"};
  for (int k = 0; k < field_.cascadeCount(); ++k) {
    const gpu::CascadeDesc& c = field_.cascade(k);
    const CascadePlaceMsg& p = places[std::size_t(k)];
    const glm::ivec3 s = p.scroll;
    if (s.x < 0 || s.y < 0 || s.z < 0 || s.x >= c.counts.x || s.y >= c.counts.y ||
        s.z >= c.counts.z)
      return Error{"scene state: cascade " + std::to_string(k) + "'s scroll out of range"};
    // The move must be whole spacings, and the scroll must have moved with it.
    const glm::ivec3 shift = originShift(c.origin, p.origin, c.spacing);
    const glm::vec3 error = p.origin - (c.origin + glm::vec3(shift) * c.spacing);
    if (glm::length(error) > 1e-3f * c.spacing)
      return Error{"scene state: cascade " + std::to_string(k) +
                   " moved by other than whole spacings"};
    for (int a = 0; a < 3; ++a) {
      const int n = c.counts[a];
      if (((c.scroll[a] + shift[a]) % n + n) % n != s[a])
        return Error{"scene state: cascade " + std::to_string(k) +
                     "'s scroll does not match its move"};
    }
  }
  for (int k = 0; k < field_.cascadeCount(); ++k) {
    gpu::CascadeDesc& c = field_.desc.cascades[k];
    const CascadePlaceMsg& p = places[std::size_t(k)];
    if (c.origin == p.origin && c.scroll == p.scroll) continue;
    c.origin = p.origin;
    c.scroll = p.scroll;
    for (int b = 0; b < int(bricks_[k].size()); ++b) {
      BrickState& held = bricks_[k][b];
      if (!held.content) continue;
      const int first = c.firstProbe + b * gpu::PC_PROBES_PER_BRICK;
      std::vector<int> before(gpu::PC_PROBES_PER_BRICK);
      for (int i = 0; i < gpu::PC_PROBES_PER_BRICK; ++i)
        before[std::size_t(i)] = field_.probes[std::size_t(first + i)].state;
      applyBrickRecords(field_, k, b, *held.content);
      for (int i = 0; i < gpu::PC_PROBES_PER_BRICK; ++i)
        held.changed |= before[std::size_t(i)] != field_.probes[std::size_t(first + i)].state;
    }
  }
  return Status::success();
}

bool StreamReceiver::adoptHeld(StreamReceiver&& previous) {
  if (!sameLayout(previous.field_.desc, field_.desc) || previous.bricks_.size() != bricks_.size())
    return false;
  for (std::size_t k = 0; k < bricks_.size(); ++k) {
    if (previous.bricks_[k].size() != bricks_[k].size()) return false;
  }
  // The atlases and probe records as the previous session left them: the mirror's content.
  field_ = std::move(previous.field_);
  field_.version = 0;
  for (int k = 0; k < int(bricks_.size()); ++k) {
    for (std::size_t i = 0; i < bricks_[k].size(); ++i) {
      BrickState& b = bricks_[k][i];
      BrickState& held = previous.bricks_[k][i];
      b = BrickState{};
      // A version past what this server announced is one it would not take as held (a relay
      // behind the one before): the brick starts from nothing, as the server sees it.
      if (held.version != 0 && held.version <= announcedVersion_) {
        b.version = held.version;
        b.precision = held.precision;
        b.appliedAt = held.appliedAt;
        b.content = std::move(held.content);
      }
      field_.brickVersions[k][i] = b.version;
      field_.version = std::max(field_.version, b.version);
    }
  }
  return true;
}

HeldBricks StreamReceiver::heldBricks() const {
  HeldBricks held(bricks_.size());
  for (std::size_t k = 0; k < bricks_.size(); ++k) {
    held[k].reserve(bricks_[k].size());
    for (const BrickState& b : bricks_[k]) held[k].push_back(HeldBrick{b.version, b.precision});
  }
  return held;
}

void StreamReceiver::announceFieldVersion(std::uint64_t version) {
  announcedVersion_ = std::max(announcedVersion_, version);
}

std::uint64_t StreamReceiver::newestAcceptedVersion() const {
  const std::uint64_t max = std::numeric_limits<std::uint64_t>::max();
  return announcedVersion_ > max - kFieldVersionSlack ? max
                                                      : announcedVersion_ + kFieldVersionSlack;
}

Status StreamReceiver::onDatagram(std::span<const std::uint8_t> bytes, double now) {
  auto d = decodeDatagram(bytes);
  if (!d) {
    ++stats_.rejectedDatagrams;
    stats_.lastError = d.error().message;
    return d.error();
  }
  if (d->sessionId != sessionId_) {
    ++stats_.rejectedDatagrams;
    stats_.lastError = "datagram: session " + std::to_string(d->sessionId) + ", expected " +
                       std::to_string(sessionId_);
    return Error{stats_.lastError};
  }
  if (d->fieldVersion > newestAcceptedVersion()) {
    ++stats_.rejectedDatagrams;
    ++stats_.refusedVersions;
    stats_.lastError = "datagram: field version " + std::to_string(d->fieldVersion) +
                       " is beyond the newest announced, " + std::to_string(announcedVersion_);
    return Error{stats_.lastError};
  }
  ++stats_.datagrams;
  if (options_.reportArrivals) {
    // The newest arrivals matter most to the sender (its recent rate and delay); past the cap
    // the oldest are dropped, which the sender takes as lost only if nothing later arrived.
    if (arrivals_.size() >= kMaxAckArrivals) arrivals_.erase(arrivals_.begin());
    arrivals_.push_back(DatagramArrivalMsg{
        d->sequence, std::uint32_t(std::int64_t(std::llround(now * 1e6)) & 0xffffffffll)});
  }
  serverVersion_ = std::max(serverVersion_, d->fieldVersion);
  if (stats_.datagrams == 1 || std::int32_t(d->sequence - newestSequence_) > 0)
    newestSequence_ = d->sequence;
  Status result;
  for (Fragment& f : d->fragments) {
    ++stats_.fragments;
    const UpdateHeader& u = f.update;
    if (u.cascade >= int(bricks_.size()) || u.brick >= bricks_[u.cascade].size() ||
        u.codec != kCodecQuantZstd) {
      ++stats_.rejectedFragments;
      stats_.lastError = "datagram: fragment names cascade " + std::to_string(u.cascade) +
                         ", brick " + std::to_string(u.brick) + ", codec " +
                         std::to_string(u.codec) + ", not in this session's field";
      result = Error{stats_.lastError};
      continue;
    }
    if (u.version > newestAcceptedVersion()) {
      ++stats_.rejectedFragments;
      ++stats_.refusedVersions;
      stats_.lastError = "datagram: brick version " + std::to_string(u.version) +
                         " is beyond the newest announced field version, " +
                         std::to_string(announcedVersion_);
      result = Error{stats_.lastError};
      continue;
    }
    if (auto done = reassembler_.add(std::move(f), now, d->sequence)) {
      if (Status s = apply(*done, now); !s) result = s;
    }
  }
  return result;
}

Status StreamReceiver::apply(const CompletedUpdate& u, double now) {
  BrickState& b = bricks_[u.update.cascade][u.update.brick];
  // Newer, or the version held refined to a finer precision.
  const bool newer = u.update.version > b.version ||
                     (u.update.version == b.version && u.update.precision < b.precision);
  if (!newer) {
    ++stats_.stale;
    return Status::success();
  }
  std::shared_ptr<const QuantizedBrick> base;
  if (u.update.baseVersion != 0) {
    if (u.update.baseVersion == b.version && u.update.basePrecision == b.precision) {
      base = b.content;
    } else if (u.update.baseVersion == b.previousVersion &&
               u.update.basePrecision == b.previousPrecision && b.previous) {
      base = b.previous;
    } else {
      ++stats_.missingBase;
      requestRepair(b);
      return Status::success();
    }
  }
  Result<std::shared_ptr<const QuantizedBrick>> q = Error{};
  if (options_.decoder) {
    q = options_.decoder->decode(u.update, u.payload, base);
  } else if (auto decoded = decodeBrick(u.payload, base.get())) {
    q = std::make_shared<const QuantizedBrick>(std::move(decoded).value());
  } else {
    q = decoded.error();
  }
  if (!q) {
    ++stats_.decodeErrors;
    stats_.lastError = q.error().message;
    requestRepair(b);
    return q.error();
  }
  if (options_.keepField) applyBrick(field_, u.update.cascade, int(u.update.brick), **q);
  b.previous = std::move(b.content);
  b.previousVersion = b.version;
  b.previousPrecision = b.precision;
  b.content = std::move(q.value());
  b.version = u.update.version;
  b.precision = u.update.precision;
  b.appliedAt = now;
  b.acksLeft = std::uint8_t(1 + std::min(options_.ackRepeats, 15));
  b.changed = true;
  b.wantRepair = false;
  field_.brickVersions[u.update.cascade][u.update.brick] = b.version;
  field_.version = std::max(field_.version, b.version);
  ++stats_.applied;
  stats_.appliedResidual += base != nullptr;
  return Status::success();
}

std::vector<std::vector<std::uint8_t>> StreamReceiver::poll(double now) {
  std::vector<std::vector<std::uint8_t>> out;
  reassembler_.expire(now);

  const bool full = now - lastFullAckAt_ >= options_.fullAckInterval;
  bool dirty = false;
  for (const auto& cascade : bricks_) {
    for (const BrickState& b : cascade) dirty |= b.acksLeft > 0;
  }
  // Partial updates that later datagrams overtook: their missing fragments, for the sender to
  // send again (selective repair), in an ack of their own timing.
  std::vector<FragmentGap> gaps;
  if (options_.reportGaps) gaps = reassembler_.takeGaps(now, newestSequence_, kMaxFragmentGaps);
  if (full || !gaps.empty() ||
      ((dirty || !arrivals_.empty()) && now - lastAckAt_ >= options_.ackInterval)) {
    AckMsg ack;
    ack.full = full;
    // The arrivals the last acks reported, then the new ones: the sender takes each once.
    std::size_t repeated = 0;
    for (const auto& earlier : reportedArrivals_) repeated += earlier.size();
    std::size_t skip = repeated > kMaxRepeatedArrivals ? repeated - kMaxRepeatedArrivals : 0;
    for (const auto& earlier : reportedArrivals_) {
      const std::size_t drop = std::min(skip, earlier.size());
      skip -= drop;
      ack.arrivals.insert(ack.arrivals.end(), earlier.begin() + std::ptrdiff_t(drop),
                          earlier.end());
    }
    ack.arrivals.insert(ack.arrivals.end(), arrivals_.begin(), arrivals_.end());
    if (options_.ackRepeats > 0) reportedArrivals_.push_back(std::move(arrivals_));
    while (reportedArrivals_.size() > std::size_t(options_.ackRepeats))
      reportedArrivals_.pop_front();
    arrivals_.clear();
    ack.fieldVersion = serverVersion_;
    for (FragmentGap& g : gaps) {
      const UpdateHeader& u = g.update;
      ack.gaps.push_back(FragmentGapMsg{u.updateId, u.cascade, u.brick, u.version, u.baseVersion,
                                        g.fragmentCount, std::move(g.missing)});
      ++stats_.gapReports;
    }
    for (int k = 0; k < int(bricks_.size()); ++k) {
      for (std::uint32_t i = 0; i < bricks_[k].size(); ++i) {
        BrickState& b = bricks_[k][i];
        const bool listed = full ? b.version != 0 : b.acksLeft > 0;
        if (b.acksLeft > 0) --b.acksLeft;
        if (!listed) continue;
        // Runs of consecutive bricks at one version: an update bumps all its bricks to the
        // same version, so runs are long.
        AckRange* last = ack.ranges.empty() ? nullptr : &ack.ranges.back();
        if (last && last->cascade == k && last->firstBrick + last->count == i &&
            last->version == b.version) {
          ++last->count;
        } else {
          ack.ranges.push_back(AckRange{k, i, 1, b.version});
        }
        if (b.precision != 0) ack.precisions.push_back(BrickPrecisionMsg{k, i, b.precision});
      }
    }
    if (options_.ackRepeats > 0) {
      // Acks that travel as datagrams (ackRepeats > 0): arrivals past what one datagram holds
      // with room for the rest go first, oldest first, in acks of their own, so that a burst
      // of datagrams read at once does not push the ack onto the session stream.
      while (ack.arrivals.size() > kMaxArrivalsPerDatagramAck) {
        AckMsg part;
        part.fieldVersion = serverVersion_;
        const auto end = ack.arrivals.begin() + std::ptrdiff_t(kMaxArrivalsPerDatagramAck);
        part.arrivals.assign(ack.arrivals.begin(), end);
        ack.arrivals.erase(ack.arrivals.begin(), end);
        out.push_back(encodeMessage(part));
      }
    }
    out.push_back(encodeMessage(ack));
    ++stats_.acks;
    lastAckAt_ = now;
    if (full) lastFullAckAt_ = now;
  }

  RepairRequestMsg repair;
  for (int k = 0; k < int(bricks_.size()); ++k) {
    for (std::uint32_t i = 0; i < bricks_[k].size(); ++i) {
      BrickState& b = bricks_[k][i];
      if (!b.wantRepair || now - b.repairAt < options_.repairInterval) continue;
      b.wantRepair = false;
      b.repairAt = now;
      repair.bricks.push_back(BrickRefMsg{k, i, b.version, b.precision});
    }
  }
  if (!repair.bricks.empty()) {
    stats_.repairBricks += repair.bricks.size();
    out.push_back(encodeMessage(repair));
  }
  return out;
}

}  // namespace pc
