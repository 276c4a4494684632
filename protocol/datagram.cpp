// Datagram encoding and decoding, fragment reassembly.
#include "datagram.h"

#include <flatbuffers/flatbuffers.h>

#include <algorithm>
#include <cstring>
#include <string>

#include "protocol/brick_precision.h"
#include "protocol/crc32.h"
#include "protocol/datagram_generated.h"

namespace pc {

namespace {

namespace fb = flatbuffers;

constexpr std::size_t kCrcBytes = 4;

Error fail(const std::string& what) { return Error{"datagram: " + what}; }

}  // namespace

std::uint16_t fragmentCount(std::uint32_t totalSize) {
  return std::uint16_t((std::size_t(totalSize) + kFragmentBytes - 1) / kFragmentBytes);
}

std::vector<std::uint8_t> encodeDatagram(std::uint32_t sessionId, std::uint32_t sequence,
                                         std::uint64_t fieldVersion,
                                         std::span<const FragmentRef> fragments) {
  fb::FlatBufferBuilder fbb(kMaxDatagramBytes);
  std::vector<fb::Offset<net::BrickFragment>> offs;
  offs.reserve(fragments.size());
  for (const FragmentRef& f : fragments) {
    auto data = fbb.CreateVector(f.data.data(), f.data.size());
    const UpdateHeader& u = f.update;
    offs.push_back(net::CreateBrickFragment(
        fbb, u.updateId, std::uint8_t(u.cascade), u.brick, u.version, u.baseVersion, u.codec,
        u.totalSize, f.index, fragmentCount(u.totalSize), data, u.precision, u.basePrecision));
  }
  auto vec = fbb.CreateVector(offs);
  auto root = net::CreateDatagram(fbb, sessionId, sequence, fieldVersion, vec);
  net::FinishDatagramBuffer(fbb, root);
  std::vector<std::uint8_t> out(fbb.GetBufferPointer(), fbb.GetBufferPointer() + fbb.GetSize());
  const std::uint32_t crc = crc32(out);
  for (int i = 0; i < 4; ++i) out.push_back(std::uint8_t(crc >> (8 * i)));
  return out;
}

Result<Datagram> decodeDatagram(std::span<const std::uint8_t> bytes) {
  if (bytes.size() > kMaxDatagramBytes) {
    return fail(std::to_string(bytes.size()) + " bytes, limit " +
                std::to_string(kMaxDatagramBytes));
  }
  if (bytes.size() < 8 + kCrcBytes)
    return fail("truncated (" + std::to_string(bytes.size()) + " bytes)");
  const std::span<const std::uint8_t> body = bytes.first(bytes.size() - kCrcBytes);
  std::uint32_t stored = 0;
  for (int i = 0; i < 4; ++i) stored |= std::uint32_t(bytes[body.size() + i]) << (8 * i);
  if (crc32(body) != stored) return fail("checksum mismatch");
  if (!fb::BufferHasIdentifier(body.data(), net::DatagramIdentifier())) {
    return fail("not a probecast datagram (wrong identifier)");
  }
  // Aligned copy: the Verifier checks alignment against the address.
  alignas(8) std::uint8_t aligned[kMaxDatagramBytes];
  std::memcpy(aligned, body.data(), body.size());
  fb::Verifier::Options opts;
  opts.max_depth = kMaxMessageDepth;
  opts.max_tables = kMaxDatagramTables;
  fb::Verifier v(aligned, body.size(), opts);
  if (!net::VerifyDatagramBuffer(v)) return fail("corrupt (flatbuffer verification failed)");
  const net::Datagram* root = net::GetDatagram(aligned);

  Datagram d;
  d.sessionId = root->session_id();
  d.sequence = root->sequence();
  d.fieldVersion = root->field_version();
  if (root->fragments()) {
    for (const net::BrickFragment* f : *root->fragments()) {
      Fragment out;
      UpdateHeader& u = out.update;
      u.updateId = f->update_id();
      u.cascade = f->cascade();
      u.brick = f->brick();
      u.version = f->version();
      u.baseVersion = f->base_version();
      u.codec = f->codec();
      u.totalSize = f->total_size();
      u.precision = f->precision();
      u.basePrecision = f->base_precision();
      out.index = f->fragment_index();
      out.count = f->fragment_count();
      const std::string at = "fragment " + std::to_string(d.fragments.size()) + ": ";
      if (u.totalSize == 0 || u.totalSize > kMaxUpdatePayloadBytes) {
        return fail(at + "payload size " + std::to_string(u.totalSize) + " out of range");
      }
      if (out.count != fragmentCount(u.totalSize)) {
        return fail(at + std::to_string(out.count) + " fragments announced for " +
                    std::to_string(u.totalSize) + " bytes");
      }
      if (out.index >= out.count) return fail(at + "index beyond the fragment count");
      const std::size_t begin = std::size_t(out.index) * kFragmentBytes;
      const std::size_t expected = std::min<std::size_t>(u.totalSize - begin, kFragmentBytes);
      const std::size_t got = f->data() ? f->data()->size() : 0;
      if (got != expected) {
        return fail(at + std::to_string(got) + " data bytes, expected " + std::to_string(expected));
      }
      if (u.precision > kMaxPrecision || u.basePrecision > kMaxPrecision) {
        return fail(at + "precision level " + std::to_string(u.precision) + " on " +
                    std::to_string(u.basePrecision) + ", the finest is 0 and the coarsest " +
                    std::to_string(kMaxPrecision));
      }
      // A residual builds on an older version, or refines its own version held coarser.
      const bool refinement =
          u.baseVersion == u.version && u.basePrecision > u.precision && u.baseVersion != 0;
      if (u.version == 0 || (u.baseVersion >= u.version && !refinement)) {
        return fail(at + "version " + std::to_string(u.version) + " on base " +
                    std::to_string(u.baseVersion));
      }
      out.data.assign(f->data()->begin(), f->data()->end());
      d.fragments.push_back(std::move(out));
    }
  }
  return d;
}

void Reassembler::erase(std::map<std::uint32_t, Partial>::iterator it) {
  bytes_ -= it->second.payload.size();
  partial_.erase(it);
}

std::optional<CompletedUpdate> Reassembler::add(Fragment&& fragment, double now,
                                                std::uint32_t sequence) {
  const UpdateHeader& u = fragment.update;
  if (fragment.count == 1) {
    // Whole payload in one fragment: nothing to hold.
    return CompletedUpdate{u, std::move(fragment.data)};
  }
  auto it = partial_.find(u.updateId);
  if (it != partial_.end() && !it->second.update.sameUpdate(u)) {
    erase(it);
    ++dropped_;
    it = partial_.end();
  }
  if (it == partial_.end()) {
    // Make room: drop the oldest partial payloads until both caps hold with this one added.
    while (!partial_.empty() && (partial_.size() + 1 > options_.maxUpdates ||
                                 bytes_ + u.totalSize > options_.maxBytes)) {
      auto oldest = std::min_element(partial_.begin(), partial_.end(), [](auto& a, auto& b) {
        return a.second.lastSeen < b.second.lastSeen;
      });
      erase(oldest);
      ++dropped_;
    }
    if (u.totalSize > options_.maxBytes) return std::nullopt;
    Partial p;
    p.update = u;
    p.payload.assign(u.totalSize, 0);
    p.have.assign(fragment.count, false);
    bytes_ += u.totalSize;
    it = partial_.emplace(u.updateId, std::move(p)).first;
  }
  Partial& p = it->second;
  p.lastSeen = now;
  p.lastSequence = sequence;
  if (!p.answered) {  // the first fragment since a report: a sample of the repair round trip
    p.answered = true;
    const double sample = now - p.reportedAt;
    repairRtt_ = repairRtt_ == 0 ? sample : 0.875 * repairRtt_ + 0.125 * sample;
  }
  if (p.have[fragment.index]) return std::nullopt;  // duplicate
  std::copy(fragment.data.begin(), fragment.data.end(),
            p.payload.begin() + std::ptrdiff_t(fragment.index) * std::ptrdiff_t(kFragmentBytes));
  p.have[fragment.index] = true;
  if (++p.received < p.have.size()) return std::nullopt;
  CompletedUpdate done{p.update, std::move(p.payload)};
  p.payload.clear();
  bytes_ -= u.totalSize;
  partial_.erase(it);
  return done;
}

std::vector<FragmentGap> Reassembler::takeGaps(double now, std::uint32_t newestSequence,
                                               std::size_t maxGaps) {
  const double repeat = std::max(options_.gapRepeat, 2.0 * repairRtt_);
  std::vector<Partial*> due;
  for (auto& [id, p] : partial_) {
    // Sequence numbers wrap: their difference, read as signed, says which is newer.
    const bool overtaken =
        std::int32_t(newestSequence - p.lastSequence) >= std::int32_t(options_.gapReorder) &&
        now - p.lastSeen >= options_.gapQuiet;
    if (p.reportedAt >= 0 && !p.answered) {
      // Reported, and no fragment answered yet: again when none came within `repeat`.
      if (now - p.reportedAt < repeat) continue;
    } else if (!overtaken) {
      continue;  // its fragments may still be coming
    }
    due.push_back(&p);
  }
  std::sort(due.begin(), due.end(),
            [](const Partial* a, const Partial* b) { return a->lastSeen < b->lastSeen; });
  if (due.size() > maxGaps) due.resize(maxGaps);
  std::vector<FragmentGap> gaps;
  for (Partial* p : due) {
    FragmentGap g;
    g.update = p->update;
    g.fragmentCount = std::uint16_t(p->have.size());
    for (std::size_t i = 0; i < p->have.size(); ++i)
      if (!p->have[i]) g.missing.push_back(std::uint16_t(i));
    p->reportedAt = now;
    p->answered = false;
    gaps.push_back(std::move(g));
  }
  return gaps;
}

void Reassembler::expire(double now) {
  for (auto it = partial_.begin(); it != partial_.end();) {
    if (now - it->second.lastSeen > options_.timeout) {
      auto next = std::next(it);
      erase(it);
      ++dropped_;
      it = next;
    } else {
      ++it;
    }
  }
}

}  // namespace pc
