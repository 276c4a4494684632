// The brick codec: one brick's content (the interiors of its 64 probe slots' irradiance, depth
// and occlusion tiles and its probe records) quantized to 16-bit codes, then coded either
// self-contained (spatial prediction) or as a residual against a base version's codes, split
// into byte planes and compressed with zstd. PROTOCOL.md ("Brick codec") specifies the format
// and states the quantization bounds, which are also the constants below.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "common/field.h"
#include "common/result.h"

namespace pc {

// Layout of QuantizedBrick::codes: sections one after another, each a sequence of planes.
namespace brick_layout {
inline constexpr int kSlots = gpu::PC_PROBES_PER_BRICK;
inline constexpr int kIrrTexels = gpu::PC_IRRADIANCE_TEXELS * gpu::PC_IRRADIANCE_TEXELS;
inline constexpr int kDepthTexels = gpu::PC_DEPTH_TEXELS * gpu::PC_DEPTH_TEXELS;
inline constexpr int kOccTexels = gpu::PC_OCCLUSION_TEXELS * gpu::PC_OCCLUSION_TEXELS;
// Irradiance: 3 planes (r, g, b), each [slot][texel row-major].
inline constexpr std::size_t kIrradiance = 0;
// Depth: 2 planes (mean, standard deviation), each [slot][texel].
inline constexpr std::size_t kDepth = kIrradiance + std::size_t(3) * kSlots * kIrrTexels;
// Occlusion: 1 plane [slot][texel].
inline constexpr std::size_t kOcclusion = kDepth + std::size_t(2) * kSlots * kDepthTexels;
// Probe offsets: 3 planes (x, y, z), each [slot].
inline constexpr std::size_t kOffset = kOcclusion + std::size_t(kSlots) * kOccTexels;
// Probe states: 1 plane [slot].
inline constexpr std::size_t kState = kOffset + std::size_t(3) * kSlots;
inline constexpr std::size_t kCodes = kState + kSlots;
}  // namespace brick_layout

// Quantization bounds (see PROTOCOL.md). Irradiance: the gamma-encoded value e as a 12-bit
// float (5 exponent bits for e in [2^-15, 2^16), 7 stored mantissa bits, round to nearest).
// Seven bits, not more: the temporal dead zone and the sender's thresholds hold changes of a
// few times 1/256 anyway, and each further bit costs about one bit per changed code on the
// wire (docs/BENCHMARKS.md, streaming bandwidth).
inline constexpr int kIrradianceMantissaBits = 7;
inline constexpr float kIrradianceRelativeBound = 1.0f / 256.0f;    // |e' - e| <= this * e
inline constexpr float kIrradianceAbsoluteBound = 1.0f / 32768.0f;  // for e < 2^-15
// Depth mean and standard deviation: 16 bits over [0, maxRayDistance].
inline constexpr float kDepthBound = 1.0f / 131070.0f;  // x maxRayDistance
// Occlusion: 8 bits over [0, 1].
inline constexpr float kOcclusionBound = 1.0f / 510.0f;
// Probe offsets: 16 bits over [-spacing, spacing].
inline constexpr float kOffsetBound = 1.0f / 65534.0f;  // x spacing

// One brick's content as codes (layout above). Shared read-only between the sender's history,
// its encode cache and every client; the receiver keeps its current one per brick as the base
// for residuals.
struct QuantizedBrick {
  std::vector<std::uint16_t> codes;  // brick_layout::kCodes values
  // The cascade's origin when the brick was quantized: its layout stamp (common/field_scroll.h).
  // A slot's data stands for the grid point that layout put there; applyBrick shows only the
  // slots that the field's current layout puts at the same grid point. Unset: the brick is of
  // the field's own layout (a cascade that never moves).
  std::optional<glm::vec3> origin;
  bool operator==(const QuantizedBrick&) const = default;
};

// Reads brick `brick` of cascade `cascade` (all 64 slots, padding slots included).
QuantizedBrick quantizeBrick(const Field& field, int cascade, int brick);
// Writes decoded values into the brick's tile interiors, re-derives the tile borders, and sets
// the probe records' offsets and states (update counts are server bookkeeping and not sent).
// A slot whose data the stamp places at another grid point than the field's layout does gets
// the uninitialized state: it is never sampled.
void applyBrick(Field& field, int cascade, int brick, const QuantizedBrick& q);
// The probe records (offsets, states) alone, masked as applyBrick does: after the cascade's
// layout moved, the held bricks' slots are shown again or hidden by their stamps.
void applyBrickRecords(Field& field, int cascade, int brick, const QuantizedBrick& q);

// Individual code conversions, exposed for tests.
std::uint16_t quantizeIrradiance(float encoded);
float dequantizeIrradiance(std::uint16_t code);

// How much a brick's content changed between two versions, for the perceptual skip.
struct BrickChange {
  float irradiance = 0;  // max over texels and channels of |delta e| (gamma-encoded)
  // Mean |delta e| over all the brick's irradiance codes, unchanged ones included: ray noise
  // moves a few texels a lot, a moving light moves many texels together.
  float irradianceMean = 0;
  // Mean of (delta e)^2 over the same codes: the held field's error (StreamSender's report).
  double irradianceMeanSquare = 0;
  float depth = 0;      // max |delta mean| / maxRayDistance
  float occlusion = 0;  // max |delta|
  float offset = 0;     // max |delta| of a relocation offset component / spacing
  bool states = false;  // a probe state (or the layout stamp) changed
};
BrickChange brickChange(const QuantizedBrick& a, const QuantizedBrick& b);

// Temporal dead zone, applied by the server when it quantizes a new version of a brick: a code
// whose value moved by no more than the tolerance since the previous version keeps the
// previous code. Ray noise then leaves most codes untouched between versions, so residuals
// are mostly zeros; real changes (a light moved) still pass. Every decoded value stays within
// the tolerance plus the quantization bound of the value it stands for, because the
// comparison is always against the newest value, never against earlier kept codes. Zero
// tolerances change nothing.
struct DeadZone {
  float irradiance = 0;  // |delta e| (gamma-encoded irradiance)
  float depth = 0;       // |delta| of depth mean and standard deviation, x the texel's mean
  float occlusion = 0;   // |delta|
  float offset = 0;      // |delta| of a relocation offset component, x the spacing; when
                         // > 0, offsets of probes that are not sampled are always held
  // A flip between active and sleeping keeps the previous state: both are sampled alike, and
  // the classification flips with ray noise for probes near its distance limit.
  bool sleepingAsActive = false;
  bool active() const {
    return irradiance > 0 || depth > 0 || occlusion > 0 || offset > 0 || sleepingAsActive;
  }
};
// Other state changes are never held. Returns the number of codes that kept their previous
// value.
std::size_t holdSmallChanges(QuantizedBrick& q, const QuantizedBrick& previous,
                             const DeadZone& tolerance);

// Codec QuantZstd. `base` null: self-contained; otherwise a residual against `base`.
// zstdLevel: 1 (fast) .. 19 (small).
std::vector<std::uint8_t> encodeBrick(const QuantizedBrick& q, const QuantizedBrick* base,
                                      int zstdLevel = 3);
// Defensive: any byte string yields either a brick whose codes are all in range, or an Error
// naming the problem. `base` must be given exactly when the update names a base version.
Result<QuantizedBrick> decodeBrick(std::span<const std::uint8_t> payload,
                                   const QuantizedBrick* base);

// A payload never exceeds this (zstd's bound for the raw planes plus the header).
std::size_t maxEncodedBrickBytes();

}  // namespace pc
