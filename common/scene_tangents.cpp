// Tangents for normal maps: checking those a file gives and generating the missing ones from
// the texture coordinates (scene_loaders.h).
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "common/scene_loaders.h"

namespace pc::scene_detail {

namespace {

bool finite(glm::vec3 v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

// v / |v|, or zero where v is zero or not finite.
glm::vec3 unitOrZero(glm::vec3 v) {
  const float len = glm::length(v);
  return len > 0.0f && std::isfinite(len) ? v / len : glm::vec3(0.0f);
}

// A unit vector perpendicular to unit n (Duff et al. 2017, without a branch on the dominant
// axis): the tangent of a vertex whose coordinates give no direction.
glm::vec3 anyPerpendicular(glm::vec3 n) {
  const float sign = std::copysign(1.0f, n.z);
  const float a = -1.0f / (sign + n.z);
  return glm::vec3(1.0f + sign * n.x * n.x * a, sign * n.x * n.y * a, -sign * n.x);
}

// The angle at corner a of triangle (a, b, c); 0 where an edge has no length.
float cornerAngle(glm::vec3 a, glm::vec3 b, glm::vec3 c) {
  const glm::vec3 u = unitOrZero(b - a), w = unitOrZero(c - a);
  if (u == glm::vec3(0.0f) || w == glm::vec3(0.0f)) return 0.0f;
  return std::acos(std::clamp(glm::dot(u, w), -1.0f, 1.0f));
}

}  // namespace

bool tangentsUsable(Mesh& mesh) {
  if (mesh.tangents.size() != mesh.positions.size()) return false;
  for (glm::vec4& t : mesh.tangents) {
    const glm::vec3 unit = unitOrZero(glm::vec3(t));
    if (unit == glm::vec3(0.0f) || !std::isfinite(t.w)) return false;
    t = glm::vec4(unit, t.w < 0.0f ? -1.0f : 1.0f);
  }
  return true;
}

Status generateTangents(Mesh& mesh) {
  mesh.tangents.clear();
  const std::size_t nv = mesh.positions.size();
  const std::string where = "mesh '" + mesh.name + "': ";
  if (mesh.uvs.size() != nv || mesh.normals.size() != nv)
    return Error{where +
                 "has no texture coordinates to make tangents from; its material's normal map is "
                 "not applied"};
  // Per vertex, the angle-weighted sums of its triangles' unit directions of increasing u
  // (the tangent) and of decreasing v (the bitangent: the map's +y points up the image, and
  // glTF's v runs down it).
  std::vector<glm::vec3> tangentSum(nv, glm::vec3(0.0f)), bitangentSum(nv, glm::vec3(0.0f));
  std::size_t mapped = 0;
  for (std::size_t t = 0; t + 2 < mesh.indices.size(); t += 3) {
    const std::uint32_t i[3] = {mesh.indices[t], mesh.indices[t + 1], mesh.indices[t + 2]};
    const glm::vec3 p[3] = {mesh.positions[i[0]], mesh.positions[i[1]], mesh.positions[i[2]]};
    const glm::vec3 e1 = p[1] - p[0], e2 = p[2] - p[0];
    const glm::vec2 d1 = mesh.uvs[i[1]] - mesh.uvs[i[0]], d2 = mesh.uvs[i[2]] - mesh.uvs[i[0]];
    // Solving e = du T + dv B' for the two edges; a zero determinant (coordinates on a line
    // or a point) gives no directions, and the triangle adds nothing.
    const float det = d1.x * d2.y - d2.x * d1.y;
    if (!(std::abs(det) > 0.0f)) continue;
    const glm::vec3 tangent = unitOrZero((e1 * d2.y - e2 * d1.y) / det);
    const glm::vec3 bitangent = unitOrZero((e1 * d2.x - e2 * d1.x) / det);  // -dP/dv
    if (tangent == glm::vec3(0.0f) || bitangent == glm::vec3(0.0f)) continue;
    ++mapped;
    for (int k = 0; k < 3; ++k) {
      const float angle = cornerAngle(p[k], p[(k + 1) % 3], p[(k + 2) % 3]);
      tangentSum[i[k]] += angle * tangent;
      bitangentSum[i[k]] += angle * bitangent;
    }
  }
  if (mapped == 0)
    return Error{where +
                 "its texture coordinates are degenerate on every triangle, so no tangents can "
                 "be made; its material's normal map is not applied"};
  mesh.tangents.resize(nv);
  for (std::size_t v = 0; v < nv; ++v) {
    const glm::vec3 n = mesh.normals[v];
    glm::vec3 tangent = unitOrZero(tangentSum[v] - n * glm::dot(n, tangentSum[v]));
    if (tangent == glm::vec3(0.0f) || !finite(tangent)) tangent = anyPerpendicular(n);
    const float w = glm::dot(glm::cross(n, tangent), bitangentSum[v]) < 0.0f ? -1.0f : 1.0f;
    mesh.tangents[v] = glm::vec4(tangent, w);
  }
  return Status::success();
}

}  // namespace pc::scene_detail
