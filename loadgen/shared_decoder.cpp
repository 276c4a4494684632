#include "shared_decoder.h"

#include <algorithm>
#include <functional>
#include <string_view>

#include "protocol/brick_codec.h"

namespace pc::load {

Result<std::shared_ptr<const QuantizedBrick>> SharedBrickDecoder::decode(
    const UpdateHeader& update, std::span<const std::uint8_t> payload,
    const std::shared_ptr<const QuantizedBrick>& base) {
  const std::uint64_t hash = std::hash<std::string_view>{}(
      std::string_view(reinterpret_cast<const char*>(payload.data()), payload.size()));
  const Key key{hash,         payload.size(), base.get(),      update.cascade,
                update.brick, update.version, update.precision};
  {
    std::lock_guard lock(mutex_);
    auto it = entries_.find(key);
    if (it != entries_.end() && it->second.base == base &&
        std::equal(payload.begin(), payload.end(), it->second.payload.begin(),
                   it->second.payload.end())) {
      it->second.lastUse = ++clock_;
      ++stats_.shared;
      return it->second.result;
    }
  }
  // Decoded outside the lock: other threads' clients keep going meanwhile.
  auto decoded = decodeBrick(payload, base.get());
  if (!decoded) return decoded.error();
  auto result = std::make_shared<const QuantizedBrick>(std::move(decoded).value());

  std::lock_guard lock(mutex_);
  ++stats_.decoded;
  std::weak_ptr<const QuantizedBrick>& canonical =
      versions_[VersionKey{update.cascade, update.brick, update.version, update.precision}];
  if (auto held = canonical.lock()) {
    if (*held == *result) {
      result = held;
    } else {
      ++stats_.mismatches;
    }
  } else {
    canonical = result;
  }
  Entry& e = entries_[key];
  e.payload.assign(payload.begin(), payload.end());
  e.base = base;
  e.result = result;
  e.lastUse = ++clock_;
  if (entries_.size() > maxEntries_) evictLocked();
  return result;
}

// Drops the least recently used half, and versions no client holds any more.
void SharedBrickDecoder::evictLocked() {
  std::vector<std::uint64_t> uses;
  uses.reserve(entries_.size());
  for (const auto& [k, e] : entries_) uses.push_back(e.lastUse);
  std::nth_element(uses.begin(), uses.begin() + uses.size() / 2, uses.end());
  const std::uint64_t cut = uses[uses.size() / 2];
  std::erase_if(entries_, [cut](const auto& kv) { return kv.second.lastUse < cut; });
  std::erase_if(versions_, [](const auto& kv) { return kv.second.expired(); });
}

SharedBrickDecoder::Stats SharedBrickDecoder::stats() const {
  std::lock_guard lock(mutex_);
  return stats_;
}

}  // namespace pc::load
