// What the field server puts in the NATS key-value bucket and on NATS subjects, and what
// relays read back: byte formats without any NATS call (PROTOCOL.md, "Field distribution over
// NATS"). Every value starts with a magic, a format version and the epoch of the field
// server's run, so a relay tells a restarted server's field from the one it holds, and
// refuses what it cannot read with an Error naming the key and the problem.
#pragma once

#include <cstdint>
#include <glm/glm.hpp>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "common/result.h"

namespace pc::relay {

inline constexpr std::uint16_t kBucketFormat = 1;

// Keys of the bucket: one per brick ("brick.<cascade>.<brick>"), whose value is the brick's
// current version; the field's catalogue; the newest scene state.
inline constexpr const char* kCatalogueKey = "catalogue";
inline constexpr const char* kStateKey = "state";
std::string brickKey(int cascade, std::uint32_t brick);

// The field's catalogue: the layout (volumes, cascades) as the session protocol's SessionInfo
// frame, the scene name connect tokens name, and the run's epoch.
struct CatalogueRecord {
  std::uint64_t epoch = 0;
  std::string sceneName;
  std::vector<std::uint8_t> sessionInfoFrame;  // encodeMessage(SessionInfoMsg)
};

// The newest scene state, written after the bricks of the field version it names.
struct StateRecord {
  std::uint64_t epoch = 0;
  std::uint64_t fieldVersion = 0;
  double wallTime = 0;  // when the field server published it, in Unix seconds (latency)
  std::vector<std::uint8_t> sceneStateFrame;  // encodeMessage(SceneStateMsg)
};

// One brick's current version, self-contained (no residual base): brick codec QuantZstd.
struct BrickRecord {
  std::uint64_t epoch = 0;
  std::uint16_t cascade = 0;
  std::uint32_t brick = 0;
  std::uint64_t version = 0;
  double wallTime = 0;
  std::vector<std::uint8_t> payload;  // encodeBrick(q, nullptr)
};

std::vector<std::uint8_t> encodeCatalogue(const CatalogueRecord& r);
std::vector<std::uint8_t> encodeState(const StateRecord& r);
std::vector<std::uint8_t> encodeBrickRecord(const BrickRecord& r);
Result<CatalogueRecord> decodeCatalogue(std::span<const std::uint8_t> bytes);
Result<StateRecord> decodeState(std::span<const std::uint8_t> bytes);
Result<BrickRecord> decodeBrickRecord(std::span<const std::uint8_t> bytes);
// (cascade, brick) of a brick key; nothing for any other key.
std::optional<std::pair<int, std::uint32_t>> parseBrickKey(const std::string& key);

// Subjects beside the bucket (core NATS, not stored), under "probecast.<bucket>.".
std::string posesSubject(const std::string& bucket, const std::string& relay);  // relay -> server
std::string loadSubject(const std::string& bucket, const std::string& relay);   // relay -> all
std::string posesWildcard(const std::string& bucket);
std::string loadWildcard(const std::string& bucket);

// A relay's viewers, for the field server's probe scheduler: each client's newest position
// and weight (connect token), at most kMaxPosesPerMessage of them.
inline constexpr std::size_t kMaxPosesPerMessage = 4096;
struct PosesMessage {
  std::string relay;
  std::vector<glm::vec3> positions;
  std::vector<float> weights;
};
std::vector<std::uint8_t> encodePoses(const PosesMessage& m);
Result<PosesMessage> decodePoses(std::span<const std::uint8_t> bytes);

// A relay's load, which clients and operators choose relays by: JSON, readable with any NATS
// tool ({"relay":..,"endpoint":"host:port","clients":n,"max_clients":m}).
struct LoadMessage {
  std::string relay, endpoint;
  std::uint64_t clients = 0, maxClients = 0;
};
std::vector<std::uint8_t> encodeLoad(const LoadMessage& m);
Result<LoadMessage> decodeLoad(std::span<const std::uint8_t> bytes);

// A relay id or bucket name as a NATS subject token: letters, digits, '-' and '_' only.
bool validToken(const std::string& s);

}  // namespace pc::relay
