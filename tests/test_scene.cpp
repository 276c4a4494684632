// Scene loading: the built-in room, small generated glTF/OBJ files (features and broken
// files), sidecars, animation, and the shared scenes where ../shared/scenes is present.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <glm/gtc/matrix_transform.hpp>
#include <limits>
#include <string>
#include <vector>

#include "common/data_folders.h"
#include "common/scene.h"
#include "common/scene_loaders.h"

namespace fs = std::filesystem;
using pc::Scene;

namespace {

// A fresh directory per test, removed afterwards.
class TempDir {
 public:
  TempDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = fs::temp_directory_path() /
            ("pc_test_scene_" + std::string(info->test_suite_name()) + "_" + info->name());
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempDir() { fs::remove_all(path_); }
  fs::path operator/(const std::string& name) const { return path_ / name; }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

void writeFile(const fs::path& p, const std::string& text) {
  std::ofstream(p, std::ios::binary) << text;
}

void writeBytes(const fs::path& p, const std::vector<unsigned char>& bytes) {
  std::ofstream(p, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
}

// Binary payload of a unit quad in the XY plane: 4 float3 positions, then 6 uint16 indices.
std::vector<unsigned char> quadBuffer(float firstX = 0.0f) {
  const float pos[12] = {firstX, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
  const std::uint16_t idx[6] = {0, 1, 2, 0, 2, 3};
  std::vector<unsigned char> out(sizeof pos + sizeof idx);
  std::memcpy(out.data(), pos, sizeof pos);
  std::memcpy(out.data() + sizeof pos, idx, sizeof idx);
  return out;
}

// glTF JSON for the quad; `extra` is spliced into the top-level object, `nodes` replaces the
// default single node.
std::string quadGltf(const std::string& uri, const std::string& extra = "",
                     const std::string& nodes = R"([{"name": "quad", "mesh": 0}])") {
  return R"({
  "asset": {"version": "2.0"},
  "scene": 0,
  "scenes": [{"nodes": [0]}],
  "nodes": )" +
         nodes + R"(,
  "meshes": [{"name": "quadmesh", "primitives": [{"attributes": {"POSITION": 0}, "indices": 1,
              "material": 0}]}],
  "materials": [{"name": "mat", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.25, 1, 1]},
                 "emissiveFactor": [1, 0.5, 0.25],
                 "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 4}}}],
  "buffers": [{)" +
         (uri.empty() ? std::string() : "\"uri\": \"" + uri + "\", ") + R"("byteLength": 60}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48},
                  {"buffer": 0, "byteOffset": 48, "byteLength": 12}],
  "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                 "min": [0, 0, 0], "max": [1, 1, 0]},
                {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}])" +
         extra + "\n}\n";
}

// A 2x1 RGBA PNG, both texels opaque: red, blue.
std::vector<unsigned char> redBluePng() {
  return {0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44,
          0x52, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00, 0x01, 0x08, 0x06, 0x00, 0x00, 0x00, 0xf4,
          0x22, 0x7f, 0x8a, 0x00, 0x00, 0x00, 0x0e, 0x49, 0x44, 0x41, 0x54, 0x78, 0x9c, 0x63, 0xf8,
          0xcf, 0xc0, 0x00, 0x42, 0xff, 0x01, 0x0f, 0xf9, 0x03, 0xfd, 0x85, 0x11, 0x99, 0x76, 0x00,
          0x00, 0x00, 0x00, 0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82};
}

// A .glb holding `json` and `bin` (chunks padded to 4 bytes as the format requires).
std::vector<unsigned char> makeGlb(std::string json, std::vector<unsigned char> bin) {
  while (json.size() % 4) json += ' ';
  while (bin.size() % 4) bin.push_back(0);
  std::vector<unsigned char> out;
  auto u32 = [&](std::uint32_t v) {
    for (int i = 0; i < 4; ++i) out.push_back(static_cast<unsigned char>(v >> (8 * i)));
  };
  out.insert(out.end(), {'g', 'l', 'T', 'F'});
  u32(2);
  u32(std::uint32_t(12 + 8 + json.size() + 8 + bin.size()));
  u32(std::uint32_t(json.size()));
  out.insert(out.end(), {'J', 'S', 'O', 'N'});
  out.insert(out.end(), json.begin(), json.end());
  u32(std::uint32_t(bin.size()));
  out.insert(out.end(), {'B', 'I', 'N', 0});
  out.insert(out.end(), bin.begin(), bin.end());
  return out;
}

// Writes quad.gltf + quad.bin into `dir` and returns the .gltf path.
fs::path writeQuadGltf(const TempDir& dir, const std::string& extra = "",
                       const std::string& nodes = R"([{"name": "quad", "mesh": 0}])") {
  writeBytes(dir / "quad.bin", quadBuffer());
  writeFile(dir / "quad.gltf", quadGltf("quad.bin", extra, nodes));
  return dir / "quad.gltf";
}

// An explicit empty sidecar keeps the project's data/sidecars out of small tests.
fs::path emptySidecar(const TempDir& dir) {
  writeFile(dir / "empty.json", "{}");
  return dir / "empty.json";
}

void expectError(const pc::Result<Scene>& r, const std::string& file, const std::string& what) {
  ASSERT_FALSE(r.ok()) << "expected an error mentioning '" << what << "'";
  EXPECT_NE(r.error().message.find(file), std::string::npos) << r.error().message;
  EXPECT_NE(r.error().message.find(what), std::string::npos) << r.error().message;
}

void expectNear(glm::vec3 a, glm::vec3 b, float tol = 1e-4f) {
  EXPECT_NEAR(a.x, b.x, tol);
  EXPECT_NEAR(a.y, b.y, tol);
  EXPECT_NEAR(a.z, b.z, tol);
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Built-in scene, model helpers, animation

TEST(BuiltinScene, IsAClosedLitRoomWithCameraAndCascades) {
  Scene s = pc::builtinScene();
  EXPECT_EQ(s.triangleCount(), 8u + 2u + 2u + 12u + 12u);
  EXPECT_TRUE(s.hasLights());
  ASSERT_FALSE(s.cameras.empty());
  ASSERT_EQ(s.volumes.size(), 2u);
  EXPECT_LT(s.volumes[0].spacing, s.volumes[1].spacing);  // finest first
  expectNear(s.boundsMin, {-1, 0, -1});
  expectNear(s.boundsMax, {1, 2, 1});
  EXPECT_NE(s.hash, 0u);
  EXPECT_EQ(s.hash, pc::builtinScene().hash);  // deterministic
  // The camera is inside the room, looking at its middle.
  const pc::Camera& cam = s.cameras[0];
  EXPECT_TRUE(glm::all(glm::greaterThan(cam.position, s.boundsMin)));
  EXPECT_TRUE(glm::all(glm::lessThan(cam.position, s.boundsMax)));
  glm::vec3 toCentre = glm::normalize(glm::vec3(0, 1, 0) - cam.position);
  EXPECT_GT(glm::dot(cam.forward, toCentre), 0.9f);
  // Every probe of every cascade lies inside the room.
  for (const pc::ProbeVolume& v : s.volumes) {
    glm::vec3 last = v.origin + v.spacing * glm::vec3(v.counts - 1);
    EXPECT_TRUE(glm::all(glm::greaterThan(v.origin, s.boundsMin)));
    EXPECT_TRUE(glm::all(glm::lessThan(last, s.boundsMax)));
  }
  for (const pc::Mesh& m : s.meshes) {
    ASSERT_EQ(m.normals.size(), m.positions.size());
    for (glm::vec3 n : m.normals) EXPECT_NEAR(glm::length(n), 1.0f, 1e-5f);
    for (std::uint32_t i : m.indices) EXPECT_LT(i, m.positions.size());
  }
  // Room walls face inward: the floor's normal points up.
  EXPECT_GT(s.meshes[0].normals[0].y, 0.9f);
  // One light and one instance are animated.
  ASSERT_EQ(s.lights.size(), 1u);
  EXPECT_GE(s.lights[0].animation, 0);
  int animated = 0;
  for (const pc::Instance& inst : s.instances) animated += inst.animation >= 0;
  EXPECT_EQ(animated, 1);
}

TEST(SceneModel, TextureSampleIsBilinearWrappedAndLinear) {
  pc::Texture t;
  t.width = 2;
  t.height = 1;
  t.rgba = {255, 0, 0, 255, 0, 0, 255, 0};  // red opaque, blue transparent
  glm::vec4 left = t.sample({0.25f, 0.5f});
  EXPECT_NEAR(left.r, 1.0f, 1e-5f);
  EXPECT_NEAR(left.b, 0.0f, 1e-5f);
  EXPECT_NEAR(left.a, 1.0f, 1e-5f);
  glm::vec4 mid = t.sample({0.5f, 0.5f});
  EXPECT_NEAR(mid.r, 0.5f, 1e-5f);
  EXPECT_NEAR(mid.a, 0.5f, 1e-5f);
  // u = 0 lies between the last and first texel: wrapping blends them.
  glm::vec4 edge = t.sample({0.0f, 0.5f});
  EXPECT_NEAR(edge.r, 0.5f, 1e-5f);
  EXPECT_NEAR(edge.b, 0.5f, 1e-5f);
  glm::vec4 wrapped = t.sample({3.25f, -4.5f});
  EXPECT_NEAR(wrapped.r, left.r, 1e-5f);
  // sRGB 128 decodes to about 0.2158 linear.
  pc::Texture g;
  g.width = g.height = 1;
  g.rgba = {128, 128, 128, 255};
  EXPECT_NEAR(g.sample({0.3f, 0.7f}).g, 0.21586f, 1e-4f);
}

TEST(SceneModel, SkyInterpolatesBetweenZenithHorizonGround) {
  pc::Sky sky;
  EXPECT_TRUE(sky.isBlack());
  sky.zenith = {0, 0, 1};
  sky.horizon = {0, 1, 0};
  sky.ground = {1, 0, 0};
  EXPECT_FALSE(sky.isBlack());
  expectNear(sky.radiance({0, 1, 0}), {0, 0, 1});
  expectNear(sky.radiance({1, 0, 0}), {0, 1, 0});
  expectNear(sky.radiance({0, -2, 0}), {1, 0, 0});
  expectNear(sky.radiance(glm::normalize(glm::vec3(1, 1, 0))), {0, 1 - 0.70711f, 0.70711f});
}

TEST(SceneModel, DefaultVolumesCoverTheBoundsInsetFinestFirst) {
  Scene s;
  s.boundsMin = {0, 0, 0};
  s.boundsMax = {24, 6, 12};
  std::vector<pc::ProbeVolume> v = pc::defaultVolumes(s, 24);
  ASSERT_EQ(v.size(), 2u);
  EXPECT_FLOAT_EQ(v[0].spacing, 1.0f);
  EXPECT_EQ(v[0].counts, glm::ivec3(24, 6, 12));
  expectNear(v[0].origin, {0.5f, 0.5f, 0.5f});  // half a spacing in from the faces
  EXPECT_FLOAT_EQ(v[1].spacing, 2.0f);
  // Small grids get one cascade.
  EXPECT_EQ(pc::defaultVolumes(s, 8).size(), 1u);
}

// A scene so small that its spacing would not be a normal float (found by fuzzing: the count
// along an axis came out as int(inf)) gets the fallback volume; a small one its own grid.
TEST(SceneModel, DefaultVolumesOfMicroscopicScenes) {
  Scene s;
  s.boundsMin = {0, 0, 0};
  s.boundsMax = {1e-40f, 2e-41f, 1e-40f};
  for (const pc::ProbeVolume& v : pc::defaultVolumes(s, 24)) {
    EXPECT_GE(v.spacing, std::numeric_limits<float>::min());
    for (int a = 0; a < 3; ++a) {
      EXPECT_GE(v.counts[a], 2);
      EXPECT_LE(v.counts[a], 24);
    }
  }
  s.boundsMax = {1e-30f, 1e-31f, 0};
  std::vector<pc::ProbeVolume> v = pc::defaultVolumes(s, 24);
  ASSERT_EQ(v.size(), 2u);
  EXPECT_FLOAT_EQ(v[0].spacing, 1e-30f / 24);
  EXPECT_EQ(v[0].counts, glm::ivec3(24, 3, 2));
}

TEST(SceneState, LightFollowsClosedPathAndBlockRotatesAboutPivot) {
  Scene s = pc::builtinScene();
  const pc::Animation& path = s.animations[s.lights[0].animation];
  ASSERT_EQ(path.points.size(), 4u);
  const float seg = path.period / 4.0f;
  expectNear(pc::evaluateScene(s, 0.0).lights[0].position, path.points[0]);
  expectNear(pc::evaluateScene(s, seg).lights[0].position, path.points[1]);
  expectNear(pc::evaluateScene(s, 0.5 * seg).lights[0].position,
             0.5f * (path.points[0] + path.points[1]));
  // The last segment leads back to the first point; time loops.
  expectNear(pc::evaluateScene(s, 3.5 * seg).lights[0].position,
             0.5f * (path.points[3] + path.points[0]));
  expectNear(pc::evaluateScene(s, path.period * 10.0 + seg).lights[0].position, path.points[1]);
  expectNear(pc::evaluateScene(s, -seg).lights[0].position, path.points[3]);

  std::size_t spinning = 0;
  while (s.instances[spinning].animation < 0) ++spinning;
  const pc::Animation& spin = s.animations[s.instances[spinning].animation];
  double t = 2.0;
  pc::SceneState st = pc::evaluateScene(s, t);
  ASSERT_EQ(st.instanceTransforms.size(), s.instances.size());
  // Unanimated instances keep their transform.
  EXPECT_EQ(st.instanceTransforms[0], s.instances[0].transform);
  // The pivot stays put; a point one unit off the axis turns by radiansPerSecond * t.
  glm::mat4 delta = st.instanceTransforms[spinning] * glm::inverse(s.instances[spinning].transform);
  expectNear(glm::vec3(delta * glm::vec4(spin.pivot, 1)), spin.pivot);
  glm::vec3 off = glm::vec3(delta * glm::vec4(spin.pivot + glm::vec3(1, 0, 0), 1)) - spin.pivot;
  float angle = float(spin.radiansPerSecond * t);
  expectNear(off, {std::cos(angle), 0, -std::sin(angle)});  // right-handed turn about +Y
}

// ---------------------------------------------------------------------------------------------
// glTF features

TEST(TextureSample, WrapModesPickTheTexelsAVulkanSamplerWould) {
  // Two texels, red then blue; u = 1.25 and -0.25 land on texel centres past either edge.
  pc::Texture t;
  t.width = 2;
  t.height = 1;
  t.rgba = {255, 0, 0, 255, 0, 0, 255, 255};
  auto red = [&](float u) { return t.sample({u, 0.5f}).r; };
  EXPECT_NEAR(red(1.25f), 1.0f, 1e-6f);  // repeat: past the right edge is the left texel
  EXPECT_NEAR(red(-0.25f), 0.0f, 1e-6f);
  t.wrapU = pc::TextureWrap::ClampToEdge;
  EXPECT_NEAR(red(1.25f), 0.0f, 1e-6f);
  EXPECT_NEAR(red(-0.25f), 1.0f, 1e-6f);
  EXPECT_NEAR(red(1e9f), 0.0f, 1e-6f);
  t.wrapU = pc::TextureWrap::MirroredRepeat;
  EXPECT_NEAR(red(1.25f), 0.0f, 1e-6f);   // the right texel again, mirrored
  EXPECT_NEAR(red(-0.25f), 1.0f, 1e-6f);  // the left texel again
  EXPECT_NEAR(red(2.25f), 1.0f, 1e-6f);   // a whole period on: as at 0.25
  EXPECT_NEAR(red(1.0f), 0.0f, 1e-6f);    // between the mirrored pair: blue on both sides
}

TEST(GltfLoad, QuadWithMaterialEmissionAndGeneratedNormals) {
  TempDir dir;
  auto r = pc::loadScene(writeQuadGltf(dir), emptySidecar(dir));
  ASSERT_TRUE(r.ok()) << r.error().message;
  const Scene& s = r.value();
  EXPECT_EQ(s.triangleCount(), 2u);
  ASSERT_EQ(s.meshes.size(), 1u);
  const pc::Mesh& m = s.meshes[0];
  ASSERT_EQ(m.normals.size(), m.positions.size());
  for (glm::vec3 n : m.normals) expectNear(n, {0, 0, 1});
  const pc::Material& mat = s.materials[m.material];
  expectNear(mat.baseColor, {0.5f, 0.25f, 1.0f});
  expectNear(mat.emissive, {4.0f, 2.0f, 1.0f});  // factor times KHR_materials_emissive_strength
  EXPECT_TRUE(s.hasLights());
  expectNear(s.boundsMin, {0, 0, 0});
  expectNear(s.boundsMax, {1, 1, 0});
  EXPECT_EQ(s.instances[0].name, "quad");
}

// Sparse accessors: a base of positions with one element replaced, and positions with no
// buffer view (zeros) made whole by sparse values. Both are valid glTF that exporters write.
TEST(Gltf, SparseAccessorsReplaceTheirElements) {
  TempDir dir;
  std::vector<unsigned char> bytes = quadBuffer();  // 48 bytes of positions, 12 of indices
  auto append = [&](const void* p, std::size_t n) {
    const auto* b = static_cast<const unsigned char*>(p);
    bytes.insert(bytes.end(), b, b + n);
  };
  const float moved[3] = {1.0f, 2.0f, 0.0f};  // at 60: replaces element 2, (1, 1, 0)
  append(moved, sizeof moved);
  const float whole[12] = {0, 0, 0, 3, 0, 0, 3, 3, 0, 0, 3, 0};  // at 72: all four elements
  append(whole, sizeof whole);
  const unsigned char which[6] = {2, 0, 1, 2, 3, 9};  // at 120: uint8 indices (9: none)
  append(which, sizeof which);
  writeBytes(dir / "sparse.bin", bytes);
  const std::string gltf = R"({
  "asset": {"version": "2.0"},
  "buffers": [{"uri": "sparse.bin", "byteLength": )" +
                           std::to_string(bytes.size()) + R"(}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48},
                  {"buffer": 0, "byteOffset": 48, "byteLength": 12},
                  {"buffer": 0, "byteOffset": 60, "byteLength": 60},
                  {"buffer": 0, "byteOffset": 120, "byteLength": 6}],
  "accessors": [
    {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
     "sparse": {"count": 1, "indices": {"bufferView": 3, "componentType": 5121},
                "values": {"bufferView": 2}}},
    {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"},
    {"componentType": 5126, "count": 4, "type": "VEC3",
     "sparse": {"count": 4, "indices": {"bufferView": 3, "byteOffset": 1, "componentType": 5121},
                "values": {"bufferView": 2, "byteOffset": 12}}}],
  "meshes": [{"name": "based", "primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]},
             {"name": "unbacked", "primitives": [{"attributes": {"POSITION": 2}, "indices": 1}]}],
  "nodes": [{"mesh": 0}, {"mesh": 1}],
  "scenes": [{"nodes": [0, 1]}], "scene": 0})";
  writeFile(dir / "sparse.gltf", gltf);
  auto r = pc::loadScene(dir / "sparse.gltf", emptySidecar(dir));
  ASSERT_TRUE(r.ok()) << r.error().message;
  ASSERT_EQ(r->meshes.size(), 2u);
  const pc::Mesh& based = r->meshes[0];
  const pc::Mesh& unbacked = r->meshes[1];
  ASSERT_EQ(based.positions.size(), 4u);
  expectNear(based.positions[1], {1, 0, 0});  // from the base
  expectNear(based.positions[2], {1, 2, 0});  // replaced
  ASSERT_EQ(unbacked.positions.size(), 4u);
  expectNear(unbacked.positions[0], {0, 0, 0});
  expectNear(unbacked.positions[2], {3, 3, 0});
  expectNear(r->boundsMax, {3, 3, 0});

  // A sparse index past the accessor's count is an error naming it.
  std::string bad = gltf;
  const std::string one =
      R"("sparse": {"count": 1, "indices": {"bufferView": 3, "componentType": 5121})";
  bad.replace(
      bad.find(one), one.size(),
      R"("sparse": {"count": 1, "indices": {"bufferView": 3, "byteOffset": 5, "componentType": 5121})");
  writeFile(dir / "bad.gltf", bad);
  expectError(pc::loadScene(dir / "bad.gltf", emptySidecar(dir)), "bad.gltf",
              "accessor 0 sparse index 9 (at 0) out of range (4 elements)");
}

// Values the sidecar refuses are refused in a glTF file too, and a glTF 1.0 file is named as
// such rather than reported as holding no triangles.
TEST(BadFiles, GltfLightsCamerasAndVersionOutOfRange) {
  TempDir dir;
  writeBytes(dir / "quad.bin", quadBuffer());
  const std::string lightNode =
      R"([{"name": "quad", "mesh": 0}, {"name": "lamp", "extensions": {"KHR_lights_punctual": {"light": 0}}}])";
  auto withLight = [&](const std::string& light) {
    std::string json = quadGltf("quad.bin",
                                R"(,
  "extensionsUsed": ["KHR_lights_punctual"],
  "extensions": {"KHR_lights_punctual": {"lights": [)" +
                                    light + "]}}",
                                lightNode);
    const std::string roots = R"("scenes": [{"nodes": [0]}])";
    json.replace(json.find(roots), roots.size(), R"("scenes": [{"nodes": [0, 1]}])");
    return json;
  };
  writeFile(dir / "neg.gltf", withLight(R"({"type": "point", "intensity": -5})"));
  expectError(pc::loadScene(dir / "neg.gltf", emptySidecar(dir)), "neg.gltf",
              "light 'lamp': intensity -5.000000 is negative or not finite");
  writeFile(
      dir / "cone.gltf",
      withLight(R"({"type": "spot", "spot": {"innerConeAngle": 1.0, "outerConeAngle": 0.2}})"));
  expectError(pc::loadScene(dir / "cone.gltf", emptySidecar(dir)), "cone.gltf",
              "spot cones must be 0 <= inner <= outer <= pi/2");
  std::string v1 = quadGltf("quad.bin");
  v1.replace(v1.find(R"("version": "2.0")"), 16, R"("version": "1.0")");
  writeFile(dir / "v1.gltf", v1);
  expectError(pc::loadScene(dir / "v1.gltf", emptySidecar(dir)), "v1.gltf",
              "glTF version '1.0' (only 2.x is read)");
}

// A scene nothing lights loads, with a warning that says so.
TEST(ObjLoad, UnlitSceneWarns) {
  TempDir dir;
  writeFile(dir / "dark.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  auto r = pc::loadScene(dir / "dark.obj", emptySidecar(dir));
  ASSERT_TRUE(r.ok()) << r.error().message;
  bool warned = false;
  for (const std::string& w : r->warnings)
    warned = warned || w.find("nothing lights the scene") != std::string::npos;
  EXPECT_TRUE(warned);
  writeFile(dir / "sky.json", R"({"sky": {"color": [0.2, 0.3, 0.4]}})");
  r = pc::loadScene(dir / "dark.obj", dir / "sky.json");
  ASSERT_TRUE(r.ok()) << r.error().message;
  for (const std::string& w : r->warnings)
    EXPECT_EQ(w.find("nothing lights"), std::string::npos) << w;
}

// A count that no bytes back is refused before anything is allocated for it.
TEST(BadFiles, GltfAccessorCountPastItsBuffer) {
  TempDir dir;
  std::string json = quadGltf("quad.bin");
  writeBytes(dir / "quad.bin", quadBuffer());
  const std::string count = R"("count": 4)";
  ASSERT_NE(json.find(count), std::string::npos);
  json.replace(json.find(count), count.size(), R"("count": 1099511627776)");  // 2^40
  writeFile(dir / "huge.gltf", json);
  expectError(pc::loadScene(dir / "huge.gltf", emptySidecar(dir)), "huge.gltf",
              "reads past the end of buffer 0 (needs 13194139533312 bytes, has 48)");
}

// A .glb whose image lies in a buffer view that runs past the buffer: tinygltf handed the view
// to its image decoder unchecked, and the decoder read past the buffer's end.
TEST(BadFiles, GltfImageViewPastItsBuffer) {
  TempDir dir;
  const std::vector<unsigned char> png = redBluePng();
  std::vector<unsigned char> bin = quadBuffer();
  bin.insert(bin.end(), png.begin(), png.end());
  std::string json = quadGltf("", R"(,
  "images": [{"bufferView": 2, "mimeType": "image/png"}],
  "textures": [{"source": 0}])");
  const std::string indexView = R"({"buffer": 0, "byteOffset": 48, "byteLength": 12})";
  json.replace(json.find(indexView), indexView.size(),
               indexView + R"(, {"buffer": 0, "byteOffset": 60, "byteLength": 4000})");
  json.replace(json.find("\"byteLength\": 60}"), 17,
               "\"byteLength\": " + std::to_string(bin.size()) + "}");
  writeBytes(dir / "image.glb", makeGlb(json, bin));
  expectError(pc::loadScene(dir / "image.glb", emptySidecar(dir)), "image.glb",
              "image 0: buffer view 2 (offset 60, 4000 bytes) lies outside its buffer");
}

// quad.gltf with `members` (JSON) added to its one material and `alpha` as its base colour
// factor's alpha.
pc::Result<Scene> loadQuadWithMaterial(const TempDir& dir, const std::string& members,
                                       const std::string& alpha = "1") {
  writeBytes(dir / "quad.bin", quadBuffer());
  std::string json = quadGltf("quad.bin");
  const std::string name = R"("name": "mat",)", factor = "[0.5, 0.25, 1, 1]";
  json.replace(json.find(name), name.size(), name + " " + members + ",");
  json.replace(json.find(factor), factor.size(), "[0.5, 0.25, 1, " + alpha + "]");
  writeFile(dir / "quad.gltf", json);
  return pc::loadScene(dir / "quad.gltf", emptySidecar(dir));
}

TEST(GltfLoad, AlphaModesBecomeCutOuts) {
  TempDir dir;
  // MASK with a base alpha under the cutoff and no texture: nothing of the quad exists.
  auto r = loadQuadWithMaterial(dir, R"("alphaMode": "MASK", "alphaCutoff": 0.75)", "0.5");
  ASSERT_TRUE(r.ok()) << r.error().message;
  const pc::Material& masked = r->materials[r->meshes[0].material];
  EXPECT_TRUE(masked.isCutOut());
  EXPECT_FLOAT_EQ(masked.alphaCutoff, 0.75f);
  EXPECT_FLOAT_EQ(masked.baseAlpha, 0.5f);
  EXPECT_FALSE(pc::coveredAt(masked, r->textures, {0.5f, 0.5f}));
  // Over the cutoff and no texture: the same answer everywhere, so no test at all.
  r = loadQuadWithMaterial(dir, R"("alphaMode": "MASK", "alphaCutoff": 0.25)");
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_FALSE(r->materials[r->meshes[0].material].isCutOut());
  // BLEND is drawn as a cut-out at one half, and said so.
  r = loadQuadWithMaterial(dir, R"("alphaMode": "BLEND")", "0.2");
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_FLOAT_EQ(r->materials[r->meshes[0].material].alphaCutoff, 0.5f);
  bool warned = false;
  for (const std::string& w : r->warnings)
    warned =
        warned || (w.find("'mat'") != std::string::npos && w.find("BLEND") != std::string::npos);
  EXPECT_TRUE(warned) << "no warning names the material and its alpha mode";
}

TEST(GltfLoad, TextureCoordinateSetsTransformsAndWrapModesAreRead) {
  TempDir dir;
  // A quad with two coordinate sets; the base colour texture reads set 1 through
  // KHR_texture_transform (scale, then rotation about the origin, then offset).
  const float pos[12] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
  const float uv0[8] = {9, 9, 9, 9, 9, 9, 9, 9};
  const float uv1[8] = {0, 0, 1, 0, 1, 1, 0, 1};
  const std::uint16_t idx[6] = {0, 1, 2, 0, 2, 3};
  std::vector<unsigned char> bin(sizeof pos + sizeof uv0 + sizeof uv1 + sizeof idx);
  std::memcpy(bin.data(), pos, sizeof pos);
  std::memcpy(bin.data() + 48, uv0, sizeof uv0);
  std::memcpy(bin.data() + 80, uv1, sizeof uv1);
  std::memcpy(bin.data() + 112, idx, sizeof idx);
  writeBytes(dir / "quad.bin", bin);
  writeBytes(dir / "t.png", redBluePng());
  writeFile(dir / "quad.gltf", R"({
  "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
  "nodes": [{"mesh": 0}],
  "extensionsUsed": ["KHR_texture_transform"], "extensionsRequired": ["KHR_texture_transform"],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1, "TEXCOORD_1": 2},
                              "indices": 3, "material": 0}]}],
  "materials": [{"name": "atlas", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0,
    "texCoord": 1, "extensions": {"KHR_texture_transform":
      {"offset": [0.5, 0.25], "scale": [2, 3], "rotation": 1.5707963}}}}}],
  "images": [{"uri": "t.png"}], "textures": [{"source": 0, "sampler": 0}],
  "samplers": [{"wrapS": 33071, "wrapT": 33648}],
  "buffers": [{"uri": "quad.bin", "byteLength": 124}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48},
                  {"buffer": 0, "byteOffset": 48, "byteLength": 32},
                  {"buffer": 0, "byteOffset": 80, "byteLength": 32},
                  {"buffer": 0, "byteOffset": 112, "byteLength": 12}],
  "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                 "min": [0, 0, 0], "max": [1, 1, 0]},
                {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"},
                {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2"},
                {"bufferView": 3, "componentType": 5123, "count": 6, "type": "SCALAR"}]
})");
  auto r = pc::loadScene(dir / "quad.gltf", emptySidecar(dir));
  ASSERT_TRUE(r.ok()) << r.error().message;
  ASSERT_EQ(r->meshes.size(), 1u);
  const std::vector<glm::vec2>& uvs = r->meshes[0].uvs;
  ASSERT_EQ(uvs.size(), 4u);
  // The sampler's wrap modes: clamp to edge across, mirrored repeat down.
  ASSERT_EQ(r->textures.size(), 1u);
  EXPECT_EQ(r->textures[0].wrapU, pc::TextureWrap::ClampToEdge);
  EXPECT_EQ(r->textures[0].wrapV, pc::TextureWrap::MirroredRepeat);
  // (u, v) of set 1 -> (0.5 - 3 v, 0.25 + 2 u).
  for (int i = 0; i < 4; ++i) {
    const glm::vec2 expected(0.5f - 3.0f * uv1[2 * i + 1], 0.25f + 2.0f * uv1[2 * i]);
    EXPECT_NEAR(uvs[i].x, expected.x, 1e-5f) << "vertex " << i;
    EXPECT_NEAR(uvs[i].y, expected.y, 1e-5f) << "vertex " << i;
  }
}

TEST(GltfLoad, GlbWithHierarchyLightsCameraAndTexture) {
  TempDir dir;
  const std::vector<unsigned char> png = redBluePng();
  std::vector<unsigned char> bin = quadBuffer();
  const std::size_t pngOffset = bin.size();
  bin.insert(bin.end(), png.begin(), png.end());
  // Parent moved up by 2, child scaled by 3; a spot light turned to point down; a camera.
  const std::string nodes = R"([
    {"name": "parent", "translation": [0, 2, 0], "children": [1, 2, 3]},
    {"name": "child", "mesh": 0, "scale": [3, 3, 3]},
    {"name": "lamp", "rotation": [-0.7071068, 0, 0, 0.7071068],
     "extensions": {"KHR_lights_punctual": {"light": 0}}},
    {"name": "eye", "translation": [0, 0, 5], "camera": 0}])";
  std::string extra = R"(,
  "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_emissive_strength"],
  "extensions": {"KHR_lights_punctual": {"lights": [
    {"name": "spot", "type": "spot", "color": [1, 0.5, 0.25], "intensity": 7,
     "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.6}}]}},
  "cameras": [{"name": "cam", "type": "perspective", "perspective": {"yfov": 0.9, "znear": 0.1}}],
  "images": [{"bufferView": 2, "mimeType": "image/png"}],
  "textures": [{"source": 0}])";
  std::string json = quadGltf("", extra, nodes);
  // Third buffer view for the PNG; the buffer grows to hold it.
  json.replace(json.find("\"byteLength\": 60}"), 17,
               "\"byteLength\": " + std::to_string(bin.size()) + "}");
  const std::string indexView = R"({"buffer": 0, "byteOffset": 48, "byteLength": 12})";
  json.replace(json.find(indexView), indexView.size(),
               indexView + R"(, {"buffer": 0, "byteOffset": )" + std::to_string(pngOffset) +
                   R"(, "byteLength": )" + std::to_string(png.size()) + "}");
  json.replace(json.find("\"baseColorFactor\""), 17,
               "\"baseColorTexture\": {\"index\": 0}, \"baseColorFactor\"");
  writeBytes(dir / "scene.glb", makeGlb(json, bin));

  auto r = pc::loadScene(dir / "scene.glb", emptySidecar(dir));
  ASSERT_TRUE(r.ok()) << r.error().message;
  const Scene& s = r.value();
  expectNear(s.boundsMin, {0, 2, 0});
  expectNear(s.boundsMax, {3, 5, 0});
  ASSERT_EQ(s.lights.size(), 1u);
  const pc::Light& l = s.lights[0];
  EXPECT_EQ(l.type, pc::LightType::Spot);
  expectNear(l.position, {0, 2, 0});
  expectNear(l.direction, {0, -1, 0});  // node -Z turned down by -90 degrees about X
  expectNear(l.color, {1, 0.5f, 0.25f});
  EXPECT_FLOAT_EQ(l.intensity, 7.0f);
  EXPECT_FLOAT_EQ(l.outerConeAngle, 0.6f);
  ASSERT_EQ(s.cameras.size(), 1u);
  expectNear(s.cameras[0].position, {0, 2, 5});
  expectNear(s.cameras[0].forward, {0, 0, -1});
  EXPECT_FLOAT_EQ(s.cameras[0].yfov, 0.9f);
  ASSERT_EQ(s.textures.size(), 1u);
  EXPECT_EQ(s.textures[0].width, 2);
  EXPECT_EQ(s.materials[0].baseColorTexture, 0);
  EXPECT_NEAR(s.textures[0].sample({0.25f, 0.5f}).r, 1.0f, 1e-5f);
  EXPECT_NEAR(s.textures[0].sample({0.75f, 0.5f}).b, 1.0f, 1e-5f);
}

// ---------------------------------------------------------------------------------------------
// OBJ features

// The quad with `pbr` as its material's pbrMetallicRoughness object and the red-blue PNG as
// texture 0; `sidecar` is the sidecar's JSON text.
pc::Result<Scene> loadQuadWithPbr(const TempDir& dir, const std::string& pbr,
                                  const std::string& sidecar = "{}") {
  writeBytes(dir / "quad.bin", quadBuffer());
  writeBytes(dir / "t.png", redBluePng());
  std::string json =
      quadGltf("quad.bin", R"(, "images": [{"uri": "t.png"}], "textures": [{"source": 0}])");
  const std::string old = R"({"baseColorFactor": [0.5, 0.25, 1, 1]})";
  json.replace(json.find(old), old.size(), pbr);
  writeFile(dir / "quad.gltf", json);
  writeFile(dir / "side.json", sidecar);
  return pc::loadScene(dir / "quad.gltf", dir / "side.json");
}

// glTF's metallic-roughness model: factors default to 1 and 1 (the specification's values),
// the texture is linear data (B metallic, G roughness), and a sidecar override replaces both
// and drops the texture.
TEST(GltfLoad, MetallicRoughnessFactorsTextureAndSidecarOverride) {
  TempDir dir;
  auto r = loadQuadWithPbr(dir, R"({"baseColorFactor": [0.5, 0.25, 1, 1]})");
  ASSERT_TRUE(r.ok()) << r.error().message;
  const pc::Material& defaults = r->materials[r->meshes[0].material];
  EXPECT_FLOAT_EQ(defaults.metallic, 1.0f);
  EXPECT_FLOAT_EQ(defaults.roughness, 1.0f);
  EXPECT_EQ(defaults.metallicRoughnessTexture, -1);
  EXPECT_FALSE(defaults.isDiffuseOnly());
  for (const std::string& w : r->warnings)
    EXPECT_EQ(w.find("metallic"), std::string::npos) << "read, yet warned unused: " << w;

  const std::string textured =
      R"({"metallicFactor": 0.25, "roughnessFactor": 0.5,
          "metallicRoughnessTexture": {"index": 0}})";
  r = loadQuadWithPbr(dir, textured);
  ASSERT_TRUE(r.ok()) << r.error().message;
  const pc::Material& mat = r->materials[r->meshes[0].material];
  EXPECT_FLOAT_EQ(mat.metallic, 0.25f);
  EXPECT_FLOAT_EQ(mat.roughness, 0.5f);
  ASSERT_GE(mat.metallicRoughnessTexture, 0);
  const pc::Texture& tex = r->textures[std::size_t(mat.metallicRoughnessTexture)];
  EXPECT_TRUE(tex.linear);  // data, never decoded from sRGB
  // Texel 0 is red (G 0, B 0), texel 1 blue (B 1): metallic is blue, roughness green.
  EXPECT_FLOAT_EQ(tex.sample({0.25f, 0.5f}).z, 0.0f);
  EXPECT_FLOAT_EQ(tex.sample({0.75f, 0.5f}).z, 1.0f);
  const std::uint64_t texturedHash = r->hash;

  // The sidecar sets roughness and metallic by material name; the texture goes.
  r = loadQuadWithPbr(dir, textured,
                      R"({"materials": [{"name": "mat", "roughness": 0.3, "metallic": 0}]})");
  ASSERT_TRUE(r.ok()) << r.error().message;
  const pc::Material& over = r->materials[r->meshes[0].material];
  EXPECT_FLOAT_EQ(over.metallic, 0.0f);
  EXPECT_FLOAT_EQ(over.roughness, 0.3f);
  EXPECT_EQ(over.metallicRoughnessTexture, -1);
  EXPECT_NE(r->hash, texturedHash);  // the wire's scene name follows the material
  // Metallic 0 and roughness 1: the diffuse surface of before.
  r = loadQuadWithPbr(dir, textured,
                      R"({"materials": [{"name": "mat", "roughness": 1, "metallic": 0}]})");
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_TRUE(r->materials[r->meshes[0].material].isDiffuseOnly());

  // Errors name the sidecar and the bad value.
  expectError(loadQuadWithPbr(dir, textured, R"({"materials": [{"name": "nope"}]})"), "side.json",
              "at /materials/0/name: no material named 'nope'");
  expectError(
      loadQuadWithPbr(dir, textured, R"({"materials": [{"name": "mat", "roughness": 1.5}]})"),
      "side.json", "at /materials/0/roughness: expected a number in [0, 1]");
  expectError(loadQuadWithPbr(dir, textured, R"({"materials": [{"name": "mat", "gloss": 1}]})"),
              "side.json", "unknown key 'gloss'");
  // An out-of-range texture index is an error naming the material.
  expectError(loadQuadWithPbr(dir, R"({"metallicRoughnessTexture": {"index": 4}})"), "quad.gltf",
              "material 'mat': metallicRoughnessTexture index 4 out of range");
}

// MTL's PBR extension: Pm and Pr where given; Phong's Ks and Ns leave a surface diffuse.
TEST(ObjLoad, PbrMetallicAndRoughnessAreReadPhongIsNot) {
  TempDir dir;
  writeFile(dir / "m.mtl",
            "newmtl phong\nKd 0.5 0.5 0.5\nKs 0.5 0.5 0.5\nNs 200\n"
            "newmtl metal\nKd 0.9 0.6 0.2\nPm 1\nPr 0.25\n");
  writeFile(dir / "m.obj",
            "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
            "usemtl phong\nf 1 2 3\nusemtl metal\nf 1 3 4\n");
  auto r = pc::loadScene(dir / "m.obj", emptySidecar(dir));
  ASSERT_TRUE(r.ok()) << r.error().message;
  ASSERT_EQ(r->meshes.size(), 2u);
  EXPECT_TRUE(r->materials[r->meshes[0].material].isDiffuseOnly());
  const pc::Material& metal = r->materials[r->meshes[1].material];
  EXPECT_FLOAT_EQ(metal.metallic, 1.0f);
  EXPECT_FLOAT_EQ(metal.roughness, 0.25f);
}

TEST(ObjLoad, SplitsByMaterialLoadsKdKeAndWarnsOnMissingTexture) {
  TempDir dir;
  writeFile(dir / "box.mtl",
            "newmtl white\nKd 0.7 0.7 0.7\n"
            "newmtl lamp\nKd 0.5 0.5 0.5\nKe 10 9 8\n"
            "newmtl tex\nmap_Kd textures/missing.png\n");
  // A unit cube without normals (8 shared vertices) plus an emissive quad and a textured quad.
  writeFile(dir / "box.obj",
            "mtllib box.mtl\n"
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
            "v 0 3 0\nv 1 3 0\nv 1 3 1\nv 0 3 1\n"
            "vt 0 0\nvt 1 0\nvt 1 1\n"
            "g cube\nusemtl white\n"
            "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 4 8 7 3\nf 1 5 8 4\nf 2 3 7 6\n"
            "g light\nusemtl lamp\nf 9 10 11 12\n"
            "g tiles\nusemtl tex\nf 1/1 2/2 3/3\n");
  auto r = pc::loadScene(dir / "box.obj", emptySidecar(dir));
  ASSERT_TRUE(r.ok()) << r.error().message;
  const Scene& s = r.value();
  EXPECT_EQ(s.triangleCount(), 12u + 2u + 1u);
  ASSERT_EQ(s.meshes.size(), 3u);
  const pc::Mesh& cube = s.meshes[0];
  EXPECT_EQ(cube.name, "cube");
  // Hard edges stay hard: every corner normal is an axis, so vertices were split (6 faces x 4).
  EXPECT_EQ(cube.positions.size(), 24u);
  for (glm::vec3 n : cube.normals)
    EXPECT_NEAR(std::max({std::abs(n.x), std::abs(n.y), std::abs(n.z)}), 1.0f, 1e-5f);
  // Outward: the face at z = 1 has normal +Z.
  for (std::size_t i = 0; i < cube.positions.size(); ++i) {
    if (cube.positions[i].z == 1.0f && cube.normals[i].z != 0.0f) {
      EXPECT_GT(cube.normals[i].z, 0.0f);
    }
  }
  expectNear(s.materials[cube.material].baseColor, {0.7f, 0.7f, 0.7f});
  expectNear(s.materials[s.meshes[1].material].emissive, {10, 9, 8});
  EXPECT_TRUE(s.hasLights());
  // Missing map_Kd: a warning naming the file, a grey stand-in colour, no texture.
  const pc::Material& tex = s.materials[s.meshes[2].material];
  EXPECT_EQ(tex.baseColorTexture, -1);
  EXPECT_GT(tex.baseColor.x, 0.1f);
  bool warned = false;
  for (const std::string& w : s.warnings)
    warned = warned || w.find("missing.png") != std::string::npos;
  EXPECT_TRUE(warned) << "no warning names the missing texture";
  // OBJ v is flipped to the glTF convention (row 0 at the top).
  ASSERT_EQ(s.meshes[2].uvs.size(), 3u);
  EXPECT_FLOAT_EQ(s.meshes[2].uvs[2].y, 0.0f);
}

// mtllib separates file names with spaces, but exporters write names that hold spaces: where
// the tokens name no file and the whole argument does, that file is read. Two real files on
// one line still both load.
TEST(ObjLoad, MaterialFileNamesWithSpaces) {
  TempDir dir;
  writeFile(dir / "my materials.mtl", "newmtl lamp\nKd 0.5 0.5 0.5\nKe 3 2 1\n");
  writeFile(dir / "a.mtl", "newmtl red\nKd 0.9 0.1 0.1\n");
  writeFile(dir / "b.mtl", "newmtl blue\nKd 0.1 0.1 0.9\n");
  const std::string quads = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n";
  writeFile(dir / "spaced.obj", "mtllib my materials.mtl\n" + quads + "usemtl lamp\nf 1 2 3 4\n");
  auto r = pc::loadScene(dir / "spaced.obj", emptySidecar(dir));
  ASSERT_TRUE(r.ok()) << r.error().message;
  ASSERT_EQ(r->meshes.size(), 1u);
  expectNear(r->materials[r->meshes[0].material].emissive, {3, 2, 1});
  for (const std::string& w : r->warnings) ADD_FAILURE() << "unexpected warning: " << w;

  writeFile(dir / "two.obj",
            "mtllib a.mtl b.mtl\n" + quads + "usemtl red\nf 1 2 3\nusemtl blue\nf 1 3 4\n");
  r = pc::loadScene(dir / "two.obj", emptySidecar(dir));
  ASSERT_TRUE(r.ok()) << r.error().message;
  ASSERT_EQ(r->meshes.size(), 2u);
  expectNear(r->materials[r->meshes[0].material].baseColor, {0.9f, 0.1f, 0.1f});
  expectNear(r->materials[r->meshes[1].material].baseColor, {0.1f, 0.1f, 0.9f});
}

TEST(ObjLoad, AlphaMapMakesACutOut) {
  TempDir dir;
  // An opaque image as map_d: its first channel is the mask (red 1, blue 0).
  writeBytes(dir / "mask.png", redBluePng());
  writeFile(dir / "leaf.mtl",
            "newmtl leaf\nKd 0.3 0.6 0.2\nmap_d mask.png\n"
            "newmtl lost\nKd 0.5 0.5 0.5\nmap_d missing_mask.png\n");
  writeFile(dir / "leaf.obj",
            "mtllib leaf.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\n"
            "usemtl leaf\nf 1/1 2/2 3/3\nusemtl lost\nf 1/1 3/3 2/2\n");
  auto r = pc::loadScene(dir / "leaf.obj", emptySidecar(dir));
  ASSERT_TRUE(r.ok()) << r.error().message;
  ASSERT_EQ(r->meshes.size(), 2u);
  const pc::Material& leaf = r->materials[r->meshes[0].material];
  EXPECT_TRUE(leaf.isCutOut());
  EXPECT_EQ(leaf.alphaChannel, 0);
  EXPECT_TRUE(pc::coveredAt(leaf, r->textures, {0.25f, 0.5f}));
  EXPECT_FALSE(pc::coveredAt(leaf, r->textures, {0.75f, 0.5f}));
  // A mask that cannot be read leaves the surface opaque, with a warning naming it.
  EXPECT_FALSE(r->materials[r->meshes[1].material].isCutOut());
  bool warned = false;
  for (const std::string& w : r->warnings)
    warned = warned || w.find("missing_mask.png") != std::string::npos;
  EXPECT_TRUE(warned);
}

TEST(ObjLoad, SmoothSurfacesShareNormals) {
  TempDir dir;
  // Two triangles meeting at 20 degrees: below the 60 degree threshold, so the shared edge
  // gets one averaged normal.
  const float a = glm::radians(20.0f);
  writeFile(dir / "fold.obj", "v 0 0 0\nv 0 0 1\nv -1 0 0\nv " + std::to_string(std::cos(a)) + " " +
                                  std::to_string(std::sin(a)) +
                                  " 0\n"
                                  "f 1 2 3\nf 2 1 4\n");
  auto r = pc::loadScene(dir / "fold.obj", emptySidecar(dir));
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ(r.value().meshes[0].positions.size(), 4u);
}

// ---------------------------------------------------------------------------------------------
// Broken files: the error names the file and the problem

TEST(BadFiles, MissingFile) {
  TempDir dir;
  expectError(pc::loadScene(dir / "nothere.glb"), "nothere.glb", "file not found");
}

TEST(BadFiles, UnsupportedFormat) {
  TempDir dir;
  writeFile(dir / "scene.fbx", "x");
  expectError(pc::loadScene(dir / "scene.fbx"), "scene.fbx", "unsupported scene format");
}

TEST(BadFiles, TruncatedGlb) {
  TempDir dir;
  std::vector<unsigned char> glb = makeGlb(quadGltf(""), quadBuffer());
  glb.resize(glb.size() / 2);
  writeBytes(dir / "cut.glb", glb);
  expectError(pc::loadScene(dir / "cut.glb", emptySidecar(dir)), "cut.glb", "truncated .glb");
  // A file that is not glTF at all goes through the parser's own message.
  writeFile(dir / "text.glb", "this is not a binary glTF file");
  expectError(pc::loadScene(dir / "text.glb", emptySidecar(dir)), "text.glb", "cannot parse glTF");
}

TEST(BadFiles, GlbWithShortBuffer) {
  TempDir dir;
  // Well-formed container, but the accessors reach past the 24 bytes the buffer really has.
  std::vector<unsigned char> bin = quadBuffer();
  bin.resize(24);
  std::string json = quadGltf("");
  json.replace(json.find("\"byteLength\": 60}"), 17, "\"byteLength\": 24}");
  writeBytes(dir / "short.glb", makeGlb(json, bin));
  auto r = pc::loadScene(dir / "short.glb", emptySidecar(dir));
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("short.glb"), std::string::npos) << r.error().message;
}

// Finite file positions that a node's scale, or the sidecar's unit_scale, carries past the
// float range: the scene's bounds were infinite, and so was every probe volume and
// acceleration structure built from them.
TEST(BadFiles, WorldPositionsPastTheFloatRange) {
  TempDir dir;
  writeBytes(dir / "quad.bin", quadBuffer());
  writeFile(dir / "nested.gltf",
            quadGltf("quad.bin", "",
                     R"([{"name": "giant", "scale": [1e30, 1e30, 1e30], "children": [1]},
                         {"name": "quad", "mesh": 0, "scale": [1e30, 1e30, 1e30]}])"));
  expectError(pc::loadScene(dir / "nested.gltf", emptySidecar(dir)), "nested.gltf",
              "instance 'quad' (mesh 'quadmesh'): vertex 0 lands at a non-finite world position");

  writeFile(
      dir / "large.gltf",
      quadGltf("quad.bin", "", R"([{"name": "quad", "mesh": 0, "scale": [1e20, 1e20, 1e20]}])"));
  auto large = pc::loadScene(dir / "large.gltf", emptySidecar(dir));
  ASSERT_TRUE(large.ok()) << large.error().message;  // large but finite: loads
  EXPECT_FLOAT_EQ(large->boundsMax.x, 1e20f);
  writeFile(dir / "scaled.json", R"({"unit_scale": 1e20})");
  expectError(pc::loadScene(dir / "large.gltf", dir / "scaled.json"), "large.gltf",
              "non-finite world position");
}

// A glTF URI naming a directory made tinygltf allocate 2^63 - 1 bytes for it (std::bad_alloc
// ended the process); a glTF URI or an OBJ texture naming a FIFO blocked the load until
// something wrote to it. Only regular files are read.
TEST(BadFiles, UrisNamingADirectoryOrAFifo) {
  TempDir dir;
  fs::create_directories(dir / "folder");
  writeFile(dir / "folder.gltf", quadGltf("folder"));
  expectError(pc::loadScene(dir / "folder.gltf", emptySidecar(dir)), "folder.gltf",
              "folder' is not a regular file");
  ASSERT_EQ(::mkfifo((dir / "pipe").c_str(), 0600), 0);
  writeFile(dir / "pipe.gltf", quadGltf("pipe"));
  expectError(pc::loadScene(dir / "pipe.gltf", emptySidecar(dir)), "pipe.gltf",
              "pipe' is not a regular file");
  // An OBJ texture that is a FIFO: a warning naming it, and the scene loads.
  writeFile(dir / "t.mtl", "newmtl t\nmap_Kd pipe\n");
  writeFile(dir / "t.obj", "mtllib t.mtl\nusemtl t\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  auto obj = pc::loadScene(dir / "t.obj", emptySidecar(dir));
  ASSERT_TRUE(obj.ok()) << obj.error().message;
  EXPECT_TRUE(obj->textures.empty());
  bool warned = false;
  for (const std::string& w : obj->warnings)
    warned = warned || w.find("pipe: cannot read image: not a regular file") != std::string::npos;
  EXPECT_TRUE(warned);
}

TEST(BadFiles, GltfIndexOutOfRange) {
  TempDir dir;
  std::vector<unsigned char> bin = quadBuffer();
  const std::uint16_t bad = 9;
  std::memcpy(bin.data() + 48 + 2 * 4, &bad, 2);
  writeBytes(dir / "quad.bin", bin);
  writeFile(dir / "quad.gltf", quadGltf("quad.bin"));
  expectError(pc::loadScene(dir / "quad.gltf", emptySidecar(dir)), "quad.gltf",
              "index 9 (at 4) out of range (4 vertices)");
}

TEST(BadFiles, GltfNaNPosition) {
  TempDir dir;
  writeBytes(dir / "quad.bin", quadBuffer(std::numeric_limits<float>::quiet_NaN()));
  writeFile(dir / "quad.gltf", quadGltf("quad.bin"));
  expectError(pc::loadScene(dir / "quad.gltf", emptySidecar(dir)), "quad.gltf",
              "vertex 0 has a non-finite position");
}

TEST(BadFiles, GltfUnknownRequiredExtension) {
  TempDir dir;
  fs::path p = writeQuadGltf(dir, R"(,
  "extensionsUsed": ["EXT_imaginary_compression"],
  "extensionsRequired": ["EXT_imaginary_compression"])");
  expectError(pc::loadScene(p, emptySidecar(dir)), "quad.gltf",
              "unsupported required glTF extension 'EXT_imaginary_compression'");
}

TEST(BadFiles, ObjIndexOutOfRange) {
  TempDir dir;
  writeFile(dir / "bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n");
  expectError(pc::loadScene(dir / "bad.obj", emptySidecar(dir)), "bad.obj",
              "vertex index 7 out of range (3 vertices)");
}

TEST(BadFiles, ObjNaNVertex) {
  TempDir dir;
  writeFile(dir / "nan.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n");
  expectError(pc::loadScene(dir / "nan.obj", emptySidecar(dir)), "nan.obj:2",
              "vertex 2 has a non-finite coordinate 'nan'");
}

TEST(BadFiles, ObjVertexWithoutThreeNumbers) {
  TempDir dir;
  writeFile(dir / "short.obj", "v 0 0 0\nv 1 0 0\nv 0 1\nf 1 2 3\n");
  expectError(pc::loadScene(dir / "short.obj", emptySidecar(dir)), "short.obj:3",
              "vertex 3 has 2 coordinates where a position needs 3");
  writeFile(dir / "word.obj", "v 0 0 0\nv 1 zero 0\nv 0 1 0\nf 1 2 3\n");
  expectError(pc::loadScene(dir / "word.obj", emptySidecar(dir)), "word.obj:2",
              "vertex 2 has a coordinate 'zero' that is not a number");
  writeFile(dir / "glued.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0x\nf 1 2 3\n");
  expectError(pc::loadScene(dir / "glued.obj", emptySidecar(dir)), "glued.obj:3",
              "vertex 3 has a coordinate '0x' that is not a number");
  // A weight and vertex colours after the position are valid OBJ.
  writeFile(dir / "extra.obj", "v 0 0 0 1\nv 1 0 0 1 0.5 0.5\nv 0 1 0\nf 1 2 3\n");
  EXPECT_TRUE(pc::loadScene(dir / "extra.obj", emptySidecar(dir)).ok());
}

TEST(BadFiles, NoTriangles) {
  TempDir dir;
  writeFile(dir / "empty.obj", "v 0 0 0\nv 1 0 0\n");
  expectError(pc::loadScene(dir / "empty.obj", emptySidecar(dir)), "empty.obj", "no triangles");
}

TEST(BadFiles, MalformedSidecarJson) {
  TempDir dir;
  fs::path scene = writeQuadGltf(dir);
  writeFile(dir / "broken.json", "{ \"lights\": [ }");
  expectError(pc::loadScene(scene, dir / "broken.json"), "broken.json", "invalid JSON");
  expectError(pc::loadScene(scene, dir / "absent.json"), "absent.json", "sidecar file not found");
}

TEST(BadFiles, SidecarWrongTypesNamePointer) {
  TempDir dir;
  fs::path scene = writeQuadGltf(dir);
  writeFile(dir / "s1.json", R"({"exposure": "bright"})");
  expectError(pc::loadScene(scene, dir / "s1.json"), "s1.json",
              "at /exposure: expected a number, got string");
  writeFile(dir / "s2.json", R"({"lights": [{"type": "point"}, {"type": "area"}]})");
  expectError(pc::loadScene(scene, dir / "s2.json"), "s2.json",
              "at /lights/1/type: unknown light type 'area'");
  writeFile(dir / "s3.json", R"({"cameras": [{"position": [0, 1], "target": [0, 0, 0]}]})");
  expectError(pc::loadScene(scene, dir / "s3.json"), "s3.json",
              "at /cameras/0/position: expected an array of 3 numbers");
  writeFile(dir / "s4.json", R"({"exposur": 2})");
  expectError(pc::loadScene(scene, dir / "s4.json"), "s4.json", "at /exposur: unknown key");
  writeFile(dir / "s5.json", R"({"animations": [{"type": "rotate", "instances": ["nope"]}]})");
  expectError(pc::loadScene(scene, dir / "s5.json"), "s5.json",
              "at /animations/0/instances/0: no node or mesh named 'nope'");
}

TEST(BadFiles, SidecarVolumesBeyondWhatAFieldHolds) {
  TempDir dir;
  fs::path scene = writeQuadGltf(dir);
  std::string five = R"({"volumes": [)";
  for (int i = 0; i < 5; ++i)
    five += std::string(i ? ", " : "") + R"({"origin": [0, 0, 0], "spacing": )" +
            std::to_string(i + 1) + R"(, "counts": [2, 2, 2]})";
  writeFile(dir / "v1.json", five + "]}");
  expectError(pc::loadScene(scene, dir / "v1.json"), "v1.json",
              "at /volumes: 5 volumes; a field has at most 4 cascades");
  // Each axis within its bound, the whole far past any memory: refused before allocating.
  writeFile(
      dir / "v2.json",
      R"({"volumes": [{"origin": [0, 0, 0], "spacing": 0.001, "counts": [2000, 2000, 2000]}]})");
  expectError(pc::loadScene(scene, dir / "v2.json"), "v2.json",
              "at /volumes/0: the volumes hold 8000000000 probes up to here; at most 4194304");
  writeFile(dir / "v3.json",
            R"({"volumes": [{"min": [0, 0, 0], "max": [1, 1, 1], "spacing": 0.0067},
                                             {"min": [0, 0, 0], "max": [1, 1, 1], "spacing": 0.01}]})");
  expectError(pc::loadScene(scene, dir / "v3.json"), "v3.json",
              "at /volumes/1: the volumes hold 4405301 probes up to here");
}

// ---------------------------------------------------------------------------------------------
// Sidecar features

// A copy of the tools finds the sidecars beside itself (sidecars/, as scripts/bundle lays them
// out) before the source tree's, and the report says which one a scene took, or where none
// was found.
TEST(Sidecar, FoundBesideTheExecutableAndReported) {
  TempDir dir;
  const std::string stem = "pc_beside_the_executable_" + std::to_string(::getpid());
  writeFile(dir / (stem + ".obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  auto bare = pc::loadScene(dir / (stem + ".obj"));
  ASSERT_TRUE(bare.ok()) << bare.error().message;
  EXPECT_TRUE(bare->sidecar.empty());
  EXPECT_NE(pc::sidecarReport(*bare).find("no sidecar (looked for"), std::string::npos)
      << pc::sidecarReport(*bare);

  const fs::path folder = fs::read_symlink("/proc/self/exe").parent_path() / "sidecars";
  const bool made = fs::create_directories(folder);
  const fs::path sidecar = folder / (stem + ".json");
  writeFile(sidecar, R"({"lights": [{"name": "lamp", "type": "point", "position": [0, 1, 1]}]})");
  auto withSidecar = pc::loadScene(dir / (stem + ".obj"));
  fs::remove(sidecar);
  if (made) fs::remove(folder);
  ASSERT_TRUE(withSidecar.ok()) << withSidecar.error().message;
  EXPECT_EQ(withSidecar->sidecar, sidecar);
  ASSERT_EQ(withSidecar->lights.size(), 1u);
  EXPECT_EQ(withSidecar->lights[0].name, "lamp");
  EXPECT_NE(pc::sidecarReport(*withSidecar).find("sidecar " + sidecar.string()), std::string::npos);
}

// Where the executable's folders hold none, $PROBECAST_DATA/sidecars is looked in too (a copy
// of the tools laid out otherwise); the report and the data folders list name it.
TEST(Sidecar, FoundUnderProbecastData) {
  TempDir dir;
  const std::string stem = "pc_under_probecast_data_" + std::to_string(::getpid());
  const fs::path data = dir / "data";
  fs::create_directories(dir / "scene");
  fs::create_directories(data / "sidecars");
  writeFile(dir / "scene" / (stem + ".obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  writeFile(data / "sidecars" / (stem + ".json"),
            R"({"lights": [{"name": "lamp", "type": "point", "position": [0, 1, 1]}]})");
  ::setenv("PROBECAST_DATA", data.c_str(), 1);
  auto scene = pc::loadScene(dir / "scene" / (stem + ".obj"));
  const std::string folders = pc::dataFolderList("sidecars");
  auto missing = pc::findDataFile("sidecars", "pc_nowhere.json");
  ::unsetenv("PROBECAST_DATA");
  ASSERT_TRUE(scene.ok()) << scene.error().message;
  EXPECT_EQ(scene->sidecar, data / "sidecars" / (stem + ".json"));
  ASSERT_EQ(scene->lights.size(), 1u);
  EXPECT_NE(folders.find((data / "sidecars").string()), std::string::npos) << folders;
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find("pc_nowhere.json: not found in " + folders),
            std::string::npos)
      << missing.error().message;
}

// The sidecars the project ships are known by name, so that a scene named for one that finds
// none stops the tool (install_and_consume checks that on a copy without its data).
TEST(Sidecar, ShippedSidecarsAreKnownByName) {
  EXPECT_TRUE(pc::scene_detail::isShippedSidecar("rtxgi-cornell.json"));
  EXPECT_TRUE(pc::scene_detail::isShippedSidecar("sauer-pandora.json"));
  EXPECT_FALSE(pc::scene_detail::isShippedSidecar("rtxgi-cornell"));
  EXPECT_FALSE(pc::scene_detail::isShippedSidecar("cornell.json"));
  EXPECT_FALSE(pc::scene_detail::isShippedSidecar(""));
}

TEST(Sidecar, UnitScaleUpAxisCamerasVolumesAnimations) {
  TempDir dir;
  fs::path scene = writeQuadGltf(dir);  // quad in the XY plane of a Z-up file: it stands up
  writeFile(dir / "scene.json", R"({
    "_comment": "keys starting with _ are ignored",
    "unit_scale": 2, "up_axis": "z", "exposure": 0.5, "emissive_mode": "field",
    "sky": {"color": [0.1, 0.2, 0.3]},
    "lights": [{"name": "bulb", "type": "point", "position": [0, 1, 0], "intensity": 3,
                "animation": "orbit"},
               {"name": "sun", "type": "directional", "direction": [0, -2, 0]}],
    "cameras": [{"name": "a", "position": [0, 1, 5], "yaw": 90, "pitch": 0, "fov": 60},
                {"name": "b", "position": [0, 1, 5], "yaw": 0, "pitch": 30}],
    "volumes": [{"min": [0, 0, 0], "max": [2, 1, 1], "spacing": 0.5},
                {"origin": [-1, -1, -1], "spacing": 1, "counts": [4, 3, 2]}],
    "animations": [{"name": "orbit", "type": "path", "points": [[0, 1, 0], [2, 1, 0]],
                    "period": 2},
                   {"name": "spin", "type": "rotate", "axis": [0, 1, 0], "pivot": [1, 0, 0],
                    "degrees_per_second": 90, "instances": ["quadmesh"]}]
  })");
  // <scene dir>/scene.json is found without being named.
  auto r = pc::loadScene(scene);
  ASSERT_TRUE(r.ok()) << r.error().message;
  const Scene& s = r.value();
  EXPECT_EQ(s.sidecar, dir / "scene.json");
  // (x, y, z) -> (x, z, -y), then doubled: the quad spans x 0..2, y 0, z -2..0.
  expectNear(s.boundsMin, {0, 0, -2});
  expectNear(s.boundsMax, {2, 0, 0});
  EXPECT_FLOAT_EQ(s.exposure, 0.5f);
  EXPECT_EQ(s.emissiveMode, pc::EmissiveMode::Field);
  expectNear(s.sky.horizon, {0.1f, 0.2f, 0.3f});
  ASSERT_EQ(s.lights.size(), 2u);
  expectNear(s.lights[1].direction, {0, -1, 0});
  ASSERT_EQ(s.cameras.size(), 2u);
  expectNear(s.cameras[0].forward, {1, 0, 0});  // yaw 90: from -Z toward +X
  EXPECT_NEAR(s.cameras[0].yfov, glm::radians(60.0f), 1e-6f);
  expectNear(s.cameras[1].forward, {0, 0.5f, -0.866025f});  // positive pitch looks up
  expectNear(s.cameras[1].up, {0, 0.866025f, 0.5f});
  ASSERT_EQ(s.volumes.size(), 2u);
  EXPECT_EQ(s.volumes[0].counts, glm::ivec3(5, 3, 3));
  expectNear(s.volumes[0].origin, {0, 0, 0});
  EXPECT_EQ(s.volumes[1].counts, glm::ivec3(4, 3, 2));
  // Animations: the light on its path, the quad turning about the pivot.
  pc::SceneState st = pc::evaluateScene(s, 0.5);
  expectNear(st.lights[0].position, {1, 1, 0});
  glm::vec3 corner = glm::vec3(st.instanceTransforms[0] * glm::vec4(1, 0, 0, 1));  // -> (2,0,0)
  const float c45 = std::cos(glm::radians(45.0f));
  expectNear(corner, {1 + c45, 0, -c45});
  EXPECT_NE(s.hash, 0u);
}

// ---------------------------------------------------------------------------------------------
// Shared scenes (skipped where ../shared/scenes is absent)

namespace {

struct SharedScene {
  const char* file;
  std::size_t triangles;
  std::size_t minLights;  // from the sidecar (or emissive material: 0 here)
  bool emissive;          // lit by an emissive material from the file
};

const SharedScene kShared[] = {
    {"rtxgi-cornell/cornell.glb", 34, 1, false},
    {"rtxgi-furnace/furnace.glb", 12, 0, false},
    {"rtxgi-two-rooms/two-rooms.glb", 90, 1, false},
    {"rtxgi-tunnel/tunnel.glb", 348, 1, false},
    {"mcguire-cornellbox/CornellBox-Original.obj", 36, 0, true},
    {"godot-living-room/living_room.glb", 5088, 3, false},
    {"sauer-pandora/pandora.obj", 60810, 1, false},
};

}  // namespace

class SharedScenes : public ::testing::TestWithParam<SharedScene> {};

TEST_P(SharedScenes, LoadWithSidecar) {
  const fs::path root = PC_SCENES_DIR;
  const SharedScene& p = GetParam();
  if (!fs::is_directory(root)) GTEST_SKIP() << "shared scenes folder " << root << " is absent";
  const fs::path file = root / p.file;
  if (!fs::exists(file)) GTEST_SKIP() << file << " is absent";
  auto r = pc::loadScene(file);
  ASSERT_TRUE(r.ok()) << r.error().message;
  const Scene& s = r.value();
  EXPECT_EQ(s.triangleCount(), p.triangles);
  EXPECT_FALSE(s.sidecar.empty()) << "no sidecar found for " << p.file;
  EXPECT_GE(s.lights.size(), p.minLights);
  EXPECT_TRUE(s.hasLights() || !s.sky.isBlack());
  if (p.emissive) {
    EXPECT_TRUE(s.hasLights());
  }
  ASSERT_FALSE(s.cameras.empty());
  ASSERT_FALSE(s.volumes.empty());
  EXPECT_TRUE(glm::all(glm::lessThan(s.boundsMin, s.boundsMax)) || s.boundsMin.y == s.boundsMax.y);
  // Sidecar cameras look at the scene: the view ray's direction points toward the bounds.
  const pc::Camera& cam = s.cameras[0];
  glm::vec3 centre = 0.5f * (s.boundsMin + s.boundsMax);
  bool inside = glm::all(glm::greaterThan(cam.position, s.boundsMin)) &&
                glm::all(glm::lessThan(cam.position, s.boundsMax));
  if (!inside) {
    EXPECT_GT(glm::dot(cam.forward, glm::normalize(centre - cam.position)), 0.5f);
  }
  for (const pc::Mesh& m : s.meshes) {
    ASSERT_EQ(m.normals.size(), m.positions.size()) << m.name;
    for (std::uint32_t i : m.indices) ASSERT_LT(i, m.positions.size());
  }
  // Loading twice gives the same hash.
  auto again = pc::loadScene(file);
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(again.value().hash, s.hash);
}

INSTANTIATE_TEST_SUITE_P(All, SharedScenes, ::testing::ValuesIn(kShared),
                         [](const ::testing::TestParamInfo<SharedScene>& info) {
                           std::string name = fs::path(info.param.file).stem().string();
                           for (char& c : name)
                             if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
                           return name;
                         });

TEST(SharedScenesDetail, SidecarValuesLandWhereExpected) {
  const fs::path root = PC_SCENES_DIR;
  if (!fs::exists(root / "sauer-pandora/pandora.obj") ||
      !fs::exists(root / "rtxgi-cornell/cornell.glb"))
    GTEST_SKIP() << "shared scenes folder " << root << " is absent";
  auto pandora = pc::loadScene(root / "sauer-pandora/pandora.obj");
  ASSERT_TRUE(pandora.ok()) << pandora.error().message;
  // Game units scaled by 0.05; missing textures are warnings, not errors.
  EXPECT_NEAR(pandora->boundsMax.x - pandora->boundsMin.x, 73.6f, 0.01f);
  EXPECT_FALSE(pandora->warnings.empty());
  EXPECT_EQ(pandora->volumes[0].counts, glm::ivec3(44, 14, 25));
  EXPECT_FLOAT_EQ(pandora->volumes[0].spacing, 1.7f);
  auto cornell = pc::loadScene(root / "rtxgi-cornell/cornell.glb");
  ASSERT_TRUE(cornell.ok()) << cornell.error().message;
  EXPECT_EQ(cornell->lights[0].type, pc::LightType::Directional);
  EXPECT_EQ(cornell->volumes[0].counts, glm::ivec3(9));
  expectNear(cornell->cameras[0].forward, {0, 0, -1});
}
