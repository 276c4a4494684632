// glTF features the loader reads past without using are named in the scene's warnings, once
// per feature with the materials that use it; a file that uses none of them gets none.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "common/scene.h"

namespace fs = std::filesystem;

namespace {

// A unit quad (4 positions, 6 uint16 indices) in a data: URI, so the file stands alone.
const char* kQuadBuffer =
    "data:application/octet-stream;base64,"
    "AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAACAPwAAgD8AAAAAAAAAAAAAgD8AAAAAAAABAAIAAAACAAMA";

// Two quads with materials `a` and `b`; `top` is spliced into the top-level object.
std::string twoMaterialGltf(const std::string& a, const std::string& b, const std::string& top) {
  return R"({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0, 1]}],
  "nodes": [{"mesh": 0}, {"mesh": 1}],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]},
             {"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 1}]}],
  "materials": [)" +
         a + ", " + b + R"(],
  "buffers": [{"uri": ")" +
         kQuadBuffer + R"(", "byteLength": 60}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48},
                  {"buffer": 0, "byteOffset": 48, "byteLength": 12}],
  "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                 "min": [0, 0, 0], "max": [1, 1, 0]},
                {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}])" +
         top + "}";
}

pc::Result<pc::Scene> loadText(const std::string& name, const std::string& gltf) {
  const fs::path dir = fs::temp_directory_path() / ("pc_test_gltf_unused_" + name);
  fs::create_directories(dir);
  std::ofstream(dir / "scene.gltf") << gltf;
  // A sky, so that the scene is lit and the only warnings are the ones under test.
  std::ofstream(dir / "sky.json") << R"({"sky": {"color": [0.2, 0.3, 0.4]}})";
  auto scene = pc::loadScene(dir / "scene.gltf", dir / "sky.json");
  fs::remove_all(dir);
  return scene;
}

// The warnings that mention `what`.
std::vector<std::string> mentioning(const pc::Scene& scene, const std::string& what) {
  std::vector<std::string> out;
  for (const std::string& w : scene.warnings)
    if (w.find(what) != std::string::npos) out.push_back(w);
  return out;
}

}  // namespace

TEST(GltfUnusedFeatures, EachIsNamedOnceWithTheMaterialsThatUseIt) {
  // Both materials have an occlusion texture, so that feature is one warning naming both; the other
  // features belong to one material each.
  const std::string a = R"({"name": "brass",
      "pbrMetallicRoughness": {"metallicFactor": 0.9, "roughnessFactor": 0.3,
                               "metallicRoughnessTexture": {"index": 0}},
      "occlusionTexture": {"index": 0},
      "extensions": {"KHR_materials_clearcoat": {"clearcoatFactor": 1}}})";
  const std::string b = R"({"name": "glass", "occlusionTexture": {"index": 0},
      "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1},
                     "KHR_materials_emissive_strength": {"emissiveStrength": 2}}})";
  const std::string top = R"(,
  "textures": [{"source": 0}],
  "images": [{"uri": "missing.png"}],
  "extensionsUsed": ["KHR_materials_clearcoat", "KHR_materials_transmission",
                     "KHR_materials_emissive_strength", "EXT_meshopt_compression"],
  "animations": [{"channels": [], "samplers": []}],
  "skins": [{"joints": [0]}])";
  auto scene = loadText("named", twoMaterialGltf(a, b, top));
  ASSERT_TRUE(scene.ok()) << scene.error().message;

  auto occlusion = mentioning(*scene, "occlusion texture");
  ASSERT_EQ(occlusion.size(), 1u);
  EXPECT_NE(occlusion[0].find("'brass', 'glass'"), std::string::npos) << occlusion[0];
  EXPECT_TRUE(mentioning(*scene, "normal map").empty());  // normal maps are read
  EXPECT_TRUE(mentioning(*scene, "metallic").empty());    // metallic-roughness is read
  auto clearcoat = mentioning(*scene, "KHR_materials_clearcoat");
  ASSERT_EQ(clearcoat.size(), 1u);  // the material's, not again as an extension used
  EXPECT_NE(clearcoat[0].find("'brass'"), std::string::npos) << clearcoat[0];
  auto transmission = mentioning(*scene, "KHR_materials_transmission");
  ASSERT_EQ(transmission.size(), 1u);
  EXPECT_NE(transmission[0].find("'glass'"), std::string::npos) << transmission[0];
  EXPECT_EQ(mentioning(*scene, "EXT_meshopt_compression").size(), 1u);
  EXPECT_TRUE(mentioning(*scene, "animations not read").empty());  // node animations are read
  EXPECT_EQ(mentioning(*scene, "skin(s) are not read").size(), 1u);
  // Emissive strength is honoured (it scales the emission): no warning.
  EXPECT_TRUE(mentioning(*scene, "emissive_strength").empty());
}

TEST(GltfUnusedFeatures, PlainMaterialsGiveNoWarning) {
  const std::string plain = R"({"name": "plain", "pbrMetallicRoughness":
      {"baseColorFactor": [0.5, 0.5, 0.5, 1]}, "emissiveFactor": [0, 0, 0]})";
  auto scene = loadText("plain", twoMaterialGltf(plain, plain, ""));
  ASSERT_TRUE(scene.ok()) << scene.error().message;
  for (const std::string& w : scene->warnings) ADD_FAILURE() << "unexpected warning: " << w;
}
