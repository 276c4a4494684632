#include <cstdio>

#include "scene.h"

namespace pc {

// Six inward-facing walls of one material: every point sees only walls, so the radiance
// everywhere is Le / (1 - a) and the irradiance pi Le / (1 - a).
Scene furnaceBox(float albedo, float emission, float size) {
  Scene s;
  char name[64];
  std::snprintf(name, sizeof name, "furnace-box a=%.3f Le=%.3f", albedo, emission);
  s.name = name;
  Material m;
  m.name = "wall";
  m.baseColor = glm::vec3(albedo);
  m.emissive = glm::vec3(emission);
  s.materials.push_back(m);
  Mesh mesh;
  mesh.name = "box";
  const float L = size;
  // Each face: corner, two edges whose cross product points into the box (front side).
  struct Face {
    glm::vec3 o, u, v;
  };
  const Face faces[6] = {
      {{0, 0, 0}, {0, 0, L}, {L, 0, 0}},  // floor, normal +y
      {{0, L, 0}, {L, 0, 0}, {0, 0, L}},  // ceiling, normal -y
      {{0, 0, 0}, {0, L, 0}, {0, 0, L}},  // x = 0, normal +x
      {{L, 0, 0}, {0, 0, L}, {0, L, 0}},  // x = L, normal -x
      {{0, 0, 0}, {L, 0, 0}, {0, L, 0}},  // z = 0, normal +z
      {{0, 0, L}, {0, L, 0}, {L, 0, 0}},  // z = L, normal -z
  };
  for (const Face& f : faces) {
    auto base = std::uint32_t(mesh.positions.size());
    glm::vec3 n = glm::normalize(glm::cross(f.u, f.v));
    for (glm::vec3 p : {f.o, f.o + f.u, f.o + f.u + f.v, f.o + f.v}) {
      mesh.positions.push_back(p);
      mesh.normals.push_back(n);
      mesh.uvs.push_back(glm::vec2(0.0f));
    }
    for (std::uint32_t i : {0u, 1u, 2u, 0u, 2u, 3u}) mesh.indices.push_back(base + i);
  }
  s.meshes.push_back(std::move(mesh));
  s.instances.push_back(Instance{});
  s.emissiveMode = EmissiveMode::Field;
  // 4 x 4 x 4 probes, one spacing in from each wall.
  s.volumes.push_back(ProbeVolume{glm::vec3(L / 5.0f), L / 5.0f, glm::ivec3(4)});
  Camera cam;
  cam.position = glm::vec3(L / 2, L / 2, L * 0.9f);
  cam.forward = glm::vec3(0, 0, -1);
  s.cameras.push_back(cam);
  s.boundsMin = glm::vec3(0.0f);
  s.boundsMax = glm::vec3(L);
  s.hash = 0xF0A7ACE000000000ull ^ (std::uint64_t(albedo * 1000.0f) << 16) ^
           std::uint64_t(emission * 1000.0f);
  return s;
}

}  // namespace pc
