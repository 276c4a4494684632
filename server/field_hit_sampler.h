// The previous field's indirect light at probe-ray hits, as the Embree update shades them: the
// very result of sampleField(field, P, N, V, PC_SAMPLE_NO_OCCLUSION), computed for the probes
// of a cage four at a time in SIMD lanes, with each probe's position, state and tile places
// read from tables built once per update instead of derived per hit and probe.
#pragma once

#include <cstdint>
#include <glm/glm.hpp>
#include <vector>

#include "../common/field.h"

namespace pc {

class FieldHitSampler {
 public:
  // Reads `field`, which must outlive the sampler and stay unchanged while it samples.
  explicit FieldHitSampler(const Field& field);

  // Irradiance (W/m^2) at surface point P with normal N, seen from V (unit, toward the viewer).
  glm::vec3 irradiance(glm::vec3 P, glm::vec3 N, glm::vec3 V) const;
  // The same looked up toward Ns (unit) instead of N, the probes placed and weighed by N:
  // pcSampleFieldShaded.
  glm::vec3 irradiance(glm::vec3 P, glm::vec3 N, glm::vec3 Ns, glm::vec3 V) const;

  // One probe of a cascade, by logical grid index x + counts.x * (y + counts.y * z).
  struct Probe {
    glm::vec3 position;             // relocated, world
    std::uint32_t depthTexel;       // float index of its depth tile's first texel (read with
                                    // the position: keep it fourth)
    std::uint32_t irradianceTexel;  // likewise in the irradiance atlas
    std::uint32_t hasData;          // pcProbeHasData of its state
  };

 private:
  glm::vec4 sampleCascade(int k, glm::vec3 P, glm::vec3 N, glm::vec3 Ns, glm::vec3 V,
                          float& weightSum) const;
  glm::vec4 sampleCascadeWide(int k, glm::vec3 P, glm::vec3 N, glm::vec3 Ns, glm::vec3 V,
                              float& weightSum) const;

  const Field& field_;
  bool tiled_ = true;                       // every cascade stores irradiance in tiles (not SH)
  std::vector<std::vector<Probe>> probes_;  // [cascade][logical index]
};

}  // namespace pc
