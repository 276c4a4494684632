// A small normal-mapped glTF scene written by the normal map tests: a 2 x 2 quad in the XY
// plane facing +Z (texture coordinates as glTF lays them out: u along +X, v down the image,
// so down -Y), a uniform 2 x 2 normal map, a directional light arriving from (1, 1, 1) and a
// camera on the +Z axis that sees nothing but the quad. The texel picks the tilt: (128, 128,
// 255) is flat, a larger red leans the normal toward +X (the tangent), a larger green toward
// +Y (the bitangent). The quad is a diffuse dielectric (metallic 0; glTF's default is 1).
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <glm/glm.hpp>
#include <string>
#include <vector>

#include "common/image.h"
#include "common/scene.h"

namespace pc::test {

struct NormalMapQuad {
  bool normalMap = true;                             // false: the material has no normalTexture
  std::array<std::uint8_t, 3> texel{128, 128, 255};  // the map's one colour
  bool tangents = true;        // write a TANGENT attribute (+X, handedness +1)
  bool uvs = true;             // write TEXCOORD_0
  bool mirrorU = false;        // u runs along -X (a mirrored mapping)
  int normalTextureIndex = 0;  // the material's normalTexture.index
  float scale = 1.0f;          // its scale
};

// One map a test renders: a name for its output, the map's colour, whether the file gives
// tangents (else they are generated).
struct NormalMapCase {
  const char* name;
  std::array<std::uint8_t, 3> texel;
  bool tangents;
};

// Where the light comes from (unit): the direction toward it.
inline glm::vec3 normalMapQuadToLight() { return glm::normalize(glm::vec3(1.0f, 1.0f, 1.0f)); }

// The cosine between the light and the normal that `texel` holds on the quad (tangent +X,
// bitangent +Y, normal +Z), decoded as the renderers decode it (linear, x 2 - 1, unit).
inline float normalMapQuadCosine(std::array<std::uint8_t, 3> texel) {
  const glm::vec3 m =
      glm::normalize(glm::vec3(texel[0], texel[1], texel[2]) / 255.0f * 2.0f - glm::vec3(1.0f));
  return glm::dot(m, normalMapQuadToLight());
}

// Writes quad.gltf, quad.bin and normal.png into `dir` (created) and returns the .gltf path.
inline std::filesystem::path writeNormalMapQuad(const std::filesystem::path& dir,
                                                const NormalMapQuad& q) {
  std::filesystem::create_directories(dir);
  const float positions[12] = {-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0};
  const float normals[12] = {0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1};
  float uvs[8] = {0, 1, 1, 1, 1, 0, 0, 0};
  if (q.mirrorU)
    for (int i = 0; i < 8; i += 2) uvs[i] = 1.0f - uvs[i];
  const float tangents[16] = {1, 0, 0, 1, 1, 0, 0, 1, 1, 0, 0, 1, 1, 0, 0, 1};
  const std::uint16_t indices[6] = {0, 1, 2, 0, 2, 3};
  std::vector<unsigned char> bin(204);
  std::memcpy(bin.data(), positions, 48);
  std::memcpy(bin.data() + 48, normals, 48);
  std::memcpy(bin.data() + 96, uvs, 32);
  std::memcpy(bin.data() + 128, tangents, 64);
  std::memcpy(bin.data() + 192, indices, 12);
  std::ofstream(dir / "quad.bin", std::ios::binary)
      .write(reinterpret_cast<const char*>(bin.data()), std::streamsize(bin.size()));

  Image8 map;
  map.width = map.height = 2;
  for (int i = 0; i < 4; ++i) map.rgb.insert(map.rgb.end(), q.texel.begin(), q.texel.end());
  (void)writePng(dir / "normal.png", map);

  // The light node's rotation takes its -Z onto the direction the light travels.
  const glm::vec3 from(0.0f, 0.0f, -1.0f), to = -normalMapQuadToLight();
  const glm::vec3 axis = glm::normalize(glm::cross(from, to));
  const float half = 0.5f * std::acos(glm::dot(from, to));
  const glm::vec4 rotation(axis * std::sin(half), std::cos(half));

  std::string attributes = R"("POSITION": 0, "NORMAL": 1)";
  if (q.uvs) attributes += R"(, "TEXCOORD_0": 2)";
  if (q.tangents) attributes += R"(, "TANGENT": 3)";
  const std::string normalTexture =
      q.normalMap ? R"(, "normalTexture": {"index": )" + std::to_string(q.normalTextureIndex) +
                        R"(, "texCoord": 0, "scale": )" + std::to_string(q.scale) + "}"
                  : std::string();
  std::ofstream(dir / "quad.gltf")
      << R"({
  "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0, 1, 2]}],
  "extensionsUsed": ["KHR_lights_punctual"],
  "extensions": {"KHR_lights_punctual": {"lights": [
    {"name": "sun", "type": "directional", "intensity": 2.0}]}},
  "nodes": [{"name": "quad", "mesh": 0},
            {"name": "sun", "rotation": [)"
      << rotation.x << ", " << rotation.y << ", " << rotation.z << ", " << rotation.w << R"(],
             "extensions": {"KHR_lights_punctual": {"light": 0}}},
            {"name": "eye", "translation": [0, 0, 3], "camera": 0}],
  "cameras": [{"type": "perspective", "perspective": {"yfov": 0.5, "znear": 0.1}}],
  "meshes": [{"name": "quad", "primitives": [{"attributes": {)"
      << attributes << R"(}, "indices": 4, "material": 0}]}],
  "materials": [{"name": "bumpy", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1],
                                                  "metallicFactor": 0})"
      << normalTexture << R"(}],
  "images": [{"uri": "normal.png"}], "textures": [{"source": 0}],
  "buffers": [{"uri": "quad.bin", "byteLength": 204}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48},
                  {"buffer": 0, "byteOffset": 48, "byteLength": 48},
                  {"buffer": 0, "byteOffset": 96, "byteLength": 32},
                  {"buffer": 0, "byteOffset": 128, "byteLength": 64},
                  {"buffer": 0, "byteOffset": 192, "byteLength": 12}],
  "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                 "min": [-1, -1, 0], "max": [1, 1, 0]},
                {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"},
                {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2"},
                {"bufferView": 3, "componentType": 5126, "count": 4, "type": "VEC4"},
                {"bufferView": 4, "componentType": 5123, "count": 6, "type": "SCALAR"}]
}
)";
  // An explicit empty sidecar keeps the project's data/sidecars out of the scene.
  std::ofstream(dir / "empty.json") << "{}";
  return dir / "quad.gltf";
}

// The normal map tests' scene loaded (with the empty sidecar beside it).
inline Result<Scene> loadNormalMapQuad(const std::filesystem::path& dir, const NormalMapQuad& q) {
  return loadScene(writeNormalMapQuad(dir, q), dir / "empty.json");
}

// Mean of an image's channels.
inline double meanRadiance(const Image& image) {
  double sum = 0.0;
  for (const glm::vec3& p : image.pixels) sum += double(p.x) + p.y + p.z;
  return image.pixels.empty() ? 0.0 : sum / (3.0 * double(image.pixels.size()));
}

}  // namespace pc::test
