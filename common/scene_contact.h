// A scene built in code for measuring contact darkening: a closed white room with a block
// standing on the floor, lit by one point light, seen from above the block. The concave edge
// where the block meets the floor is the contact the probes are too coarse to resolve.
#pragma once

#include <array>
#include <glm/glm.hpp>

#include "scene.h"

namespace pc {

// The block's footprint on the floor (y = 0): the rectangle whose edges are the contact line.
inline constexpr glm::vec3 kContactBlockLo{-0.4f, 0.0f, -0.4f};
inline constexpr glm::vec3 kContactBlockHi{0.4f, 0.8f, 0.4f};

Scene contactScene();

// The contact line: the four bottom edges of the block, as segments (a, b).
std::array<std::array<glm::vec3, 2>, 4> contactSceneEdges();

}  // namespace pc
