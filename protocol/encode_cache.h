// Encoded brick updates, kept so that each (cascade, brick, version, base) is encoded once and
// its bytes shared by every client. The FieldPublisher drops a brick's entries once they can no
// longer be sent (eraseBrickIf), which bounds the cache by the field's size; least recently
// used entries go first when the byte cap is reached as well. An entry still held by a sender
// stays alive through its shared_ptr.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <list>
#include <map>
#include <memory>
#include <tuple>
#include <vector>

#include "protocol/datagram.h"

namespace pc {

struct EncodedUpdate {
  UpdateHeader header;  // updateId: updateIdFor(key); totalSize = payload.size()
  std::vector<std::uint8_t> payload;
};

struct EncodeKey {
  int cascade = 0;
  std::uint32_t brick = 0;
  std::uint64_t version = 0, base = 0;
  // Precision levels of the version's codes and of the base's (brick_precision.h).
  std::uint8_t precision = 0, basePrecision = 0;
  auto operator<=>(const EncodeKey&) const = default;
};

// The update id of an encoded (cascade, brick, version, base): a hash of the key, never 0 (a
// receiver's zeroed state matches no update). A version's content never changes within a
// session and encoding is deterministic, so an update encoded again after it left the cache
// carries the same id and bytes, and a receiver completes it from the fragments of both sends
// (Reassembler). Different keys that hash alike differ in their headers, which the receiver
// compares in full (UpdateHeader::sameUpdate).
std::uint32_t updateIdFor(const EncodeKey& key);

class EncodeCache {
 public:
  explicit EncodeCache(std::size_t maxBytes) : maxBytes_(maxBytes) {}
  std::shared_ptr<const EncodedUpdate> find(const EncodeKey& key);
  // Stores `payload` under `key` (update id updateIdFor(key)) and returns the entry.
  std::shared_ptr<const EncodedUpdate> insert(const EncodeKey& key, std::uint8_t codec,
                                              std::vector<std::uint8_t> payload);
  // Drops every entry of brick (cascade, brick) whose key `drop` returns true for.
  void eraseBrickIf(int cascade, std::uint32_t brick,
                    const std::function<bool(const EncodeKey&)>& drop);
  // Heap bytes of the payloads held (their capacity, which is what they cost).
  std::size_t bytes() const { return bytes_; }
  std::size_t entries() const { return map_.size(); }
  std::uint64_t hits() const { return hits_; }
  std::uint64_t misses() const { return misses_; }

 private:
  struct Entry {
    std::shared_ptr<const EncodedUpdate> update;
    std::list<EncodeKey>::iterator lru;
  };
  void erase(std::map<EncodeKey, Entry>::iterator it);
  std::size_t maxBytes_;
  std::size_t bytes_ = 0;
  std::map<EncodeKey, Entry> map_;
  std::list<EncodeKey> lru_;  // front: most recently used
  std::uint64_t hits_ = 0, misses_ = 0;
};

}  // namespace pc
