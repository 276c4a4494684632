// Session messages of the streaming protocol (session.fbs): plain C++ values, and their wire
// form, a size-prefixed flatbuffer per message on a reliable ordered stream (TCP). Decoding
// checks the size, the identifier and the flatbuffers Verifier, then every count and value, and
// returns an Error naming what was wrong.
#pragma once

#include <cstddef>
#include <cstdint>
#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>
#include <optional>
#include <span>
#include <string>
#include <variant>
#include <vector>

#include "common/field.h"
#include "common/result.h"
#include "common/scene.h"
#include "common/scene_edits.h"
#include "protocol/connect_token.h"
#include "protocol/stream_limits.h"

namespace pc {

// Codec ids (session.fbs enum Codec).
inline constexpr std::uint8_t kCodecQuantZstd = 1;

struct HelloMsg {
  std::uint32_t protocolVersion = kProtocolVersion;
  std::string authToken;
  std::string clientName;
  bool wantsUdp = true;
  std::uint16_t udpPort = 0;
  // Protocol version 7: the field epoch of what the client's mirror holds (0: none).
  std::uint64_t heldEpoch = 0;
};

struct WelcomeMsg {
  std::uint32_t protocolVersion = kProtocolVersion;
  std::uint32_t sessionId = 0;
};

struct RejectMsg {
  std::uint32_t protocolVersion = kProtocolVersion;
  std::string reason;
};

// The field layout a client needs to build its mirror (see mirrorField).
struct SessionInfoMsg {
  std::uint64_t sceneHash = 0;
  std::uint64_t fieldVersion = 0;
  int irradianceTexels = gpu::PC_IRRADIANCE_TEXELS;
  int depthTexels = gpu::PC_DEPTH_TEXELS;
  int occlusionTexels = gpu::PC_OCCLUSION_TEXELS;
  int brickSize = gpu::PC_BRICK_SIZE;
  int atlasTilesPerRow = gpu::PC_ATLAS_TILES_PER_ROW;
  float hysteresis = 0, distanceExponent = 0, occlusionDistance = 0;
  std::vector<gpu::CascadeDesc> cascades;
  std::vector<std::uint8_t> codecs{kCodecQuantZstd};
  std::uint32_t maxDatagramBytes = kMaxDatagramBytes;
  // The server's UDP port for this session's acks and repair requests (protocol version 6,
  // uplink_datagram.h); 0: they go over the session stream.
  std::uint16_t uplinkPort = 0;
  // The field server run this field comes from (protocol version 7; 0: not stated): brick
  // versions of one epoch name the same content on every endpoint serving it.
  std::uint64_t fieldEpoch = 0;
};

struct LightStateMsg {
  glm::vec3 position{0.0f}, direction{0.0f}, color{0.0f};
  float intensity = 0;
  // Protocol version 8: a point light an edit added, and its range (0: unlimited).
  bool added = false;
  float range = 0;
};

// Where a cascade lies: its origin and toroidal scroll (common/field_scroll.h).
struct CascadePlaceMsg {
  glm::vec3 origin{0.0f};
  glm::ivec3 scroll{0};
  bool operator==(const CascadePlaceMsg&) const = default;
};

struct SceneStateMsg {
  double animationTime = 0;
  std::vector<LightStateMsg> lights;
  std::vector<glm::mat4> instanceTransforms;
  // The field version published with this state (0: not stated) and when, in seconds on the
  // server's monotonic clock (steadySeconds()). Bricks carry the field version they changed
  // at, so a client knows when each brick version was published.
  std::uint64_t fieldVersion = 0;
  double publishTime = 0;
  // Protocol version 8: the runtime edits included (0: none; clients replay the animation),
  // and per material a factor on its emission (empty: all 1).
  std::uint64_t editVersion = 0;
  std::vector<float> emissionScales;
  // Protocol version 9: every cascade's place when any cascade follows the viewers (empty:
  // none moves). At most PC_MAX_CASCADES; the receiver checks them against its layout.
  std::vector<CascadePlaceMsg> cascadePlaces;
};

struct ViewerPoseMsg {
  glm::vec3 position{0.0f};
  glm::quat orientation{1.0f, 0.0f, 0.0f, 0.0f};
  double time = 0;
};

// A run of `count` consecutive bricks of one cascade held at one version.
struct AckRange {
  int cascade = 0;
  std::uint32_t firstBrick = 0, count = 0;
  std::uint64_t version = 0;
};

// A partially received update and the fragments it lacks (selective repair).
struct FragmentGapMsg {
  std::uint32_t updateId = 0;
  int cascade = 0;
  std::uint32_t brick = 0;
  std::uint64_t version = 0, baseVersion = 0;
  std::uint16_t fragmentCount = 0;
  std::vector<std::uint16_t> missing;  // indices below fragmentCount
};

// Gaps one Ack may carry (more is refused): the receiver's reassembly holds fewer partial
// updates than this.
inline constexpr std::size_t kMaxFragmentGaps = 128;

// A datagram's arrival: its sequence number and the receiver's clock then, in microseconds
// (wrapping).
struct DatagramArrivalMsg {
  std::uint32_t sequence = 0;
  std::uint32_t arrivalMicros = 0;
};

// Arrivals one Ack may carry (more is refused). A receiver acknowledges every ack interval
// (20 ms), in which 1,024 datagrams of 1,200 bytes are 490 Mbit/s.
inline constexpr std::size_t kMaxAckArrivals = 1024;

// A brick held at a precision level above 0 (protocol/brick_precision.h).
struct BrickPrecisionMsg {
  int cascade = 0;
  std::uint32_t brick = 0;
  int precision = 0;
};

struct AckMsg {
  bool full = false;  // every held brick is listed; unlisted bricks hold nothing
  std::uint64_t fieldVersion = 0;
  std::vector<AckRange> ranges;
  std::vector<FragmentGapMsg> gaps;
  std::vector<DatagramArrivalMsg> arrivals;  // since the previous Ack, in order of arrival
  // Bricks of `ranges` held coarser than the codec's own precision; the others are at 0.
  std::vector<BrickPrecisionMsg> precisions;
};

struct BrickRefMsg {
  int cascade = 0;
  std::uint32_t brick = 0;
  std::uint64_t haveVersion = 0;
  int havePrecision = 0;  // the precision level `haveVersion` is held at
};

struct RepairRequestMsg {
  std::vector<BrickRefMsg> bricks;
};

// What the server's sender sees of one client (session.fbs StreamReport).
struct StreamReportMsg {
  double rate = 0, delivered = 0;  // bytes/s
  float queueDelayMs = 0, loss = 0;
  int qualityLevel = 0;
  float heldPsnrDb = 0;  // kHeldPsnrCap where the held field equals the current one
  float oldestChangeSeconds = 0;
  std::uint32_t pendingBricks = 0;
  std::uint64_t fieldVersion = 0;
};

// The most bricks a Resume may claim: a layout holds at most 4M probe slots (mirrorField), 64
// to a brick.
inline constexpr std::uint32_t kMaxResumeBricks = (4u << 20) / 64;

// What a client's mirror holds, for a session on another endpoint of the same field (protocol
// version 7; resume_state.h builds and reads it).
struct ResumeMsg {
  std::uint64_t sceneHash = 0, fieldEpoch = 0;
  std::uint32_t brickCount = 0;               // every brick of the field, or 0: nothing held
  std::vector<std::uint8_t> versions;         // zstd frame of brickCount uint64, as 8 byte planes
  std::vector<BrickPrecisionMsg> precisions;  // bricks held at a level above 0
};

// Protocol version 8: a runtime edit (common/scene_edits.h) from an editor's session. Decoding
// checks only the structure and the operation; SceneEdits bounds every value, so a hostile
// value gets an EditResult naming it and the session goes on.
struct EditMsg {
  std::uint32_t editId = 0;
  SceneEdit edit;
};

struct EditResultMsg {
  std::uint32_t editId = 0;
  bool accepted = false;
  std::string reason;
  std::uint64_t editVersion = 0;
  std::uint32_t target = 0;
};

// An EditResult's reason is cut to this many bytes when read.
inline constexpr std::size_t kMaxEditReasonBytes = 512;
// The most scene materials a SceneState may carry emission factors for.
inline constexpr std::size_t kMaxEmissionScales = 65536;

using SessionMessage =
    std::variant<HelloMsg, WelcomeMsg, RejectMsg, SessionInfoMsg, SceneStateMsg, ViewerPoseMsg,
                 AckMsg, RepairRequestMsg, StreamReportMsg, ResumeMsg, EditMsg, EditResultMsg>;

// The message's name as the schema spells it ("Hello", "SessionInfo", ...), for errors.
const char* sessionMessageName(const SessionMessage& message);

// Size-prefixed flatbuffer: 4-byte little-endian length, then the message.
std::vector<std::uint8_t> encodeMessage(const SessionMessage& message);
// Whole frame, size prefix included.
Result<SessionMessage> decodeMessage(std::span<const std::uint8_t> frame);
// For stream readers: given the first 4 bytes of a frame, the whole frame's size, or an Error
// when it announces more than kMaxSessionMessageBytes.
Result<std::size_t> messageFrameSize(std::span<const std::uint8_t> prefix);

// Server side of the handshake: the client's protocol version, then its connect token
// (connect_token.h), verified for `scene` at `nowUnix`. Nothing in `reject` admits the client
// with the token's claims.
struct HelloVerdict {
  std::optional<RejectMsg> reject;
  bool versionMismatch = false;          // rejected for its protocol version
  std::optional<TokenError> tokenError;  // rejected for its token, and why
  TokenClaims claims;                    // the admitted client's
};
HelloVerdict checkHello(const HelloMsg& hello, const TokenVerifier& verifier,
                        std::string_view scene, std::int64_t nowUnix);
// Client side: an Error when the server's protocol version is one this client cannot speak.
Status checkServerVersion(std::uint32_t serverVersion);

// The layout message for a field, and the empty mirror field a client builds from it (every
// brick at version 0, every probe uninitialized). mirrorField checks the layout as strictly as
// a baked file reader does.
SessionInfoMsg sessionInfoFor(const Field& field);
Result<Field> mirrorField(const SessionInfoMsg& info);

// Scene state <-> message. applySceneState needs the scene's own lights and instances (types,
// cones, meshes), evaluated at any time, and fails when the instance counts differ or the
// message's lights are neither the scene's nor, after them, lights edits added.
// Every cascade's place when any cascade of `field` follows the viewers; else empty.
std::vector<CascadePlaceMsg> cascadePlaces(const Field& field);
SceneStateMsg sceneStateMessage(const SceneState& state);
Status applySceneState(const SceneStateMsg& message, SceneState& state);

}  // namespace pc
