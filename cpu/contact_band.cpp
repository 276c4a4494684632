#include "contact_band.h"

#include <algorithm>
#include <cmath>

namespace pc {

namespace {

float distanceToSegment(glm::vec3 p, glm::vec3 a, glm::vec3 b) {
  const glm::vec3 ab = b - a;
  const float t = std::clamp(glm::dot(p - a, ab) / std::max(glm::dot(ab, ab), 1e-20f), 0.0f, 1.0f);
  return glm::length(p - (a + t * ab));
}

}  // namespace

std::vector<bool> contactBandMask(const ViewSurfaces& surfaces,
                                  const std::array<std::array<glm::vec3, 2>, 4>& segments,
                                  float width) {
  std::vector<bool> mask(surfaces.position.size(), false);
  for (std::size_t i = 0; i < mask.size(); ++i) {
    const glm::vec4 p = surfaces.position[i];
    if (p.w <= 0.0f) continue;
    const glm::vec3 world = surfaces.eye + glm::vec3(p);
    for (const auto& s : segments) {
      if (distanceToSegment(world, s[0], s[1]) <= width) {
        mask[i] = true;
        break;
      }
    }
  }
  return mask;
}

BandError bandError(const Image8& image, const Image8& reference, const std::vector<bool>& mask) {
  BandError e;
  if (image.width != reference.width || image.height != reference.height) return e;
  double abs = 0, sum = 0;
  const std::size_t n = std::size_t(image.width) * image.height;
  for (std::size_t i = 0; i < n && i < mask.size(); ++i) {
    if (!mask[i]) continue;
    for (int c = 0; c < 3; ++c) {
      const double d = double(image.rgb[i * 3 + c]) - double(reference.rgb[i * 3 + c]);
      abs += std::abs(d);
      sum += d;
    }
    ++e.pixels;
  }
  if (e.pixels > 0) {
    e.meanAbs = abs / (3.0 * e.pixels);
    e.meanSigned = sum / (3.0 * e.pixels);
  }
  return e;
}

}  // namespace pc
