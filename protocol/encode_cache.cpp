#include "encode_cache.h"

namespace pc {

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
  // Update id 0 is never used, so a receiver's zeroed state never matches a real update.
  if (nextId_ == 0) nextId_ = 1;
  u->header = UpdateHeader{nextId_++,
                           key.cascade,
                           key.brick,
                           key.version,
                           key.base,
                           codec,
                           std::uint32_t(payload.size())};
  u->payload = std::move(payload);
  if (auto it = map_.find(key); it != map_.end()) {
    bytes_ -= it->second.update->payload.size();
    lru_.erase(it->second.lru);
    map_.erase(it);
  }
  bytes_ += u->payload.size();
  lru_.push_front(key);
  map_.emplace(key, Entry{u, lru_.begin()});
  while (bytes_ > maxBytes_ && lru_.size() > 1) {
    auto victim = map_.find(lru_.back());
    bytes_ -= victim->second.update->payload.size();
    map_.erase(victim);
    lru_.pop_back();
  }
  return u;
}

}  // namespace pc
