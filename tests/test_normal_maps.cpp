// glTF normal maps: the material's normalTexture and the meshes' tangents as loading reads or
// makes them, and the reference path tracer shading with the mapped normal (tests/
// normal_map_scene.h: a lit quad whose map leans its normal one way).
#include <gtest/gtest.h>

#include <cstdio>
#include <string>

#include "common/scene_loaders.h"
#include "cpu/path_tracer.h"
#include "normal_map_scene.h"
#include "shaders/interop/normal_map.h"

namespace pc::test {
namespace {

// A folder of its own per test, under the system's temporary folder, removed afterwards.
class TestDir {
 public:
  TestDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = std::filesystem::temp_directory_path() /
            ("pc_test_normal_maps_" + std::string(info->name()));
    std::filesystem::remove_all(path_);
  }
  ~TestDir() { std::filesystem::remove_all(path_); }
  std::filesystem::path sub(const std::string& name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

void expectNear(glm::vec4 a, glm::vec4 b, float tol = 1e-5f) {
  EXPECT_NEAR(a.x, b.x, tol);
  EXPECT_NEAR(a.y, b.y, tol);
  EXPECT_NEAR(a.z, b.z, tol);
  EXPECT_NEAR(a.w, b.w, tol);
}

bool warnsAbout(const Scene& scene, const std::string& what) {
  for (const std::string& w : scene.warnings)
    if (w.find(what) != std::string::npos) return true;
  return false;
}

TEST(NormalMapLoad, NormalTextureScaleAndTangentsAreRead) {
  TestDir dir;
  NormalMapQuad q;
  q.texel = {204, 128, 230};
  q.scale = 0.5f;
  auto scene = loadNormalMapQuad(dir.sub("q"), q);
  ASSERT_TRUE(scene.ok()) << scene.error().message;
  ASSERT_EQ(scene->meshes.size(), 1u);
  const Material& mat = scene->materials[std::size_t(scene->meshes[0].material)];
  ASSERT_GE(mat.normalTexture, 0);
  EXPECT_FLOAT_EQ(mat.normalScale, 0.5f);
  const Texture& map = scene->textures[std::size_t(mat.normalTexture)];
  EXPECT_TRUE(map.linear);
  // Linear codes / 255: 204 would read 0.604 if it were decoded from sRGB.
  const glm::vec4 texel = map.sample({0.5f, 0.5f});
  EXPECT_NEAR(texel.x, 204.0f / 255.0f, 1e-6f);
  EXPECT_NEAR(texel.z, 230.0f / 255.0f, 1e-6f);
  ASSERT_EQ(scene->meshes[0].tangents.size(), 4u);
  for (const glm::vec4& t : scene->meshes[0].tangents) expectNear(t, {1, 0, 0, 1});
  EXPECT_FALSE(warnsAbout(*scene, "normal")) << "a read normal map is not to be warned about";
}

TEST(NormalMapLoad, MissingTangentsAreGeneratedFromTheCoordinates) {
  TestDir dir;
  NormalMapQuad q;
  q.tangents = false;
  auto scene = loadNormalMapQuad(dir.sub("plain"), q);
  ASSERT_TRUE(scene.ok()) << scene.error().message;
  ASSERT_EQ(scene->meshes[0].tangents.size(), 4u);
  // u along +X; v down the image along -Y, so the map's +y is +Y: cross(N, T) = +Y, w = +1.
  for (const glm::vec4& t : scene->meshes[0].tangents) expectNear(t, {1, 0, 0, 1});
  EXPECT_TRUE(scene->warnings.empty()) << scene->warnings.front();

  // Mirrored in u: the tangent turns to -X and the handedness to -1, keeping the bitangent +Y.
  q.mirrorU = true;
  auto mirrored = loadNormalMapQuad(dir.sub("mirrored"), q);
  ASSERT_TRUE(mirrored.ok()) << mirrored.error().message;
  ASSERT_EQ(mirrored->meshes[0].tangents.size(), 4u);
  for (const glm::vec4& t : mirrored->meshes[0].tangents) expectNear(t, {-1, 0, 0, -1});

  // Without a normal map, tangents are neither kept nor made.
  q.normalMap = false;
  q.tangents = true;
  auto unmapped = loadNormalMapQuad(dir.sub("unmapped"), q);
  ASSERT_TRUE(unmapped.ok()) << unmapped.error().message;
  EXPECT_TRUE(unmapped->meshes[0].tangents.empty());
}

TEST(NormalMapLoad, TangentsFromDegenerateOrMissingCoordinates) {
  // One triangle with all three coordinates equal, one proper: the proper one's direction
  // reaches the shared corners, and the corner only the degenerate one touches still gets a
  // unit tangent perpendicular to its normal.
  Mesh mesh;
  mesh.name = "strip";
  mesh.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {-1, 1, 0}};
  mesh.normals.assign(5, glm::vec3(0, 0, 1));
  mesh.uvs = {{0, 1}, {1, 1}, {1, 0}, {0, 1}, {0, 1}};
  mesh.indices = {0, 1, 2, 3, 0, 4};  // the second triangle's coordinates are one point
  ASSERT_TRUE(scene_detail::generateTangents(mesh).ok());
  ASSERT_EQ(mesh.tangents.size(), 5u);
  expectNear(mesh.tangents[0], {1, 0, 0, 1});  // shared with the proper triangle
  expectNear(mesh.tangents[1], {1, 0, 0, 1});
  for (const glm::vec4& t : mesh.tangents) {
    EXPECT_NEAR(glm::length(glm::vec3(t)), 1.0f, 1e-5f);
    EXPECT_NEAR(t.z, 0.0f, 1e-5f);
  }

  // Every triangle degenerate: an error naming the mesh, and no tangents.
  mesh.uvs.assign(5, glm::vec2(0.25f));
  const Status all = scene_detail::generateTangents(mesh);
  ASSERT_FALSE(all.ok());
  EXPECT_NE(all.error().message.find("'strip'"), std::string::npos) << all.error().message;
  EXPECT_TRUE(mesh.tangents.empty());

  // A glTF mesh without coordinates loads, drawn without its map, with one warning saying so.
  TestDir dir;
  NormalMapQuad q;
  q.uvs = false;
  auto scene = loadNormalMapQuad(dir.sub("no_uvs"), q);
  ASSERT_TRUE(scene.ok()) << scene.error().message;
  EXPECT_TRUE(scene->meshes[0].tangents.empty());
  EXPECT_TRUE(warnsAbout(*scene, "mesh 'quad'") && warnsAbout(*scene, "normal map"));
}

TEST(NormalMapLoad, BadNormalTextureIndexIsAnErrorNamingIt) {
  TestDir dir;
  NormalMapQuad q;
  q.normalTextureIndex = 3;
  auto scene = loadNormalMapQuad(dir.sub("bad"), q);
  ASSERT_FALSE(scene.ok());
  const std::string& message = scene.error().message;
  EXPECT_NE(message.find("quad.gltf"), std::string::npos) << message;
  EXPECT_NE(message.find("material 'bumpy'"), std::string::npos) << message;
  EXPECT_NE(message.find("normalTexture index 3 out of range (1 textures)"), std::string::npos)
      << message;
}

TEST(NormalMapMath, PerturbsInTheTangentFrame) {
  const glm::vec3 n(0.0f, 0.0f, 1.0f);
  // The tangent need be neither unit nor perpendicular: it is made so against N.
  const glm::vec3 t(2.0f, 0.0f, 0.5f);
  const auto near = [](glm::vec3 a, glm::vec3 b) { return glm::length(a - b) < 1e-6f; };
  EXPECT_TRUE(near(gpu::pcPerturbNormal(n, t, 1.0f, {1, 0, 0}), {1, 0, 0}));
  EXPECT_TRUE(near(gpu::pcPerturbNormal(n, t, 1.0f, {0, 1, 0}), {0, 1, 0}));  // cross(N, T)
  EXPECT_TRUE(near(gpu::pcPerturbNormal(n, t, -1.0f, {0, 1, 0}), {0, -1, 0}));
  EXPECT_TRUE(near(gpu::pcPerturbNormal(n, t, 1.0f, {0, 0, 3}), n));
  // No frame (a tangent along the normal): the normal itself.
  EXPECT_TRUE(near(gpu::pcPerturbNormal(n, n, 1.0f, {1, 0, 0}), n));
  // The texel's decoding: x 2 - 1, x and y scaled.
  EXPECT_TRUE(near(gpu::pcNormalMapDirection({1.0f, 0.5f, 0.75f}, 0.5f), {0.5f, 0.0f, 0.5f}));
}

// The reference's mean radiance over the quad (it fills the image), direct light only.
double referenceMean(const Scene& scene) {
  PathTraceOptions o;
  o.width = o.height = 24;
  o.spp = 2;
  o.maxBounces = 0;
  auto r = renderReference(scene, o);
  EXPECT_TRUE(r.ok()) << (r ? "" : r.error().message);
  return r ? meanRadiance(r->image) : 0.0;
}

TEST(NormalMapReference, ShadesWithTheMappedNormal) {
  TestDir dir;
  NormalMapQuad q;
  q.normalMap = false;
  auto plain = loadNormalMapQuad(dir.sub("plain"), q);
  ASSERT_TRUE(plain.ok()) << plain.error().message;
  const double base = referenceMean(*plain);
  const float baseCosine = glm::dot(glm::vec3(0.0f, 0.0f, 1.0f), normalMapQuadToLight());
  ASSERT_GT(base, 0.0);

  // Each map: its texel, and the mean it must give relative to the unmapped quad (the
  // cosines' ratio: the light is the same everywhere on the quad and nothing else lights it).
  const NormalMapCase cases[] = {{"flat", {128, 128, 255}, true},
                                 {"toward +x (tangent)", {204, 128, 230}, true},
                                 {"toward +y (bitangent)", {128, 204, 230}, true},
                                 {"toward -x", {51, 128, 230}, true},
                                 {"toward +y, generated tangents", {128, 204, 230}, false}};
  for (const NormalMapCase& c : cases) {
    q.normalMap = true;
    q.texel = c.texel;
    q.tangents = c.tangents;
    auto scene = loadNormalMapQuad(dir.sub(c.name), q);
    ASSERT_TRUE(scene.ok()) << scene.error().message;
    const double ratio = referenceMean(*scene) / base;
    const double expected = normalMapQuadCosine(c.texel) / baseCosine;
    std::printf("reference, map %-30s mean / unmapped %.4f (expected %.4f)\n", c.name, ratio,
                expected);
    EXPECT_NEAR(ratio, expected, 0.01 * expected) << c.name;
  }
}

}  // namespace
}  // namespace pc::test
