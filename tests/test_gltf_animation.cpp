// glTF node animations read as scene animation: linear, step and cubic-spline tracks on a
// node hierarchy, looping, the sidecar's unit scale, lights under animated nodes, and the
// errors a malformed animation gets.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <glm/glm.hpp>
#include <string>
#include <vector>

#include "common/scene.h"

namespace fs = std::filesystem;

namespace {

class TempDir {
 public:
  TempDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = fs::temp_directory_path() / ("pc_test_gltf_animation_" + std::string(info->name()));
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempDir() { fs::remove_all(path_); }
  fs::path operator/(const std::string& name) const { return path_ / name; }

 private:
  fs::path path_;
};

void writeFile(const fs::path& p, const std::string& text) {
  std::ofstream(p, std::ios::binary) << text;
}

// The buffer: a triangle, its indices, then the animation keys (offsets in the JSON below).
std::vector<unsigned char> animationBuffer() {
  std::vector<unsigned char> b;
  const auto floats = [&](std::initializer_list<float> v) {
    for (float f : v) {
      unsigned char bytes[4];
      std::memcpy(bytes, &f, 4);
      b.insert(b.end(), bytes, bytes + 4);
    }
  };
  floats({0, 0, 0, 1, 0, 0, 0, 0, 1});          // 0: positions
  b.insert(b.end(), {0, 0, 1, 0, 2, 0, 0, 0});  // 36: indices and padding
  floats({0, 2});                               // 44: key times 0 and 2 s
  floats({0, 0, 0, 4, 0, 0});                   // 52: translations
  const float h = std::sqrt(0.5f);
  floats({0, 0, 0, 1, 0, h, 0, h});  // 76: rotations, identity then 90 degrees about +Y
  floats({0, 1});                    // 108: key times 0 and 1 s
  floats({0, 0, 0, 1, 1, 1, 0, 0, 0, 0, 0, 0, 3, 3, 3, 0, 0, 0});  // 116: cubic scale keys
  return b;
}

// `times` replaces the first key-time accessor's view (to make bad files).
std::string animationGltf(const std::string& firstTimesView = "2") {
  return R"({
  "asset": {"version": "2.0"},
  "extensionsUsed": ["KHR_lights_punctual"],
  "extensions": {"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 5}]}},
  "scene": 0,
  "scenes": [{"nodes": [0, 3, 4]}],
  "nodes": [
    {"name": "parent", "children": [1, 2]},
    {"name": "child", "mesh": 0, "translation": [0, 1, 0]},
    {"name": "lamp", "translation": [0, 0, 1], "extensions": {"KHR_lights_punctual": {"light": 0}}},
    {"name": "grower", "mesh": 0},
    {"name": "still", "mesh": 0, "translation": [5, 0, 0]}],
  "meshes": [{"name": "tri", "primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
  "buffers": [{"uri": "anim.bin", "byteLength": 188}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                  {"buffer": 0, "byteOffset": 36, "byteLength": 6},
                  {"buffer": 0, "byteOffset": 44, "byteLength": 8},
                  {"buffer": 0, "byteOffset": 52, "byteLength": 24},
                  {"buffer": 0, "byteOffset": 76, "byteLength": 32},
                  {"buffer": 0, "byteOffset": 108, "byteLength": 8},
                  {"buffer": 0, "byteOffset": 116, "byteLength": 72},
                  {"buffer": 0, "byteOffset": 48, "byteLength": 8}],
  "accessors": [
    {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
     "min": [0, 0, 0], "max": [1, 0, 1]},
    {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"},
    {"bufferView": )" +
         firstTimesView + R"(, "componentType": 5126, "count": 2, "type": "SCALAR"},
    {"bufferView": 3, "componentType": 5126, "count": 2, "type": "VEC3"},
    {"bufferView": 4, "componentType": 5126, "count": 2, "type": "VEC4"},
    {"bufferView": 5, "componentType": 5126, "count": 2, "type": "SCALAR"},
    {"bufferView": 6, "componentType": 5126, "count": 6, "type": "VEC3"}],
  "animations": [
    {"name": "move",
     "samplers": [{"input": 2, "output": 3},
                  {"input": 5, "output": 4, "interpolation": "STEP"}],
     "channels": [{"sampler": 0, "target": {"node": 0, "path": "translation"}},
                  {"sampler": 1, "target": {"node": 1, "path": "rotation"}}]},
    {"name": "grow",
     "samplers": [{"input": 2, "output": 6, "interpolation": "CUBICSPLINE"}],
     "channels": [{"sampler": 0, "target": {"node": 3, "path": "scale"}}]}]
}
)";
}

pc::Result<pc::Scene> load(const TempDir& dir, const std::string& gltf,
                           const std::string& sidecar = "{}") {
  const std::vector<unsigned char> bin = animationBuffer();
  std::ofstream(dir / "anim.bin", std::ios::binary)
      .write(reinterpret_cast<const char*>(bin.data()), std::streamsize(bin.size()));
  writeFile(dir / "anim.gltf", gltf);
  writeFile(dir / "anim.json", sidecar);
  return pc::loadScene(dir / "anim.gltf", dir / "anim.json");
}

int instanceNamed(const pc::Scene& s, const std::string& name) {
  for (std::size_t i = 0; i < s.instances.size(); ++i)
    if (s.instances[i].name == name) return int(i);
  return -1;
}

glm::vec3 apply(const glm::mat4& m, glm::vec3 p) { return glm::vec3(m * glm::vec4(p, 1.0f)); }

void expectNear(glm::vec3 a, glm::vec3 b) {
  EXPECT_NEAR(a.x, b.x, 1e-4f);
  EXPECT_NEAR(a.y, b.y, 1e-4f);
  EXPECT_NEAR(a.z, b.z, 1e-4f);
}

}  // namespace

TEST(GltfAnimation, NodeTracksMoveInstancesAndLightsThroughTheHierarchy) {
  TempDir dir;
  auto scene = load(dir, animationGltf());
  ASSERT_TRUE(scene.ok()) << scene.error().message;
  const int child = instanceNamed(*scene, "child"), grower = instanceNamed(*scene, "grower"),
            still = instanceNamed(*scene, "still");
  ASSERT_GE(child, 0);
  ASSERT_GE(grower, 0);
  ASSERT_GE(still, 0);
  EXPECT_GE(scene->instances[std::size_t(child)].animation, 0);
  EXPECT_GE(scene->instances[std::size_t(grower)].animation, 0);
  EXPECT_EQ(scene->instances[std::size_t(still)].animation, -1);
  ASSERT_EQ(scene->lights.size(), 1u);
  EXPECT_GE(scene->lights[0].animation, 0);

  // t = 0.5: the parent is a quarter of the way to (4, 0, 0); the child's step rotation still
  // holds its first key (identity).
  pc::SceneState half = pc::evaluateScene(*scene, 0.5);
  expectNear(apply(half.instanceTransforms[std::size_t(child)], {1, 0, 0}), {2, 1, 0});
  // Cubic spline with zero tangents: 1 + 2 * smoothstep(0.25) = 1.3125.
  expectNear(apply(half.instanceTransforms[std::size_t(grower)], {1, 0, 0}), {1.3125f, 0, 0});
  expectNear(half.lights[0].position, {1, 0, 1});

  // t = 1: the parent halfway; the step rotation at its second key turns +X to -Z.
  pc::SceneState one = pc::evaluateScene(*scene, 1.0);
  expectNear(apply(one.instanceTransforms[std::size_t(child)], {1, 0, 0}), {2, 1, -1});
  expectNear(one.lights[0].position, {2, 0, 1});
  expectNear(apply(one.instanceTransforms[std::size_t(still)], {0, 0, 0}), {5, 0, 0});

  // The animations loop on their length (2 s): t = 3 is t = 1.
  pc::SceneState three = pc::evaluateScene(*scene, 3.0);
  expectNear(apply(three.instanceTransforms[std::size_t(child)], {1, 0, 0}), {2, 1, -1});
  expectNear(apply(three.instanceTransforms[std::size_t(grower)], {1, 0, 0}), {2, 0, 0});
}

TEST(GltfAnimation, SidecarUnitScaleAppliesToTheMovingNodes) {
  TempDir dir;
  auto scene = load(dir, animationGltf(), R"({"unit_scale": 2})");
  ASSERT_TRUE(scene.ok()) << scene.error().message;
  const int child = instanceNamed(*scene, "child");
  ASSERT_GE(child, 0);
  pc::SceneState one = pc::evaluateScene(*scene, 1.0);
  expectNear(apply(one.instanceTransforms[std::size_t(child)], {1, 0, 0}), {4, 2, -2});
  expectNear(one.lights[0].position, {4, 0, 2});
  // Animated scenes hash by their keys: another clip is another scene.
  auto other = load(dir, [] {
    std::string g = animationGltf();
    g.replace(g.find("\"interpolation\": \"STEP\""), 23, "\"interpolation\": \"LINEAR\"");
    return g;
  }());
  ASSERT_TRUE(other.ok()) << other.error().message;
  auto same = load(dir, animationGltf());
  ASSERT_TRUE(same.ok()) << same.error().message;
  EXPECT_NE(other->hash, same->hash);
}

TEST(GltfAnimation, MalformedAnimationsAreErrorsNamingTheAnimation) {
  TempDir dir;
  // Key times 2 then 4 read from offset 48 are (2, 0): decreasing.
  auto decreasing = load(dir, animationGltf("7"));
  ASSERT_FALSE(decreasing.ok());
  EXPECT_NE(decreasing.error().message.find("animation 'move'"), std::string::npos)
      << decreasing.error().message;
  EXPECT_NE(decreasing.error().message.find("increasing"), std::string::npos)
      << decreasing.error().message;

  std::string badSampler = animationGltf();
  badSampler.replace(badSampler.find("{\"sampler\": 1,"), 14, "{\"sampler\": 9,");
  auto sampler = load(dir, badSampler);
  ASSERT_FALSE(sampler.ok());
  EXPECT_NE(sampler.error().message.find("animation sampler index 9"), std::string::npos)
      << sampler.error().message;

  std::string unknown = animationGltf();
  unknown.replace(unknown.find("\"STEP\""), 6, "\"BOUNCY\"");
  auto interpolation = load(dir, unknown);
  ASSERT_FALSE(interpolation.ok());
  EXPECT_NE(interpolation.error().message.find("unknown interpolation 'BOUNCY'"), std::string::npos)
      << interpolation.error().message;
}
