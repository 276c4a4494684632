// Brick decoding shared by every receiver of one process. Hundreds of clients receive the same
// payloads (the server encodes each once for all of them), and a payload on the same base
// always decodes to the same codes: decoding it once and sharing the codes saves the clients'
// CPU and memory without changing what any of them holds. Exact, not approximate: a cached
// result is reused only for byte-identical payloads on the very same base object, and every
// decoded version is checked against the codes other clients hold for it.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <tuple>
#include <vector>

#include "protocol/stream_receiver.h"

namespace pc::load {

class SharedBrickDecoder final : public BrickDecoder {
 public:
  explicit SharedBrickDecoder(std::size_t maxEntries = 256) : maxEntries_(maxEntries) {}

  Result<std::shared_ptr<const QuantizedBrick>> decode(
      const UpdateHeader& update, std::span<const std::uint8_t> payload,
      const std::shared_ptr<const QuantizedBrick>& base) override;

  struct Stats {
    std::uint64_t decoded = 0;  // payloads actually decoded
    std::uint64_t shared = 0;   // answered from the cache
    // A version decoded to codes that differ from what another client holds for it: the
    // server sent two different contents under one version. Never expected.
    std::uint64_t mismatches = 0;
  };
  Stats stats() const;

 private:
  struct Key {
    std::uint64_t hash;
    std::size_t size;
    const QuantizedBrick* base;
    int cascade;
    std::uint32_t brick;
    std::uint64_t version;
    std::uint8_t precision;
    auto operator<=>(const Key&) const = default;
  };
  struct Entry {
    std::vector<std::uint8_t> payload;
    std::shared_ptr<const QuantizedBrick> base;  // pinned, so `Key::base` is never reused
    std::shared_ptr<const QuantizedBrick> result;
    std::uint64_t lastUse = 0;
  };
  // (cascade, brick, version, precision level): each level of a version is its own content.
  using VersionKey = std::tuple<int, std::uint32_t, std::uint64_t, std::uint8_t>;

  void evictLocked();

  std::size_t maxEntries_;
  mutable std::mutex mutex_;
  std::map<Key, Entry> entries_;
  // One object per brick version while any client holds it, so residual bases converge on
  // one pointer and later residuals hit the cache.
  std::map<VersionKey, std::weak_ptr<const QuantizedBrick>> versions_;
  std::uint64_t clock_ = 0;
  Stats stats_;
};

}  // namespace pc::load
