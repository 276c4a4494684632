// Directions about +Y for the tests that integrate BRDFs over the hemisphere of a surface whose
// normal is +Y.
#pragma once

#include <cmath>
#include <glm/glm.hpp>

namespace pc::testdir {

// The direction at polar angle theta from +Y (the normal) and azimuth phi.
inline glm::vec3 fromAngles(double theta, double phi) {
  return {float(std::sin(theta) * std::cos(phi)), float(std::cos(theta)),
          float(std::sin(theta) * std::sin(phi))};
}

}  // namespace pc::testdir
