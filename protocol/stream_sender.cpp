#include "stream_sender.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "protocol/resume_state.h"

namespace pc {

namespace {

// Fragment i of an encoded update: a view of its bytes.
FragmentRef fragmentOf(const EncodedUpdate& u, std::uint16_t i) {
  const std::size_t begin = std::size_t(i) * kFragmentBytes;
  const std::size_t size = std::min(kFragmentBytes, u.payload.size() - begin);
  return FragmentRef{u.header, i, std::span(u.payload).subspan(begin, size)};
}

// Packs fragments into datagrams in the order given, each within kMaxDatagramBytes.
class Packer {
 public:
  Packer(std::uint32_t sessionId, std::uint32_t& sequence, std::uint64_t fieldVersion,
         std::vector<std::vector<std::uint8_t>>& out)
      : sessionId_(sessionId), sequence_(sequence), fieldVersion_(fieldVersion), out_(out) {}

  void add(const FragmentRef& f) {
    const std::size_t cost = kFragmentOverheadBytes + f.data.size();
    if (!pending_.empty() && size_ + cost > kMaxDatagramBytes) flush();
    pending_.push_back(f);
    size_ += cost;
  }
  void flush() {
    if (pending_.empty()) return;
    out_.push_back(encodeDatagram(sessionId_, sequence_++, fieldVersion_, pending_));
    pending_.clear();
    size_ = kDatagramOverheadBytes;
  }

 private:
  std::uint32_t sessionId_;
  std::uint32_t& sequence_;
  std::uint64_t fieldVersion_;
  std::vector<std::vector<std::uint8_t>>& out_;
  std::vector<FragmentRef> pending_;
  std::size_t size_ = kDatagramOverheadBytes;
};

}  // namespace

std::optional<BrickChange> BrickChangeCache::get(const FieldPublisher& publisher, int cascade,
                                                 int brick, std::uint64_t version,
                                                 std::uint64_t ref, int refPrecision) {
  const Key key{cascade, brick, version, ref, refPrecision};
  {
    std::lock_guard lock(mutex_);
    if (auto it = entries_.find(key); it != entries_.end()) {
      ++hits_;
      return it->second;
    }
  }
  std::optional<BrickChange> change;
  auto cur = publisher.find(cascade, brick, version);
  auto old = publisher.find(cascade, brick, ref, refPrecision);
  if (cur && old) change = brickChange(*cur, *old);
  std::lock_guard lock(mutex_);
  // Senders only compare a brick's current version, so pairs of older versions are never asked
  // for again. Dropping them whenever the map has doubled since the last time keeps it near
  // what is live (current versions x the references clients hold) at an amortized constant
  // cost; past maxEntries everything goes, which costs one comparison per live pair.
  if (entries_.size() >= pruneAt_) {
    std::erase_if(entries_, [&](const auto& entry) {
      const Key& k = entry.first;
      return k.version != publisher.current(k.cascade, k.brick).version;
    });
    if (entries_.size() >= maxEntries_) entries_.clear();
    pruneAt_ = std::min(maxEntries_, std::max(kMinPruneAt, 2 * entries_.size()));
  }
  ++computed_;
  entries_.emplace(key, change);  // kept as it is where another sender stored it meanwhile
  return change;
}

StreamSender::StreamSender(FieldPublisher& publisher, std::uint32_t sessionId,
                           SenderOptions options, BrickChangeCache* changes)
    : publisher_(publisher),
      sessionId_(sessionId),
      options_(options),
      changes_(changes),
      rate_([&] {
        RateControlOptions o = options.rateControl;
        o.maxRate = options.bytesPerSecond;
        return o;
      }()) {
  tracks_.resize(publisher.cascadeCount());
  for (int k = 0; k < publisher.cascadeCount(); ++k) tracks_[k].resize(publisher.brickCount(k));
  stats_.srtt = options_.initialRtt;
  stats_.rttvar = options_.initialRtt / 2;
  descentHold_ = options_.descentHold;
}

double StreamSender::resendTimeout() const {
  // Twice the smoothed round trip, or more where acks come late by varying amounts (a loaded
  // client): RFC 6298's srtt + 4 x rttvar, so that jitter does not send updates again that
  // arrived.
  return std::max(
      {options_.minResendTimeout, 2.0 * stats_.srtt, stats_.srtt + 4.0 * stats_.rttvar});
}

double StreamSender::sendRate() const {
  return options_.congestionControl ? std::min(rate_.rate(), options_.bytesPerSecond)
                                    : options_.bytesPerSecond;
}

std::optional<BrickChange> StreamSender::changeOf(int k, int b, std::uint64_t version,
                                                  std::uint64_t ref, int refPrecision) {
  if (changes_) return changes_->get(publisher_, k, b, version, ref, refPrecision);
  auto cur = publisher_.find(k, b, version);
  auto old = publisher_.find(k, b, ref, refPrecision);
  if (!cur || !old) return std::nullopt;
  return brickChange(*cur, *old);
}

double StreamSender::changeAge(Track& t, int k, int b, double now) {
  if (t.acked == 0) return t.pendingSince >= 0 ? now - t.pendingSince : 0.0;
  if (t.changedFor != t.acked || t.changedAt < 0) {
    const std::optional<double> at = publisher_.changedAfter(k, b, t.acked);
    t.changedFor = t.acked;
    t.changedAt = at ? *at : -1.0;
  }
  return t.changedAt >= 0 ? std::max(0.0, now - t.changedAt) : 0.0;
}

HeldFieldReport StreamSender::heldField(double now) {
  HeldFieldReport r;
  double squares = 0;
  std::size_t measured = 0;
  for (int k = 0; k < int(tracks_.size()); ++k) {
    for (int b = 0; b < int(tracks_[k].size()); ++b) {
      const BrickVersion& cur = publisher_.current(k, b);
      if (cur.version == 0) continue;
      ++r.currentBricks;
      Track& t = tracks_[k][b];
      if (t.acked != cur.version) {
        ++r.pendingBricks;
        r.oldestChangeSeconds = std::max(r.oldestChangeSeconds, changeAge(t, k, b, now));
      }
      if (t.acked == 0) continue;
      ++r.heldBricks;
      if (t.acked == cur.version && t.ackedPrecision == 0) {
        ++measured;
        continue;
      }
      // Against what the client holds: the acknowledged version at its precision level.
      const std::optional<BrickChange> change =
          changeOf(k, b, cur.version, t.acked, t.ackedPrecision);
      if (!change) {
        ++r.unknownBricks;
        continue;
      }
      squares += change->irradianceMeanSquare;
      ++measured;
    }
  }
  const double mse = measured > 0 ? squares / double(measured) : 0.0;
  r.psnrDb = measured == 0 ? 0.0
             : mse <= 0    ? kHeldPsnrCap
                           : std::min(kHeldPsnrCap, 10.0 * std::log10(1.0 / mse));
  return r;
}

StreamReportMsg StreamSender::report(double now) {
  const HeldFieldReport held = heldField(now);
  const RateEstimate& e = rate_.estimate();
  StreamReportMsg m;
  m.rate = sendRate();
  m.delivered = e.delivered;
  m.queueDelayMs = float(e.queueDelay * 1e3);
  m.loss = float(e.loss);
  m.qualityLevel = level_;
  m.heldPsnrDb = float(held.psnrDb);
  m.oldestChangeSeconds = float(held.oldestChangeSeconds);
  m.pendingBricks = std::uint32_t(held.pendingBricks);
  m.fieldVersion = publisher_.fieldVersion();
  return m;
}

std::size_t StreamSender::pendingBricks() const {
  std::size_t n = 0;
  for (int k = 0; k < int(tracks_.size()); ++k) {
    for (int b = 0; b < int(tracks_[k].size()); ++b) {
      const std::uint64_t v = publisher_.current(k, b).version;
      n += v != 0 && tracks_[k][b].acked != v;
    }
  }
  return n;
}

Status StreamSender::onMessage(std::span<const std::uint8_t> frame, double now) {
  auto m = decodeMessage(frame);
  if (!m) {
    ++stats_.badMessages;
    return m.error();
  }
  return onMessage(*m, now);
}

Status StreamSender::onMessage(const SessionMessage& message, double now) {
  Status s;
  if (const auto* ack = std::get_if<AckMsg>(&message)) {
    s = onAck(*ack, now);
  } else if (const auto* repair = std::get_if<RepairRequestMsg>(&message)) {
    s = onRepair(*repair);
  } else if (const auto* pose = std::get_if<ViewerPoseMsg>(&message)) {
    viewer_ = pose->position;
  } else if (const auto* resume = std::get_if<ResumeMsg>(&message)) {
    s = onResume(*resume, now);
  } else {
    s = Error{"stream sender: unexpected message type from the client"};
  }
  if (!s) ++stats_.badMessages;
  return s;
}

Status StreamSender::onAck(const AckMsg& ack, double now) {
  // Check every range before changing anything, so a bad ack changes nothing.
  for (const AckRange& r : ack.ranges) {
    if (r.cascade < 0 || r.cascade >= int(tracks_.size()) ||
        std::uint64_t(r.firstBrick) + r.count > tracks_[r.cascade].size()) {
      return Error{"ack: range (cascade " + std::to_string(r.cascade) + ", bricks " +
                   std::to_string(r.firstBrick) + "+" + std::to_string(r.count) +
                   ") outside the field"};
    }
  }
  for (const FragmentGapMsg& g : ack.gaps) {
    if (g.cascade < 0 || g.cascade >= int(tracks_.size()) || g.brick >= tracks_[g.cascade].size()) {
      return Error{"ack: fragment gap of brick " + std::to_string(g.brick) + " of cascade " +
                   std::to_string(g.cascade) + ", outside the field"};
    }
  }
  for (const BrickPrecisionMsg& p : ack.precisions) {
    if (p.cascade < 0 || p.cascade >= int(tracks_.size()) || p.brick >= tracks_[p.cascade].size() ||
        p.precision < 0 || p.precision > kMaxPrecision) {
      return Error{"ack: precision " + std::to_string(p.precision) + " of brick " +
                   std::to_string(p.brick) + " of cascade " + std::to_string(p.cascade) +
                   ", outside the field or the levels"};
    }
  }
  // A full ack lists every brick the client holds: the others it holds nothing of.
  //
  // Its bricks also give round-trip samples, as if just acknowledged, of the time since their
  // last send: the smoothed round trip then follows how long bricks wait between sends as well
  // (seconds where the field is still), which keeps the resend timeout long. That is kept on
  // purpose: with samples from first acks only, the timeout followed the true round trip, and
  // a client whose acks came late now and then was sent its bricks again (probecast-bench
  // load, 1000 clients on two cores: 427-466 instead of 306-334 kbit/s per client, p99
  // latency 1.0 s instead of 0.38-0.52, 0 and 38 clients stale for over 2 s). The cost: under
  // heavy loss (50%) the timeout grows to seconds once bricks arrive; the fragment gaps that
  // acks report (queueRepair) do not wait for it.
  if (ack.full) {
    for (auto& cascade : tracks_) {
      for (Track& t : cascade) t.acked = 0;
    }
  }
  for (const AckRange& r : ack.ranges) {
    for (std::uint32_t i = 0; i < r.count; ++i) {
      Track& t = tracks_[r.cascade][r.firstBrick + i];
      if (r.version == t.sent && t.acked != t.sent && !t.resent) {
        // Round-trip sample (with the receiver's ack delay, which the timeout must cover too).
        const double sample = now - t.sentAt;
        if (sample >= 0 && sample < 10.0) {
          stats_.rttvar = 0.75 * stats_.rttvar + 0.25 * std::abs(stats_.srtt - sample);
          stats_.srtt = 0.875 * stats_.srtt + 0.125 * sample;
        }
      }
      t.acked = r.version;
      t.ackedPrecision = 0;  // unless the ack names a coarser level below
    }
  }
  for (const BrickPrecisionMsg& p : ack.precisions)
    tracks_[p.cascade][p.brick].ackedPrecision = p.precision;
  for (const FragmentGapMsg& g : ack.gaps) queueRepair(g);
  if (options_.congestionControl && !ack.arrivals.empty()) {
    std::vector<RateController::Arrival> arrivals;
    arrivals.reserve(ack.arrivals.size());
    for (const DatagramArrivalMsg& a : ack.arrivals)
      arrivals.push_back(RateController::Arrival{a.sequence, a.arrivalMicros});
    rate_.setAppLimited(reportPolls_ > 0 && appLimitedPolls_ * 2 > reportPolls_);
    rate_.onArrivals(arrivals, now);
    appLimitedPolls_ = reportPolls_ = 0;
  }
  return Status::success();
}

// Only for the update in flight: the version last sent and not yet acknowledged, which the
// publisher still encodes to the same bytes (the same update id and fragment count). Anything
// else the client reports is stale (the brick moved on, or arrived since), and is ignored.
void StreamSender::queueRepair(const FragmentGapMsg& g) {
  const Track& t = tracks_[g.cascade][g.brick];
  if (g.missing.empty() || t.sent != g.version || heldAsSent(t)) return;
  // The update in flight was encoded at the levels it was sent at.
  auto update = publisher_.encoded(g.cascade, int(g.brick), g.version, g.baseVersion,
                                   t.sentPrecision, t.sentBasePrecision);
  if (!update || update->header.updateId != g.updateId ||
      fragmentCount(update->header.totalSize) != g.fragmentCount)
    return;
  Repair repair{g.cascade, int(g.brick), std::move(update), g.missing};
  auto same = std::find_if(repairs_.begin(), repairs_.end(), [&](const Repair& r) {
    return r.cascade == repair.cascade && r.brick == repair.brick;
  });
  if (same != repairs_.end())
    *same = std::move(repair);
  else
    repairs_.push_back(std::move(repair));
}

Status StreamSender::onRepair(const RepairRequestMsg& repair) {
  for (const BrickRefMsg& r : repair.bricks) {
    if (r.cascade < 0 || r.cascade >= int(tracks_.size()) || r.brick >= tracks_[r.cascade].size()) {
      return Error{"repair request: brick outside the field"};
    }
    if (r.havePrecision < 0 || r.havePrecision > kMaxPrecision) {
      return Error{"repair request: precision level " + std::to_string(r.havePrecision)};
    }
  }
  for (const BrickRefMsg& r : repair.bricks) {
    Track& t = tracks_[r.cascade][r.brick];
    t.acked = r.haveVersion;
    t.ackedPrecision = r.haveVersion != 0 ? r.havePrecision : 0;
    t.repair = true;
    t.sent = 0;  // not in flight any more: what was sent did not help
  }
  return Status::success();
}

Status StreamSender::onResume(const ResumeMsg& resume, double now) {
  if (resumeHeard_) return Error{"resume: a second Resume"};
  resumeHeard_ = true;
  awaitResumeUntil_ = -1;  // the wait is over either way
  const SessionInfoMsg& info = publisher_.sessionInfo();
  if (resume.brickCount == 0) return Status::success();  // holds nothing
  // Versions of another run, or of another scene, name other content: the client holds
  // nothing this sender can build on, and gets the whole field as a new client does.
  if (info.fieldEpoch == 0 || resume.fieldEpoch != info.fieldEpoch ||
      resume.sceneHash != info.sceneHash) {
    ++stats_.resumeMismatches;
    return Status::success();
  }
  std::vector<std::size_t> bricks;
  for (const auto& cascade : tracks_) bricks.push_back(cascade.size());
  auto held = heldBricksOf(resume, bricks);
  if (!held) return held.error();  // nothing changed
  ++stats_.resumes;
  for (int k = 0; k < int(tracks_.size()); ++k) {
    for (int b = 0; b < int(tracks_[k].size()); ++b) {
      const HeldBrick& h = (*held)[k][b];
      if (h.version == 0) continue;
      // A version past this sender's newest cannot be checked against anything it holds (a
      // relay that is behind, or a lie): the client counts as holding nothing of the brick.
      if (h.version > publisher_.current(k, b).version) {
        ++stats_.resumeRefusedBricks;
        continue;
      }
      Track& t = tracks_[k][b];
      t.acked = h.version;
      t.ackedPrecision = h.precision;
      // Residuals go on the held version while the publisher has it (the same content on
      // every endpoint of this epoch); otherwise poll() falls back to self-contained. The
      // self-contained interval, a safety net, runs from here.
      t.selfContainedAt = now;
      ++stats_.resumedBricks;
    }
  }
  return Status::success();
}

bool StreamSender::belowThresholds(Track& t, int k, int b, std::uint64_t version, std::uint64_t ref,
                                   int refPrecision) {
  if (t.skipVersion == version && t.skipRef == ref && t.skipRefPrecision == refPrecision &&
      t.skipLevel == level_)
    return t.skipBelow;
  const std::optional<BrickChange> change = changeOf(k, b, version, ref, refPrecision);
  bool below = false;
  Reason reason = Reason::First;  // a version no longer in the history: as if new
  // Each quality level doubles every threshold.
  const float scale = float(1 << level_);
  t.skipChange = 1.0f;  // unknown: as valuable as a brick can be
  if (change) {
    const BrickChange& c = *change;
    t.skipChange = c.irradianceMean;
    if (c.irradiance >= scale * options_.irradianceThreshold)
      reason = Reason::Irradiance;
    else if (options_.irradianceMeanThreshold > 0 &&
             c.irradianceMean >= scale * options_.irradianceMeanThreshold)
      reason = Reason::IrradianceMean;
    else if (c.depth >= scale * options_.depthThreshold)
      reason = Reason::Depth;
    else if (c.occlusion >= scale * options_.occlusionThreshold)
      reason = Reason::Occlusion;
    else if (c.offset >= scale * options_.offsetThreshold)
      reason = Reason::Offset;
    else if (c.states)
      reason = Reason::State;
    else
      below = true;
  }
  t.skipVersion = version;
  t.skipRef = ref;
  t.skipRefPrecision = refPrecision;
  t.skipBelow = below;
  t.skipReason = reason;
  t.skipLevel = level_;
  return below;
}

void StreamSender::count(Reason reason) {
  SenderStats::Reasons& r = stats_.reasons;
  switch (reason) {
    case Reason::First:
      ++r.first;
      break;
    case Reason::Irradiance:
      ++r.irradiance;
      break;
    case Reason::IrradianceMean:
      ++r.irradianceMean;
      break;
    case Reason::Depth:
      ++r.depth;
      break;
    case Reason::Occlusion:
      ++r.occlusion;
      break;
    case Reason::Offset:
      ++r.offset;
      break;
    case Reason::State:
      ++r.state;
      break;
    case Reason::Settled:
      ++r.settled;
      break;
    case Reason::Refresh:
      ++r.refresh;
      break;
    case Reason::Repair:
      ++r.repair;
      break;
    case Reason::Timeout:
      ++r.timeout;
      break;
    case Reason::Aged:
      ++stats_.aged;
      break;
    case Reason::Refine:
      ++r.refine;
      break;
  }
}

double StreamSender::distanceInBricks(int k, int b) const {
  if (!viewer_) return 0.0;
  const gpu::CascadeDesc& c = publisher_.cascade(k);
  const glm::ivec3 bc = gpu::pcBrickCoord(c, b) * gpu::PC_BRICK_SIZE;
  // The brick's middle probe, in logical (scrolled) grid coordinates.
  const glm::ivec3 mid = glm::min(bc + glm::ivec3(gpu::PC_BRICK_SIZE / 2), c.counts - 1);
  const glm::vec3 centre = gpu::pcProbeGridPosition(c, gpu::pcLogicalCoord(c, mid));
  const float brickSize = c.spacing * float(gpu::PC_BRICK_SIZE);
  return std::max(0.0, double(glm::length(*viewer_ - centre) / brickSize) - 0.9);
}

void StreamSender::adjustQuality(double now) {
  if (now - levelAt_ < options_.qualityInterval) return;
  // Short of rate: the sender spent its rate and changes at the age bound waited in most polls.
  // Pacing holds a poll to a few milliseconds of the rate, so some change at the age bound
  // waits in most polls whenever several come due together, with the rate far from spent:
  // waiting alone said the rate was short where it was not (a client of a 2 Mbit/s link
  // climbed to the coarsest level while its sender sent 0.5 Mbit/s).
  const double use = levelAllowed_ > 0 ? levelSent_ / levelAllowed_ : 1.0;
  const bool shortOfRate = shortPolls_ * 2 > levelPolls_ && use >= options_.fullUse;
  if (shortOfRate && oldestPending_ > 0.5 * options_.ageBound &&
      level_ < options_.maxQualityLevel) {
    ++level_;
    roomySince_ = -1;
    levelUpAt_ = now;
    // Short again soon after a level came down: that level does not fit this link, so the
    // next try waits twice as long (the refinements and coarse versions of each try cost).
    if (now - levelDownAt_ < 2.0 * descentHold_)
      descentHold_ = std::min(descentHold_ * 2.0, options_.maxDescentHold);
  } else if (shortOfRate) {
    roomySince_ = -1;
  } else {
    // Not short: a level comes down after descentHold_ of this (an interval on a still
    // field, where what is left to send is the refinement of what the client holds coarse).
    // The thresholds it lowers make more versions worth sending: the sender then spends more
    // of its rate, and the controller, no longer application-limited, finds whether the link
    // carries it; if not, the level goes up again. Neither the oldest change nor the share of
    // the rate spent holds a level up: while the field moves, what the thresholds hold back
    // waits up to the age bound's lead at every level, so the oldest change is always past
    // half the bound (a ladder that came down only below that never came down on an animated
    // scene); and an application-limited sender's rate does not grow, so a share of it says
    // little about the link.
    if (roomySince_ < 0) roomySince_ = now;
    const double hold = oldestPending_ > 0 ? descentHold_ : options_.qualityInterval;
    if (level_ > 0 && now - roomySince_ >= hold) {
      --level_;
      roomySince_ = now;
      levelDownAt_ = now;
    }
    // The last level that came down held: the link has room, come down at the usual pace.
    if (levelDownAt_ > levelUpAt_ && now - levelDownAt_ >= 2.0) descentHold_ = options_.descentHold;
  }
  levelAt_ = now;
  shortPolls_ = levelPolls_ = 0;
  levelAllowed_ = levelSent_ = 0;
  oldestPending_ = 0;
}

std::vector<std::vector<std::uint8_t>> StreamSender::poll(double now) {
  std::vector<std::vector<std::uint8_t>> out;
  if (now < awaitResumeUntil_) {
    // The client's Resume is on its way: bricks sent now would mostly be ones it holds. Only
    // heartbeats, which tell it the field version and that the server is alive.
    if (now - lastDatagramAt_ >= options_.heartbeatInterval) {
      out.push_back(encodeDatagram(sessionId_, sequence_, publisher_.fieldVersion(), {}));
      if (options_.congestionControl) rate_.onSent(sequence_, out.back().size(), now);
      ++sequence_;
      lastDatagramAt_ = now;
      ++stats_.datagrams;
      stats_.bytes += out.back().size();
    }
    return out;
  }
  const double rate = sendRate();
  // With congestion control the bucket is a pacer: it holds a few milliseconds at the rate.
  const double burst =
      options_.congestionControl
          ? std::clamp(rate * options_.pacingBurstSeconds, 3.0 * double(kMaxDatagramBytes),
                       std::max(options_.burstBytes, 3.0 * double(kMaxDatagramBytes)))
          : options_.burstBytes;
  if (lastPoll_ < 0) {
    tokens_ = burst;
  } else {
    tokens_ = std::min(burst, tokens_ + rate * std::max(0.0, now - lastPoll_));
    levelAllowed_ += rate * std::max(0.0, now - lastPoll_);
  }
  lastPoll_ = now;
  firstSends_.clear();

  // What earlier polls packed leaves first; new choices are made only once it has all left,
  // so that they are made on the newest acks and field (and a poll whose tokens went to
  // packed datagrams is one where bricks waited).
  release(now, out);
  bool waited = true, changesWaited = lastChangesWaited_;
  if (paced_.empty() && tokens_ > 0) {
    pack(now, waited, changesWaited);
    lastChangesWaited_ = changesWaited;
    release(now, out);
  }
  if (out.empty() && paced_.empty() && now - lastDatagramAt_ >= options_.heartbeatInterval) {
    // Heartbeat: tells the client the newest field version and that the server is alive.
    paced_.push_back(Paced{
        encodeDatagram(sessionId_, sequence_, publisher_.fieldVersion(), {}), sequence_, {}, {}});
    ++sequence_;
    tokens_ = std::max(tokens_, 1.0);  // a heartbeat is never held back
    release(now, out);
  }
  ++reportPolls_;
  appLimitedPolls_ += !waited;
  ++levelPolls_;
  shortPolls_ += changesWaited;
  adjustQuality(now);
  return out;
}

void StreamSender::release(double now, std::vector<std::vector<std::uint8_t>>& out) {
  while (!paced_.empty() && tokens_ > 0) {
    Paced& p = paced_.front();
    tokens_ -= double(p.datagram.size());
    for (const auto& [k, b] : p.completes) {
      if (k >= int(tracks_.size()) || b >= int(tracks_[std::size_t(k)].size())) continue;
      Track& t = tracks_[std::size_t(k)][std::size_t(b)];
      // Its last send was self-contained when both times were the same (see pack()).
      if (t.selfContainedAt == t.sentAt) t.selfContainedAt = now;
      t.sentAt = now;
    }
    firstSends_.insert(firstSends_.end(), p.firstSends.begin(), p.firstSends.end());
    lastDatagramAt_ = now;
    ++stats_.datagrams;
    stats_.bytes += p.datagram.size();
    levelSent_ += double(p.datagram.size());
    if (options_.congestionControl) rate_.onSent(p.sequence, p.datagram.size(), now);
    out.push_back(std::move(p.datagram));
    paced_.pop_front();
  }
}

void StreamSender::pack(double now, bool& waited, bool& changesWaited) {
  // Fragments the client reported missing go first: each completes an update the client holds
  // in part, at the cost of the fragments alone.
  std::vector<std::vector<std::uint8_t>> packed;
  const std::uint32_t firstSequence = sequence_;
  Packer packer(sessionId_, sequence_, publisher_.fieldVersion(), packed);
  // Where each update or repair ends: (datagram index, cascade, brick, first-sent version or 0).
  struct Completion {
    std::size_t datagram;
    int cascade, brick;
    std::uint64_t firstSend;
  };
  std::vector<Completion> completions;
  double budget = tokens_;
  std::size_t repaired = 0;
  for (; repaired < repairs_.size() && budget > 0; ++repaired) {
    const Repair& r = repairs_[repaired];
    const EncodedUpdate& u = *r.update;
    Track& t = tracks_[r.cascade][r.brick];
    if (t.sent != u.header.version || t.sentPrecision != u.header.precision || heldAsSent(t))
      continue;  // moved on since
    for (std::uint16_t i : r.fragments) {
      const FragmentRef f = fragmentOf(u, i);
      packer.add(f);
      budget -= double(f.data.size() + kFragmentOverheadBytes);
    }
    completions.push_back(Completion{packed.size(), r.cascade, r.brick, 0});
    stats_.fragments += r.fragments.size();
    stats_.repairedFragments += r.fragments.size();
    // Sent again: in flight from now (the whole update's resend waits a timeout from here), and
    // its ack gives no round-trip sample (Karn).
    t.sentAt = now;
    t.resent = true;
  }
  // The fragments must be packed before the updates they point into may go.
  packer.flush();
  repairs_.erase(repairs_.begin(), repairs_.begin() + std::ptrdiff_t(repaired));

  // Which bricks want sending, most urgent first.
  std::vector<Candidate> candidates;
  const double timeout = resendTimeout();
  const double agedAfter = std::max(0.0, options_.ageBound - options_.ageLead);
  // Lost updates of several fragments, which the receiver may hold in part.
  std::size_t lostUpdates = 0, lostBytes = 0;
  const int precision = precisionNow();
  for (int k = 0; k < int(tracks_.size()); ++k) {
    for (int b = 0; b < int(tracks_[k].size()); ++b) {
      Track& t = tracks_[k][b];
      const BrickVersion& cur = publisher_.current(k, b);
      // Holds the current version, at a precision the quality level allows (else: refine).
      const bool current = t.acked == cur.version;
      if (cur.version == 0 || (current && t.ackedPrecision <= precision)) {
        t.pendingSince = -1;
        t.repair = false;
        continue;
      }
      if (t.pendingSince < 0) t.pendingSince = now;
      const double age = changeAge(t, k, b, now);
      if (t.acked != 0) oldestPending_ = std::max(oldestPending_, age);
      const bool unacked = t.sent != 0 && !heldAsSent(t);
      // A brick the client holds nothing of, whose update of several fragments was not
      // acknowledged (yet), goes again as it was while the publisher holds that version: the
      // receiver completes it from the fragments of every send. A brick the client holds gets
      // the newest version instead, as before: it is not missing, and a resend of an old
      // version after an ack that was only late would hold the client back.
      // (Its last send was self-contained when it was also the last self-contained one.)
      const bool resendable = unacked && t.acked == 0 && t.selfContainedAt == t.sentAt &&
                              !t.repair && fragmentCount(t.sentBytes) > 1 &&
                              publisher_.find(k, b, t.sent);
      if (resendable && (t.resent || now - t.sentAt >= timeout)) {
        ++lostUpdates;
        lostBytes += t.sentBytes;
      }
      // One version in flight per brick: the client keeps only the version it holds, so a
      // newer version sent before the last one is acknowledged would have to be a residual on
      // a version the client may already have replaced (and would need a repair). Waiting for
      // the ack (one round trip) also batches a quickly changing brick's versions.
      if (unacked && now - t.sentAt < timeout) continue;
      // Waiting counts from when the brick became pending or was last sent, whichever is
      // later: a brick that keeps changing is pending for good, and counted from the first
      // it would keep the priority of a brick that was never sent.
      const double waited = now - std::max(t.pendingSince, t.sentAt);
      const double distance = distanceInBricks(k, b);
      const bool missing = t.acked == 0;
      const bool aged = !missing && age >= agedAfter;
      // Bricks the client lacks: nearest first, waiting moves a brick nearer. Bricks it holds:
      // by perceptual value per byte, the change against what the client holds (mean
      // |delta e|) weighted by nearness to the viewer and raised by waiting, over the bytes
      // the brick's last update took.
      const auto valueKey = [&] {
        const double weight = 1.0 / (1.0 + distance);
        const double value =
            (double(t.skipChange) + 1e-4) * weight * (1.0 + 4.0 * waited / options_.ageBound);
        return -value / double(t.sentBytes > 0 ? t.sentBytes : 8192);
      };
      const double key = missing ? distance - options_.agingBricksPerSecond * waited : 0.0;
      if (resendable) {  // lost: the resend timeout passed
        candidates.push_back(Candidate{k, b, key, Reason::Timeout, true, missing, false});
        continue;
      }
      Reason reason = Reason::Timeout;
      if (t.repair) {
        reason = Reason::Repair;
      } else if (current) {
        // The current version, held coarser than the level allows now: its value is the
        // rounding's error.
        reason = Reason::Refine;
        if (const auto change = changeOf(k, b, cur.version, cur.version, t.ackedPrecision))
          t.skipChange = change->irradianceMean;
      } else if (t.sent != cur.version) {
        // A new version: hold it back while the change is small, still moving, the client
        // heard from this brick recently and its oldest change is young.
        const bool sentNewer = t.sent > t.acked;
        const std::uint64_t ref = sentNewer ? t.sent : t.acked;
        const int refPrecision = sentNewer ? t.sentPrecision : t.ackedPrecision;
        if (ref == 0) {
          reason = Reason::First;
        } else if (!belowThresholds(t, k, b, cur.version, ref, refPrecision)) {
          reason = t.skipReason;
        } else if (now - cur.publishedAt >= options_.settleTime) {
          reason = Reason::Settled;
        } else if (aged) {
          reason = Reason::Aged;
        } else if (now - t.sentAt >= options_.refreshInterval) {
          reason = Reason::Refresh;
        } else {
          ++stats_.skipped;
          continue;
        }
      }
      candidates.push_back(
          Candidate{k, b, missing ? key : valueKey(), reason, false, missing, aged});
    }
  }
  // Lost updates first (finishing them frees the receiver's reassembly), then bricks the client
  // lacks (a brick it holds only gets fresher), then changes near the age bound, then by key.
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
    if (a.again != b.again) return a.again;
    if (a.missing != b.missing) return a.missing;
    if (a.aged != b.aged) return a.aged;
    return a.key < b.key || (a.key == b.key && (a.cascade < b.cascade ||
                                                (a.cascade == b.cascade && a.brick < b.brick)));
  });

  // Encoded updates stay alive (shared_ptr) until their fragments are packed.
  std::vector<std::shared_ptr<const EncodedUpdate>> chosen;
  std::vector<Completion> chosenBricks;
  std::size_t considered = 0;
  for (const Candidate& c : candidates) {
    if (budget <= 0) break;
    ++considered;
    Track& t = tracks_[c.cascade][c.brick];
    std::uint64_t version = publisher_.current(c.cascade, c.brick).version;
    std::uint64_t base = 0;
    int level = precision, baseLevel = 0;
    // A residual builds on what the client holds: an older version, or this one held coarser.
    const bool buildsOn = t.acked < version || (t.acked == version && t.ackedPrecision > level);
    if (c.again) {
      version = t.sent;  // self-contained, as it was sent
      level = t.sentPrecision;
    } else if (t.acked != 0 && buildsOn &&
               now - t.selfContainedAt < options_.selfContainedInterval) {
      base = t.acked;
      baseLevel = t.ackedPrecision;
    }
    auto update = publisher_.encoded(c.cascade, c.brick, version, base, level, baseLevel);
    if (!update && base != 0 && !c.again) {
      base = 0;  // the acknowledged version left the history
      baseLevel = 0;
      update = publisher_.encoded(c.cascade, c.brick, version, 0, level, 0);
    }
    if (!update) continue;
    const std::size_t fragments = fragmentCount(update->header.totalSize);
    if (!c.again && fragments > 1 && lostUpdates > 0 &&
        (lostUpdates >= options_.maxLostUpdates ||
         lostBytes + update->payload.size() > options_.maxLostBytes)) {
      continue;  // the receiver may be holding as many partial updates as it can
    }
    budget -= double(update->payload.size() + fragments * kFragmentOverheadBytes);
    const std::uint64_t firstSend = !c.again && t.sent != version ? version : 0;
    if (t.sent == version && t.sentPrecision == level) {
      ++stats_.resends;
      t.resent = true;
    } else {
      t.resent = false;
    }
    t.sent = version;
    t.sentPrecision = level;
    t.sentBasePrecision = baseLevel;
    stats_.coarseUpdates += level != 0;
    t.sentBytes = std::uint32_t(update->payload.size());
    t.sentAt = now;
    if (base == 0) t.selfContainedAt = now;
    t.repair = false;
    ++stats_.updates;
    stats_.residualUpdates += base != 0;
    count(c.reason);
    chosen.push_back(std::move(update));
    chosenBricks.push_back(Completion{0, c.cascade, c.brick, firstSend});
    if (chosen.size() * 2 >= options_.maxDatagramsPerPoll) break;
  }
  // Bricks waited for tokens: the rate, not the field, limits what this client holds (and the
  // sender is not application-limited). The quality ladder counts only changes at the age
  // bound that waited: the perceptual thresholds hold small changes back on purpose, pacing
  // leaves some brick waiting in most polls, and refinements are sent with what room there
  // is (counting them would hold the level up by the very bricks it made coarse).
  waited = considered < candidates.size();
  changesWaited = std::any_of(candidates.begin() + std::ptrdiff_t(considered), candidates.end(),
                              [](const Candidate& c) { return c.aged; });

  for (std::size_t u = 0; u < chosen.size(); ++u) {
    const std::uint16_t n = fragmentCount(chosen[u]->header.totalSize);
    for (std::uint16_t i = 0; i < n; ++i) {
      packer.add(fragmentOf(*chosen[u], i));
      ++stats_.fragments;
    }
    completions.push_back(chosenBricks[u]);
    completions.back().datagram = packed.size();  // the datagram being filled
  }
  packer.flush();

  if (packed.empty()) return;
  for (std::size_t i = 0; i < packed.size(); ++i)
    paced_.push_back(Paced{std::move(packed[i]), firstSequence + std::uint32_t(i), {}, {}});
  const std::size_t first = paced_.size() - packed.size();
  for (const Completion& c : completions) {
    Paced& p = paced_[first + std::min(c.datagram, packed.size() - 1)];
    p.completes.emplace_back(c.cascade, c.brick);
    if (c.firstSend != 0) p.firstSends.push_back(c.firstSend);
  }
}

}  // namespace pc
