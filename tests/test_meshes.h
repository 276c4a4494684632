// Geometry built in code for the tests: quads and axis-aligned boxes with flat normals.
#pragma once

#include <cstdint>

#include <glm/glm.hpp>

#include "common/scene.h"

namespace pc::testmesh {

// Appends the quad a b c d (counter-clockwise seen from its front) as two triangles with flat
// normals.
inline void addQuad(Mesh& mesh, glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 d) {
  const glm::vec3 n = glm::normalize(glm::cross(b - a, c - a));
  const auto base = static_cast<std::uint32_t>(mesh.positions.size());
  for (glm::vec3 p : {a, b, c, d}) {
    mesh.positions.push_back(p);
    mesh.normals.push_back(n);
  }
  for (std::uint32_t i : {0u, 1u, 2u, 0u, 2u, 3u}) mesh.indices.push_back(base + i);
}

// Axis-aligned closed box. Front faces point outward (a solid block) or inward (a room).
inline Mesh boxMesh(glm::vec3 lo, glm::vec3 hi, bool inward) {
  Mesh mesh;
  const glm::vec3 c[8] = {{lo.x, lo.y, lo.z}, {hi.x, lo.y, lo.z}, {hi.x, hi.y, lo.z},
                          {lo.x, hi.y, lo.z}, {lo.x, lo.y, hi.z}, {hi.x, lo.y, hi.z},
                          {hi.x, hi.y, hi.z}, {lo.x, hi.y, hi.z}};
  // Outward counter-clockwise corner orders for -z, +z, -x, +x, -y, +y.
  const int faces[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 4, 7, 3},
                           {1, 2, 6, 5}, {0, 1, 5, 4}, {3, 7, 6, 2}};
  for (const auto& f : faces) {
    if (inward) {
      addQuad(mesh, c[f[0]], c[f[3]], c[f[2]], c[f[1]]);
    } else {
      addQuad(mesh, c[f[0]], c[f[1]], c[f[2]], c[f[3]]);
    }
  }
  return mesh;
}

}  // namespace pc::testmesh
