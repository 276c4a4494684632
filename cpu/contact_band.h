// The concave-edge measure: the error of an image against the reference in a band along a
// contact line (where a block stands on a floor, common/scene_contact.h), in 8-bit levels of
// the tone-mapped image, where probes alone leave the contact too bright.
#pragma once

#include <array>
#include <glm/glm.hpp>
#include <vector>

#include "../common/image.h"
#include "screen_ao.h"

namespace pc {

// Pixels whose surface (under the pixel centre) lies within `width` of one of the segments.
std::vector<bool> contactBandMask(const ViewSurfaces& surfaces,
                                  const std::array<std::array<glm::vec3, 2>, 4>& segments,
                                  float width);

struct BandError {
  double meanAbs = 0;     // mean |image - reference| over the band's pixels and channels
  double meanSigned = 0;  // mean (image - reference): > 0, the image is too bright there
  int pixels = 0;
};
BandError bandError(const Image8& image, const Image8& reference, const std::vector<bool>& mask);

}  // namespace pc
