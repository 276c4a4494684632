#include "scene_contact.h"

#include "scene_loaders.h"

namespace pc {

namespace {

// A quad with its own flat normal, corners counter-clockwise seen from its front.
void addQuad(Mesh& m, glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 d) {
  const glm::vec3 n = glm::normalize(glm::cross(b - a, c - a));
  const auto base = std::uint32_t(m.positions.size());
  for (glm::vec3 p : {a, b, c, d}) {
    m.positions.push_back(p);
    m.normals.push_back(n);
  }
  m.uvs.insert(m.uvs.end(), {{0, 1}, {1, 1}, {1, 0}, {0, 0}});
  m.indices.insert(m.indices.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
}

// Axis-aligned box with front faces pointing out (a block) or in (a room).
void addBox(Mesh& m, glm::vec3 lo, glm::vec3 hi, bool inward) {
  const glm::vec3 c[8] = {{lo.x, lo.y, lo.z}, {hi.x, lo.y, lo.z}, {hi.x, hi.y, lo.z},
                          {lo.x, hi.y, lo.z}, {lo.x, lo.y, hi.z}, {hi.x, lo.y, hi.z},
                          {hi.x, hi.y, hi.z}, {lo.x, hi.y, hi.z}};
  // Outward counter-clockwise corner orders for -z, +z, -x, +x, -y, +y.
  const int faces[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 4, 7, 3},
                           {1, 2, 6, 5}, {0, 1, 5, 4}, {3, 7, 6, 2}};
  for (const auto& f : faces) {
    if (inward)
      addQuad(m, c[f[0]], c[f[3]], c[f[2]], c[f[1]]);
    else
      addQuad(m, c[f[0]], c[f[1]], c[f[2]], c[f[3]]);
  }
}

}  // namespace

Scene contactScene() {
  Scene s;
  s.name = "contact-block";
  s.materials = {{.name = "white", .baseColor = {0.7f, 0.7f, 0.7f}}};
  // A 4 x 2.5 x 4 room: closed, so the light has one well-defined answer.
  Mesh room{.name = "room", .material = 0};
  addBox(room, {-2.0f, 0.0f, -2.0f}, {2.0f, 2.5f, 2.0f}, true);
  Mesh block{.name = "block", .material = 0};
  addBox(block, kContactBlockLo, kContactBlockHi, false);
  s.meshes = {room, block};
  s.instances = {{.name = "room", .mesh = 0}, {.name = "block", .mesh = 1}};
  // A spot in a corner aimed at the ceiling: the floor and the block get bounced light only,
  // which is what the field carries, so the contact shows the field's error alone.
  s.lights.push_back({.name = "uplight",
                      .type = LightType::Spot,
                      .position = {1.4f, 1.0f, -1.4f},
                      .direction = {0.0f, 1.0f, 0.0f},
                      .color = {1.0f, 1.0f, 1.0f},
                      .intensity = 20.0f,
                      .outerConeAngle = 0.7f});
  s.cameras.push_back({.name = "above",
                       .position = {0.0f, 1.9f, 1.9f},
                       .forward = glm::normalize(glm::vec3(0.0f, -1.5f, -1.9f)),
                       .up = {0.0f, 1.0f, 0.0f},
                       .yfov = glm::radians(60.0f)});
  // Probes half a metre apart, a quarter in from the walls: a spacing a user would pick for
  // a room this size, and coarse next to the contact.
  s.volumes = {
      {.origin = glm::vec3(-1.75f, 0.25f, -1.75f), .spacing = 0.5f, .counts = glm::ivec3(8, 5, 8)}};
  s.exposure = 1.0f;
  (void)scene_detail::computeBounds(s);  // cannot fail: every vertex is a small constant
  s.hash = scene_detail::hashScene(s);
  return s;
}

std::array<std::array<glm::vec3, 2>, 4> contactSceneEdges() {
  const glm::vec3 lo = kContactBlockLo, hi = kContactBlockHi;
  const glm::vec3 a{lo.x, 0.0f, lo.z}, b{hi.x, 0.0f, lo.z}, c{hi.x, 0.0f, hi.z},
      d{lo.x, 0.0f, hi.z};
  return {{{a, b}, {b, c}, {c, d}, {d, a}}};
}

}  // namespace pc
