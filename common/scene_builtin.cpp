// The built-in scene: a closed Cornell-style room, 2 x 2 x 2 units, with a point light
// circling under the ceiling and a slowly turning block. Needs no files, so tests and demos
// always have something to light.
#include <glm/gtc/matrix_transform.hpp>

#include "common/scene.h"
#include "common/scene_loaders.h"

namespace pc {

namespace {

// An axis-aligned quad with its own normal (flat shading; no shared vertices between walls).
void addQuad(Mesh& m, glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 d) {
  glm::vec3 n = glm::normalize(glm::cross(b - a, c - a));
  auto base = std::uint32_t(m.positions.size());
  for (glm::vec3 p : {a, b, c, d}) {
    m.positions.push_back(p);
    m.normals.push_back(n);
  }
  m.uvs.insert(m.uvs.end(), {{0, 1}, {1, 1}, {1, 0}, {0, 0}});
  m.indices.insert(m.indices.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
}

// Unit cube centred on the origin, faces pointing out.
Mesh cube(const std::string& name, int material) {
  Mesh m;
  m.name = name;
  m.material = material;
  const float h = 0.5f;
  // Each face: four corners counter-clockwise seen from outside.
  addQuad(m, {-h, -h, h}, {h, -h, h}, {h, h, h}, {-h, h, h});      // +Z
  addQuad(m, {h, -h, -h}, {-h, -h, -h}, {-h, h, -h}, {h, h, -h});  // -Z
  addQuad(m, {h, -h, h}, {h, -h, -h}, {h, h, -h}, {h, h, h});      // +X
  addQuad(m, {-h, -h, -h}, {-h, -h, h}, {-h, h, h}, {-h, h, -h});  // -X
  addQuad(m, {-h, h, h}, {h, h, h}, {h, h, -h}, {-h, h, -h});      // +Y
  addQuad(m, {-h, -h, -h}, {h, -h, -h}, {h, -h, h}, {-h, -h, h});  // -Y
  return m;
}

}  // namespace

Scene builtinScene() {
  Scene s;
  s.name = "builtin-cornell";
  // Albedos of the measured Cornell box.
  s.materials = {
      {.name = "white", .baseColor = {0.725f, 0.71f, 0.68f}},
      {.name = "red", .baseColor = {0.63f, 0.065f, 0.05f}},
      {.name = "green", .baseColor = {0.14f, 0.45f, 0.091f}},
  };
  const float x0 = -1, x1 = 1, y0 = 0, y1 = 2, z0 = -1, z1 = 1;
  // Walls face into the room. The front wall closes it (the camera is inside), so no light
  // escapes and GI converges to a well-defined answer.
  Mesh white{.name = "room-white", .material = 0};
  addQuad(white, {x0, y0, z1}, {x1, y0, z1}, {x1, y0, z0}, {x0, y0, z0});  // floor
  addQuad(white, {x0, y1, z0}, {x1, y1, z0}, {x1, y1, z1}, {x0, y1, z1});  // ceiling
  addQuad(white, {x0, y0, z0}, {x1, y0, z0}, {x1, y1, z0}, {x0, y1, z0});  // back
  addQuad(white, {x1, y0, z1}, {x0, y0, z1}, {x0, y1, z1}, {x1, y1, z1});  // front
  Mesh red{.name = "room-red", .material = 1};
  addQuad(red, {x0, y0, z1}, {x0, y0, z0}, {x0, y1, z0}, {x0, y1, z1});  // left (x = -1)
  Mesh green{.name = "room-green", .material = 2};
  addQuad(green, {x1, y0, z0}, {x1, y0, z1}, {x1, y1, z1}, {x1, y1, z0});  // right (x = +1)
  s.meshes = {white, red, green, cube("block", 0)};

  s.instances = {{.name = "room-white", .mesh = 0},
                 {.name = "room-red", .mesh = 1},
                 {.name = "room-green", .mesh = 2}};
  // Tall block, fixed, turned a little as in the classic box.
  glm::mat4 tall = glm::translate(glm::mat4(1.0f), {-0.35f, 0.6f, -0.35f});
  tall = glm::rotate(tall, glm::radians(17.0f), {0, 1, 0});
  s.instances.push_back(
      {.name = "tall-block", .mesh = 3, .transform = glm::scale(tall, {0.6f, 1.2f, 0.6f})});
  // Short block, turning slowly about its own vertical axis.
  glm::mat4 shortB = glm::translate(glm::mat4(1.0f), {0.45f, 0.3f, 0.35f});
  shortB = glm::rotate(shortB, glm::radians(-18.0f), {0, 1, 0});
  s.instances.push_back({.name = "short-block",
                         .mesh = 3,
                         .transform = glm::scale(shortB, {0.6f, 0.6f, 0.6f}),
                         .animation = 1});

  // Point light below the ceiling on a square loop; 3 W/sr gives the floor an irradiance
  // near 1.3, well exposed at exposure 1.
  s.lights.push_back({.name = "ceiling-light",
                      .type = LightType::Point,
                      .position = {-0.5f, 1.5f, -0.5f},
                      .color = {1.0f, 0.95f, 0.85f},
                      .intensity = 3.0f,
                      .animation = 0});
  Animation path;
  path.kind = Animation::Kind::Path;
  path.points = {
      {-0.5f, 1.5f, -0.5f}, {0.5f, 1.5f, -0.5f}, {0.5f, 1.5f, 0.5f}, {-0.5f, 1.5f, 0.5f}};
  path.period = 8.0f;
  Animation spin;
  spin.kind = Animation::Kind::Rotate;
  spin.axis = {0, 1, 0};
  spin.pivot = {0.45f, 0.3f, 0.35f};
  spin.radiansPerSecond = 0.3f;
  s.animations = {path, spin};

  // Inside, 0.1 in front of the front wall, seeing the whole back wall.
  s.cameras.push_back({.name = "front",
                       .position = {0.0f, 1.0f, 0.9f},
                       .forward = {0.0f, 0.0f, -1.0f},
                       .up = {0.0f, 1.0f, 0.0f},
                       .yfov = glm::radians(60.0f)});

  // Two cascades, probes half a spacing in from the walls.
  s.volumes = {
      {.origin = glm::vec3(-0.875f, 0.125f, -0.875f), .spacing = 0.25f, .counts = glm::ivec3(8)},
      {.origin = glm::vec3(-0.75f, 0.25f, -0.75f), .spacing = 0.5f, .counts = glm::ivec3(4)}};
  s.exposure = 1.0f;
  (void)scene_detail::computeBounds(s);  // cannot fail: every vertex is a small constant
  s.hash = scene_detail::hashScene(s);
  return s;
}

}  // namespace pc
