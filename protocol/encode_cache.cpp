#include "encode_cache.h"

#include <iterator>

namespace pc {

std::uint32_t updateIdFor(const EncodeKey& key) {
  // splitmix64's finalizer over the key's words, folded to 32 bits.
  auto mix = [](std::uint64_t h) {
    h ^= h >> 30;
    h *= 0xbf58476d1ce4e5b9ull;
    h ^= h >> 27;
    h *= 0x94d049bb133111ebull;
    return h ^ (h >> 31);
  };
  std::uint64_t h = mix(std::uint64_t(std::uint32_t(key.cascade)) << 32 | key.brick);
  h = mix(h ^ key.version);
  h = mix(h ^ (key.base + 0x9e3779b97f4a7c15ull));
  // Levels other than 0 change the id; at level 0 it is what it always was.
  if (key.precision != 0 || key.basePrecision != 0)
    h = mix(h ^ (std::uint64_t(key.precision) << 8 | key.basePrecision));
  const std::uint32_t id = std::uint32_t(h ^ (h >> 32));
  return id != 0 ? id : 1u;
}

std::shared_ptr<const EncodedUpdate> EncodeCache::find(const EncodeKey& key) {
  auto it = map_.find(key);
  if (it == map_.end()) {
    ++misses_;
    return nullptr;
  }
  ++hits_;
  lru_.splice(lru_.begin(), lru_, it->second.lru);
  return it->second.update;
}

std::shared_ptr<const EncodedUpdate> EncodeCache::insert(const EncodeKey& key, std::uint8_t codec,
                                                         std::vector<std::uint8_t> payload) {
  auto u = std::make_shared<EncodedUpdate>();
  u->header = UpdateHeader{updateIdFor(key),
                           key.cascade,
                           key.brick,
                           key.version,
                           key.base,
                           codec,
                           std::uint32_t(payload.size()),
                           key.precision,
                           key.basePrecision};
  u->payload = std::move(payload);
  if (auto it = map_.find(key); it != map_.end()) erase(it);
  bytes_ += u->payload.capacity();
  lru_.push_front(key);
  map_.emplace(key, Entry{u, lru_.begin()});
  while (bytes_ > maxBytes_ && lru_.size() > 1) erase(map_.find(lru_.back()));
  return u;
}

void EncodeCache::eraseBrickIf(int cascade, std::uint32_t brick,
                               const std::function<bool(const EncodeKey&)>& drop) {
  // Keys order by (cascade, brick, version, base): one brick's entries are one range.
  auto it = map_.lower_bound(EncodeKey{cascade, brick, 0, 0});
  while (it != map_.end() && it->first.cascade == cascade && it->first.brick == brick) {
    auto next = std::next(it);
    if (drop(it->first)) erase(it);
    it = next;
  }
}

void EncodeCache::erase(std::map<EncodeKey, Entry>::iterator it) {
  bytes_ -= it->second.update->payload.capacity();
  lru_.erase(it->second.lru);
  map_.erase(it);
}

}  // namespace pc
