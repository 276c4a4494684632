// Geometry built in code for the tests: quads and axis-aligned boxes with flat normals.
#pragma once

#include <cstdint>
#include <glm/glm.hpp>
#include <initializer_list>
#include <vector>

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

// The built-in room with a cut-out grille under the light: a quad across the room at y = 1.2
// whose alpha is a checker of 1-texel cells (uv repeating 3 times across), so that about half
// of the light reaches the floor through it. `cutOut` false: the same grille, opaque. `wrapU`
// and `wrapV`: the grille texture's wrap modes.
inline Scene grilleRoom(bool cutOut, TextureWrap wrapU = TextureWrap::Repeat,
                        TextureWrap wrapV = TextureWrap::Repeat) {
  Scene scene = builtinScene();
  Texture checker;
  checker.name = "grille";
  checker.width = checker.height = 8;
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 8; ++x)
      checker.rgba.insert(checker.rgba.end(), {200, 200, 200, std::uint8_t((x + y) % 2 ? 255 : 0)});
  checker.wrapU = wrapU;
  checker.wrapV = wrapV;
  scene.textures.push_back(checker);
  Material grille{.name = "grille", .baseColor = glm::vec3(0.6f)};
  if (cutOut) {
    // Not 0.5: between a 0 and a 1 texel bilinear alpha is exactly 0.5 along whole lines,
    // where the CPU's float and the GPU sampler's fixed-point weights round either way.
    grille.alphaCutoff = 0.4f;
    grille.alphaTexture = int(scene.textures.size()) - 1;
  }
  scene.materials.push_back(grille);
  // Two faces back to back, 0.01 apart, so that probes on either side see fronts (backfaces
  // would mark the probes below as inside geometry). Neither is coplanar with the tall block's
  // top (y = 1.2, between them): rays reaching coplanar faces at one distance pick either, and
  // the backends break such ties differently.
  Mesh quad{.name = "grille", .material = int(scene.materials.size()) - 1};
  const float h = 0.9f;
  for (float y : {1.205f, 1.195f}) {
    const float up = y > 1.2f ? 1.0f : -1.0f;
    const auto base = std::uint32_t(quad.positions.size());
    const glm::vec3 corners[4] = {{-h, y, h}, {h, y, h}, {h, y, -h}, {-h, y, -h}};
    for (glm::vec3 c : corners) {
      quad.positions.push_back(c);
      quad.normals.push_back({0, up, 0});
      quad.uvs.push_back(glm::vec2(c.x + h, c.z + h) / (2.0f * h) * 3.0f);
    }
    if (up > 0)
      quad.indices.insert(quad.indices.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
    else
      quad.indices.insert(quad.indices.end(), {base, base + 2, base + 1, base, base + 3, base + 2});
  }
  scene.meshes.push_back(quad);
  scene.instances.push_back({.name = "grille", .mesh = int(scene.meshes.size()) - 1});
  return scene;
}

// cardRoom's cards: how many, and the plane of card i. Off the probe planes (z = -0.875 +
// 0.25 k, -0.75 + 0.5 k) by 0.025 at least, so that no probe sits on a card's plane.
constexpr int cardRoomCards = 9;
inline float cardRoomCardZ(int i) { return -0.69f + 0.13f * float(i); }

// The built-in room, its blocks taken out, with a thicket of one-sided cards standing in it, like a
// bush of leaf cards: 9 vertical quads at z = -0.69 .. 0.35 (0.13 apart, closer than the fine
// cascade's 0.25 spacing, so the probes among them stand between two cards), each facing +z (the
// camera) only. `cutOut`: the cards are leaf-like cut-outs (a checker of 1-texel cells, about half
// open); else opaque. A probe between opaque one-sided cards sees their backs along +z and is
// classed inside geometry; between cut-out cards it must not be (pcBackfaceIsSurface).
inline Scene cardRoom(bool cutOut) {
  Scene scene = builtinScene();
  Texture checker;
  checker.name = "leaf";
  checker.width = checker.height = 8;
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 8; ++x)
      checker.rgba.insert(checker.rgba.end(), {90, 160, 70, std::uint8_t((x + y) % 2 ? 255 : 0)});
  scene.textures.push_back(checker);
  Material leaf{.name = "leaf", .baseColor = glm::vec3(0.5f, 0.7f, 0.4f)};
  if (cutOut) {
    leaf.alphaCutoff = 0.4f;  // not 0.5: see grilleRoom
    leaf.alphaTexture = int(scene.textures.size()) - 1;
  }
  scene.materials.push_back(leaf);
  Mesh cards{.name = "cards", .material = int(scene.materials.size()) - 1};
  for (int i = 0; i < cardRoomCards; ++i) {
    const float z = cardRoomCardZ(i);
    const auto base = std::uint32_t(cards.positions.size());
    // Counter-clockwise seen from +z: the front faces +z.
    const glm::vec3 corners[4] = {
        {-0.7f, 0.1f, z}, {0.7f, 0.1f, z}, {0.7f, 1.5f, z}, {-0.7f, 1.5f, z}};
    for (glm::vec3 c : corners) {
      cards.positions.push_back(c);
      cards.normals.push_back({0, 0, 1});
      cards.uvs.push_back(glm::vec2(c.x + 0.7f, c.y - 0.1f) * (3.0f / 1.4f));
    }
    cards.indices.insert(cards.indices.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
  }
  scene.meshes.push_back(cards);
  scene.instances.push_back({.name = "cards", .mesh = int(scene.meshes.size()) - 1});
  // The blocks go: they would stand among the cards (the short one turning through them).
  std::erase_if(scene.instances, [](const Instance& i) { return i.name.ends_with("-block"); });
  return scene;
}

// The built-in room, still (no animation), moved `shift` along x and z with its lights, probe
// volumes and cameras: the same room where float steps are larger.
inline Scene shiftedRoom(float shift) {
  Scene scene = builtinScene();
  const glm::vec3 by(shift, 0.0f, shift);
  for (Instance& inst : scene.instances) {
    inst.transform[3] += glm::vec4(by, 0.0f);  // a translation after the instance's own
    inst.animation = -1;
  }
  for (Light& light : scene.lights) {
    light.position += by;
    light.animation = -1;
  }
  for (ProbeVolume& v : scene.volumes) v.origin += by;
  for (Camera& c : scene.cameras) c.position += by;
  scene.animations.clear();
  return scene;
}

}  // namespace pc::testmesh
