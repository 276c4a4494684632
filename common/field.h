// A probe field on the CPU: the cascades' description, the three tile atlases (with 1-texel
// borders, laid out exactly as on the GPU), the per-probe records and per-brick versions.
// The server's update writes it, baked files store it, renderers sample it.
#pragma once

#include <array>
#include <cstdint>
#include <glm/glm.hpp>
#include <span>
#include <vector>

#include "../shaders/interop/probe_math.h"
#include "scene.h"

namespace pc {

// Rays per probe per update: the blend indexes rays with 16 bits and keeps per-ray scratch on
// the stack, and a baked file may not ask for more.
inline constexpr int kMinRaysPerProbe = 16;
inline constexpr int kMaxRaysPerProbe = 1024;

struct FieldSettings {
  int raysPerProbe = 256;  // kMinRaysPerProbe..kMaxRaysPerProbe (Field::create clamps)
  float hysteresis = 0.97f;
  float distanceExponent = 50.0f;
  float normalBias = 0.1f;  // fraction of spacing
  // Fraction of spacing. 0.1, not 0.3: a long view bias moves the point whose visibility is
  // tested far off the surface, toward probes that see more light than the surface does (in
  // corners, under overhangs). It gains 0.16-0.9 dB on five shared scenes and loses 0.43 on
  // two-rooms (docs/BENCHMARKS.md, "Never black, cut-outs, view bias").
  float viewBias = 0.1f;
  float maxRayDistance = 0.0f;     // world units; 0: 1.5 x the cage diagonal (see create)
  float occlusionDistance = 1.0f;  // d_max, fraction of the finest spacing
  float blendMargin = 1.0f;        // fraction of a cascade's spacing
  // How cascades store irradiance where their volume does not say (VolumeSettings::encoding).
  ProbeEncoding encoding = ProbeEncoding::Octahedral;
  // Whether cascades follow the viewers where their volume does not say (VolumeSettings::follow).
  bool followViewers = false;
};

// One SH probe's radiance coefficients, rgb each, in the order of pcShBasis (band 2; a band-1
// probe uses the first 4 and keeps the rest zero).
using ShCoefficients = std::array<glm::vec3, 9>;

// One probe's bookkeeping. `offset` is the relocation from its grid point.
struct ProbeRecord {
  glm::vec3 offset{0.0f};
  int state = gpu::PC_PROBE_UNINITIALIZED;
  std::uint32_t updates = 0;  // blends since the last history reset
};

// A float image of `channels` interleaved channels.
struct Atlas {
  int width = 0, height = 0, channels = 0;
  std::vector<float> texels;
  float* at(int x, int y) { return &texels[(std::size_t(y) * width + x) * channels]; }
  const float* at(int x, int y) const { return &texels[(std::size_t(y) * width + x) * channels]; }
};

class Field {
 public:
  // Lays out the cascades; every probe starts uninitialized.
  static Field create(const std::vector<ProbeVolume>& volumes, const FieldSettings& settings);

  gpu::FieldDesc desc{};
  FieldSettings settings;
  Atlas irradiance;                 // rgb: irradiance^(1/gamma), see PC_IRRADIANCE_GAMMA
  Atlas depth;                      // rg: mean and mean square of hit distance
  Atlas occlusion;                  // r: cos-weighted share of rays that travel past d_max
  std::vector<ProbeRecord> probes;  // field-wide slot index: cascades[k].firstProbe + slot
  // Radiance coefficients of every probe slot, field-wide slot order, when any cascade is SH
  // (empty otherwise). For an SH cascade they are the field's own; its irradiance tiles are
  // derived from them (deriveShTile) for whatever reads tiles (wire, GPU client).
  std::vector<ShCoefficients> sh;
  std::vector<std::vector<std::uint64_t>> brickVersions;  // [cascade][brick]
  std::uint64_t version = 0;  // bumped by every update that changes something
  std::uint64_t sceneHash = 0;

  int cascadeCount() const { return desc.cascadeCount; }
  const gpu::CascadeDesc& cascade(int k) const { return desc.cascades[k]; }
  ProbeRecord& probe(int k, int slot) { return probes[desc.cascades[k].firstProbe + slot]; }
  const ProbeRecord& probe(int k, int slot) const {
    return probes[desc.cascades[k].firstProbe + slot];
  }
  int encoding(int k) const { return desc.cascades[k].encoding; }  // PC_ENCODING_*
  ShCoefficients& shProbe(int k, int slot) { return sh[desc.cascades[k].firstProbe + slot]; }
  const ShCoefficients& shProbe(int k, int slot) const {
    return sh[desc.cascades[k].firstProbe + slot];
  }
  int probeCount() const;                          // real probes, not padding slots
  glm::vec3 probePosition(int k, int slot) const;  // world, relocated

  // Re-derives every tile's border from its interior (after interiors changed).
  void fixBorders(int k, int slot);
};

// Whether two fields lay out their probes alike (cascades, counts, origins, spacing, scroll,
// atlas places): a brick of one then means the same probes in the other.
bool sameLayout(const gpu::FieldDesc& a, const gpu::FieldDesc& b);

// Irradiance (rgb, W/m^2) and occlusion (a) at surface point P with normal N, seen from
// direction V (unit, towards the viewer). Uses the shared sampling code of
// shaders/interop/probe_sampling.h. `coverage` < 1 where no cascade holds data.
glm::vec4 sampleField(const Field& field, glm::vec3 P, glm::vec3 N, glm::vec3 V, int flags,
                      float* coverage = nullptr);
// sampleField with a renderer's last fallback: `ambient` stands in where no probe near P holds
// data (pcSampleFieldOrAmbient), as in the client's lighting pass. N, the surface's own normal,
// places the sample and weighs the probes; Ns, the shading normal (normal-mapped, else N), is
// the direction whose irradiance is looked up.
glm::vec4 sampleFieldOrAmbient(const Field& field, glm::vec3 P, glm::vec3 N, glm::vec3 Ns,
                               glm::vec3 V, int flags, glm::vec3 ambient);
// sampleFieldOrAmbient that also returns, in `specular`, the probes' radiance convolved with
// the GGX lobe of `roughness` toward the mirror direction R (unit), with the same probe weights
// (shaders/interop/specular_probe.h); ambient / pi where no probe holds data.
glm::vec4 sampleFieldOrAmbientLit(const Field& field, glm::vec3 P, glm::vec3 N, glm::vec3 Ns,
                                  glm::vec3 V, int flags, glm::vec3 ambient, glm::vec3 R,
                                  float roughness, glm::vec3& specular);

// Bilinear fetches used by sampleField, exposed for tests and the bake checks.
glm::vec3 fetchIrradiance(const Field& field, int cascade, int slot, glm::vec3 dir);  // decoded
glm::vec2 fetchDepth(const Field& field, int cascade, int slot, glm::vec3 dir);

// ---- spherical-harmonics probes (shaders/interop/sh_probe.h) ----

// Radiance coefficients of `count` (4 or 9) basis functions from radiance samples in uniformly
// spread unit directions: (4 pi / samples) * sum L Y_i.
ShCoefficients projectSh(std::span<const glm::vec3> dirs, std::span<const glm::vec3> radiance,
                         int count);
// Irradiance (W/m^2) toward unit `dir` from the first `count` coefficients: the cosine lobe's
// convolution, clamped at 0.
glm::vec3 shIrradiance(const ShCoefficients& c, int count, glm::vec3 dir);
// Rewrites the irradiance tile of SH probe (k, slot) (interior and border) from its
// coefficients; returns the largest change of an encoded texel, for change detection.
float deriveShTile(Field& field, int k, int slot);
// Rounds every coefficient to float16, as baked files store them: what a client would hold.
void roundShToHalf(Field& field);
// Bytes one probe's irradiance takes at 16 bits per value in `encoding`: an 8x8 rgb tile
// (octahedral, interior only, as the wire carries it), 28 halves (L2, 27 padded to a 4-byte
// boundary) or 12 (L1). Depth moments and occlusion, octahedral in every encoding, come on top.
int irradianceBytesPerProbe(ProbeEncoding encoding);

}  // namespace pc
