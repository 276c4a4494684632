// Scene files written to attack the tools: references that leave the scene's folder, images
// and triangle counts that ask for more memory than a scene may have, vertices shared by a huge
// number of faces. Each is refused with an error naming what was wrong (or, for the shared
// vertex, loads in bounded time), and ordinary files load as before.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "common/image.h"
#include "common/scene.h"

namespace fs = std::filesystem;

namespace {

// A fresh folder per test, removed afterwards: scenes go in its "scene" subfolder, files they
// must not reach beside it.
class HostileFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    root_ = fs::temp_directory_path() /
            ("pc_test_hostile_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(root_);
    fs::create_directories(root_ / "scene");
  }
  void TearDown() override { fs::remove_all(root_); }
  fs::path scene(const std::string& name) const { return root_ / "scene" / name; }
  fs::path outside(const std::string& name) const { return root_ / name; }
  fs::path root_;
};

void writeFile(const fs::path& p, const std::string& text) {
  std::ofstream(p, std::ios::binary) << text;
}

bool contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

// A unit quad's buffer: 4 float3 positions, then 6 uint16 indices (60 bytes).
std::vector<unsigned char> quadBuffer() {
  const float pos[12] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
  const std::uint16_t idx[6] = {0, 1, 2, 0, 2, 3};
  std::vector<unsigned char> out(sizeof pos + sizeof idx);
  std::memcpy(out.data(), pos, sizeof pos);
  std::memcpy(out.data() + sizeof pos, idx, sizeof idx);
  return out;
}

void writeQuadBuffer(const fs::path& p) {
  const std::vector<unsigned char> b = quadBuffer();
  std::ofstream(p, std::ios::binary)
      .write(reinterpret_cast<const char*>(b.data()), std::streamsize(b.size()));
}

std::string base64(const std::vector<unsigned char>& in) {
  static const char* abc = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (std::size_t i = 0; i < in.size(); i += 3) {
    const std::size_t left = in.size() - i;
    std::uint32_t v = std::uint32_t(in[i]) << 16;
    if (left > 1) v |= std::uint32_t(in[i + 1]) << 8;
    if (left > 2) v |= in[i + 2];
    out += abc[(v >> 18) & 63];
    out += abc[(v >> 12) & 63];
    out += left > 1 ? abc[(v >> 6) & 63] : '=';
    out += left > 2 ? abc[v & 63] : '=';
  }
  return out;
}

// A quad as glTF, its buffer at `bufferUri`; `images` (a JSON array) adds a textured material;
// `nodes` replaces the single node.
std::string quadGltf(const std::string& bufferUri, const std::string& images = "",
                     const std::string& nodes = R"([{"mesh": 0}])") {
  const std::string material = images.empty()
                                   ? ""
                                   : R"(, "material": 0}]}], "materials": [{"pbrMetallicRoughness":
           {"baseColorTexture": {"index": 0}}}], "textures": [{"source": 0}], "images": )" +
                                         images;
  return R"({"asset": {"version": "2.0"}, "scene": 0,
  "scenes": [{"nodes": [0]}], "nodes": )" +
         nodes + R"(,
  "buffers": [{"uri": ")" +
         bufferUri +
         R"(", "byteLength": 60}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48},
                  {"buffer": 0, "byteOffset": 48, "byteLength": 12}],
  "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                 "min": [0, 0, 0], "max": [1, 1, 0]},
                {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1)" +
         (images.empty() ? "}]}]" : material) + "}";
}

// The first bytes of a PNG whose header declares width x height (no pixel data follows: the
// header is all a size check may read).
std::string pngHeader(std::uint32_t width, std::uint32_t height) {
  std::string s("\x89PNG\r\n\x1a\n", 8);
  auto be32 = [&](std::uint32_t v) {
    for (int i = 3; i >= 0; --i) s += char((v >> (8 * i)) & 0xff);
  };
  be32(13);
  s += "IHDR";
  be32(width);
  be32(height);
  s += std::string("\x08\x06\x00\x00\x00", 5);  // 8-bit RGBA
  be32(0);                                      // CRC (stb_image does not check it)
  return s;
}

void writeSmallPng(const fs::path& p, int size) {
  pc::Image8 img;
  img.width = img.height = size;
  img.rgb.assign(std::size_t(size) * size * 3, 128);
  ASSERT_TRUE(pc::writePng(p, img).ok());
}

// ---- references outside the scene's folder ----

TEST_F(HostileFiles, GltfBufferOutsideTheFolderIsRefused) {
  writeQuadBuffer(outside("outside.bin"));
  writeFile(scene("up.gltf"), quadGltf("../outside.bin"));
  auto r = pc::loadScene(scene("up.gltf"));
  ASSERT_FALSE(r.ok());
  const std::string& m = r.error().message;
  EXPECT_TRUE(contains(m, "'../outside.bin'")) << m;
  EXPECT_TRUE(contains(m, "outside the scene's folder " + fs::canonical(root_ / "scene").string()))
      << m;

  // Far above the folder: the traversal the tools were attacked with.
  writeFile(scene("etc.gltf"), quadGltf("../../../../../../../../../../etc/hostname"));
  r = pc::loadScene(scene("etc.gltf"));
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "'../../../../../../../../../../etc/hostname' leads to"))
      << r.error().message;

  // The user may allow it.
  pc::SceneLoadOptions allow;
  allow.allowOutsidePaths = true;
  auto allowed = pc::loadScene(scene("up.gltf"), {}, allow);
  ASSERT_TRUE(allowed.ok()) << allowed.error().message;
  EXPECT_EQ(allowed->triangleCount(), 2u);
}

TEST_F(HostileFiles, GltfLinkLeadingOutsideIsRefused) {
  writeQuadBuffer(outside("outside.bin"));
  fs::create_symlink(outside("outside.bin"), scene("link.bin"));
  writeFile(scene("link.gltf"), quadGltf("link.bin"));
  auto r = pc::loadScene(scene("link.gltf"));
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message,
                       "'link.bin' leads to " + fs::canonical(outside("outside.bin")).string()))
      << r.error().message;
}

TEST_F(HostileFiles, GltfInsideAndDataUrisStillLoad) {
  fs::create_directories(scene("bin"));
  writeQuadBuffer(scene("bin/quad.bin"));
  writeFile(scene("inside.gltf"), quadGltf("bin/../bin/quad.bin"));
  auto inside = pc::loadScene(scene("inside.gltf"));
  ASSERT_TRUE(inside.ok()) << inside.error().message;

  writeFile(scene("data.gltf"),
            quadGltf("data:application/octet-stream;base64," + base64(quadBuffer())));
  auto data = pc::loadScene(scene("data.gltf"));
  ASSERT_TRUE(data.ok()) << data.error().message;
  EXPECT_EQ(data->triangleCount(), 2u);
}

TEST_F(HostileFiles, GltfImageOutsideTheFolderIsRefused) {
  writeQuadBuffer(scene("quad.bin"));
  writeSmallPng(outside("secret.png"), 4);
  writeFile(scene("img.gltf"), quadGltf("quad.bin", R"([{"uri": "../secret.png"}])"));
  auto r = pc::loadScene(scene("img.gltf"));
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "'../secret.png' leads to")) << r.error().message;
}

TEST_F(HostileFiles, ObjMaterialLibraryAndTexturesOutsideAreRefused) {
  const std::string tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
  writeFile(outside("evil.mtl"), "newmtl m\nKd 1 0 0\n");
  writeFile(scene("mtl.obj"), "mtllib ../evil.mtl\n" + tri + "usemtl m\nf 1 2 3\n");
  auto r = pc::loadScene(scene("mtl.obj"));
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "material library '../evil.mtl' leads to"))
      << r.error().message;

  writeSmallPng(outside("tex.png"), 4);
  writeFile(scene("tex.mtl"), "newmtl m\nmap_Kd ../tex.png\n");
  writeFile(scene("tex.obj"), "mtllib tex.mtl\n" + tri + "usemtl m\nf 1 2 3\n");
  r = pc::loadScene(scene("tex.obj"));
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "texture map '../tex.png' leads to"))
      << r.error().message;

  writeFile(scene("abs.mtl"), "newmtl m\nmap_Kd " + outside("tex.png").string() + "\n");
  writeFile(scene("abs.obj"), "mtllib abs.mtl\n" + tri + "usemtl m\nf 1 2 3\n");
  r = pc::loadScene(scene("abs.obj"));
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "outside the scene's folder")) << r.error().message;

  pc::SceneLoadOptions allow;
  allow.allowOutsidePaths = true;
  auto allowed = pc::loadScene(scene("tex.obj"), {}, allow);
  ASSERT_TRUE(allowed.ok()) << allowed.error().message;
  ASSERT_EQ(allowed->textures.size(), 1u);
}

// ---- texture sizes ----

TEST_F(HostileFiles, OversizedTextureRefusedFromItsHeader) {
  const std::string tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n";
  writeFile(scene("big.png"), pngHeader(16384, 16384));
  writeFile(scene("big.mtl"), "newmtl m\nmap_Kd big.png\n");
  writeFile(scene("big.obj"), "mtllib big.mtl\n" + tri + "usemtl m\nf 1/1 2/2 3/3\n");
  auto r = pc::loadScene(scene("big.obj"));
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message,
                       "texture 'big.png' is 16384x16384, over the limit of 8192 texels per side"))
      << r.error().message;

  // The same image in a glTF, as a file and as a data URI.
  writeQuadBuffer(scene("quad.bin"));
  writeFile(scene("big.gltf"), quadGltf("quad.bin", R"([{"uri": "big.png"}])"));
  r = pc::loadScene(scene("big.gltf"));
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "texture 'big.png' is 16384x16384")) << r.error().message;
  const std::string png = pngHeader(20000, 3);
  writeFile(scene("data.gltf"),
            quadGltf("quad.bin", R"([{"name": "wide", "uri": "data:image/png;base64,)" +
                                     base64({png.begin(), png.end()}) + "\"}]"));
  r = pc::loadScene(scene("data.gltf"));
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "texture 'wide' is 20000x3")) << r.error().message;
}

TEST_F(HostileFiles, SceneTexelBudgetAndRaisedLimits) {
  writeSmallPng(scene("a.png"), 8);
  writeSmallPng(scene("b.png"), 8);
  writeFile(scene("two.mtl"), "newmtl a\nmap_Kd a.png\nnewmtl b\nmap_Kd b.png\n");
  writeFile(scene("two.obj"),
            "mtllib two.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\nusemtl b\nf 1 3 2\n");
  pc::SceneLoadOptions o;
  o.maxSceneTexels = 100;  // one 8x8 texture fits, two do not
  auto r = pc::loadScene(scene("two.obj"), {}, o);
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message,
                       "texture 'b.png' (8x8) brings the scene's textures to 128 texels, over "
                       "the limit of 100"))
      << r.error().message;
  o.maxSceneTexels = 128;
  auto ok = pc::loadScene(scene("two.obj"), {}, o);
  ASSERT_TRUE(ok.ok()) << ok.error().message;
  EXPECT_EQ(ok->textures.size(), 2u);

  o.maxTextureSize = 4;
  r = pc::loadScene(scene("two.obj"), {}, o);
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "'a.png' is 8x8, over the limit of 4"))
      << r.error().message;
}

// ---- triangle counts ----

TEST_F(HostileFiles, TriangleLimitFromTheFileCounts) {
  std::string obj = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 2 0\n";
  for (int i = 0; i < 5; ++i) obj += "f 1 2 3 4 5\n";  // 3 triangles each, once triangulated
  writeFile(scene("many.obj"), obj);
  pc::SceneLoadOptions o;
  o.maxTriangles = 14;
  auto r = pc::loadScene(scene("many.obj"), {}, o);
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "many.obj: 15 triangles, over the limit of 14"))
      << r.error().message;
  o.maxTriangles = 15;
  EXPECT_TRUE(pc::loadScene(scene("many.obj"), {}, o).ok());

  // glTF: from the index accessor's count, and over the instances drawn.
  writeQuadBuffer(scene("quad.bin"));
  writeFile(scene("quad.gltf"), quadGltf("quad.bin"));
  o.maxTriangles = 1;
  r = pc::loadScene(scene("quad.gltf"), {}, o);
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "2 triangles, over the limit of 1")) << r.error().message;
  writeFile(scene("three.gltf"),
            quadGltf("quad.bin", "", R"([{"children": [1, 2, 3]}, {"mesh": 0}, {"mesh": 0},
                                         {"mesh": 0}])"));
  o.maxTriangles = 5;
  r = pc::loadScene(scene("three.gltf"), {}, o);
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "the triangles drawn over all instances: 6 triangles"))
      << r.error().message;
}

TEST_F(HostileFiles, NodeGraphThatDoublesEachLevelIsRefused) {
  // Node k lists node k+1 twice: 2^40 paths to the last node, in a few hundred bytes.
  std::string nodes = "[";
  for (int k = 0; k < 40; ++k)
    nodes += "{\"children\": [" + std::to_string(k + 1) + ", " + std::to_string(k + 1) + "]},";
  nodes += "{\"mesh\": 0}]";
  writeQuadBuffer(scene("quad.bin"));
  writeFile(scene("dag.gltf"), quadGltf("quad.bin", "", nodes));
  auto r = pc::loadScene(scene("dag.gltf"));
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "triangles drawn over all instances") ||
              contains(r.error().message, "nodes reached through many paths"))
      << r.error().message;
}

// ---- normal generation ----

// FNV-1a over the loaded meshes' positions, normals, uvs and indices.
std::uint64_t meshHash(const pc::Scene& s) {
  std::uint64_t h = 0xcbf29ce484222325ull;
  auto bytes = [&](const void* p, std::size_t n) {
    for (std::size_t i = 0; i < n; ++i) {
      h ^= static_cast<const unsigned char*>(p)[i];
      h *= 0x100000001b3ull;
    }
  };
  for (const pc::Mesh& m : s.meshes) {
    bytes(m.positions.data(), m.positions.size() * sizeof(glm::vec3));
    bytes(m.normals.data(), m.normals.size() * sizeof(glm::vec3));
    bytes(m.uvs.data(), m.uvs.size() * sizeof(glm::vec2));
    bytes(m.indices.data(), m.indices.size() * 4);
  }
  return h;
}

// Ordinary meshes without normals (a UV sphere, a cube, a bumpy height field) get the normals,
// vertex splits and order that the generator has always given them: the hash was recorded from
// the earlier (quadratic) generator.
TEST_F(HostileFiles, GeneratedNormalsUnchangedOnOrdinaryMeshes) {
  std::ostringstream obj;
  obj.precision(6);
  int base = 1;
  // UV sphere: 24 segments, 12 rings.
  obj << "o sphere\nv 0 1 0\n";
  for (int r = 1; r < 12; ++r)
    for (int s = 0; s < 24; ++s) {
      const double th = M_PI * r / 12, ph = 2 * M_PI * s / 24;
      obj << "v " << std::sin(th) * std::cos(ph) << " " << std::cos(th) << " "
          << std::sin(th) * std::sin(ph) << "\n";
    }
  obj << "v 0 -1 0\n";
  auto ring = [&](int r, int s) { return base + 1 + (r - 1) * 24 + (s % 24); };
  for (int s = 0; s < 24; ++s)
    obj << "f " << base << " " << ring(1, s + 1) << " " << ring(1, s) << "\n";
  for (int r = 1; r < 11; ++r)
    for (int s = 0; s < 24; ++s)
      obj << "f " << ring(r, s) << " " << ring(r, s + 1) << " " << ring(r + 1, s + 1) << " "
          << ring(r + 1, s) << "\n";
  const int south = base + 1 + 11 * 24;
  for (int s = 0; s < 24; ++s)
    obj << "f " << south << " " << ring(11, s) << " " << ring(11, s + 1) << "\n";
  base = south + 1;
  // Cube.
  obj << "o cube\n";
  for (int i = 0; i < 8; ++i)
    obj << "v " << 3 + (i & 1) << " " << ((i >> 1) & 1) << " " << ((i >> 2) & 1) << "\n";
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                           {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads)
    obj << "f " << base + q[0] << " " << base + q[1] << " " << base + q[2] << " " << base + q[3]
        << "\n";
  base += 8;
  // Height field, 16x16 cells, heights from a fixed sequence (sharp and smooth creases).
  obj << "o terrain\n";
  std::uint32_t seed = 12345;
  for (int z = 0; z <= 16; ++z)
    for (int x = 0; x <= 16; ++x) {
      seed = seed * 1664525u + 1013904223u;
      obj << "v " << x * 0.25 << " " << double(seed >> 24) / 255.0 * 0.6 << " " << z * 0.25 + 5
          << "\n";
    }
  for (int z = 0; z < 16; ++z)
    for (int x = 0; x < 16; ++x) {
      const int a = base + z * 17 + x;
      obj << "f " << a << " " << a + 17 << " " << a + 18 << " " << a + 1 << "\n";
    }
  writeFile(scene("ordinary.obj"), obj.str());
  auto s = pc::loadScene(scene("ordinary.obj"));
  ASSERT_TRUE(s.ok()) << s.error().message;
  ASSERT_EQ(s->meshes.size(), 3u);
  std::size_t vertices = 0;
  for (const pc::Mesh& m : s->meshes) vertices += m.positions.size();
  RecordProperty("vertices", int(vertices));
  EXPECT_EQ(meshHash(*s), 457824801525431184ull) << "vertices " << vertices;
}

// A fan of `faces` triangles around one vertex, flat (a disc) or as a cone.
std::string fanObj(int faces, bool cone) {
  std::string obj;
  obj.reserve(std::size_t(faces) * 60);
  obj += cone ? "v 0 1 0\n" : "v 0 0 0\n";
  char line[96];
  for (int i = 0; i < faces; ++i) {
    const double a = 2 * M_PI * i / faces;
    std::snprintf(line, sizeof line, "v %.9f 0 %.9f\n", std::cos(a), std::sin(a));
    obj += line;
  }
  for (int i = 0; i < faces; ++i) {
    std::snprintf(line, sizeof line, "f 1 %d %d\n", 2 + (i + 1) % faces, 2 + i);
    obj += line;
  }
  return obj;
}

// 250,000 faces around one vertex: the generator compared every face around a vertex with
// every other (62.5 billion tests here, minutes); it now finishes within the suite's run.
TEST_F(HostileFiles, NormalsOfAHugeFanGenerateInBoundedTime) {
  constexpr int kFaces = 250000;
  for (bool cone : {false, true}) {
    writeFile(scene("fan.obj"), fanObj(kFaces, cone));
    const auto t0 = std::chrono::steady_clock::now();
    auto s = pc::loadScene(scene("fan.obj"));
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    RecordProperty(cone ? "cone_seconds" : "disc_seconds", std::to_string(seconds));
    std::printf("%s fan of %d faces: loaded in %.3f s\n", cone ? "cone" : "disc", kFaces, seconds);
    ASSERT_TRUE(s.ok()) << s.error().message;
    ASSERT_EQ(s->meshes.size(), 1u);
    const pc::Mesh& m = s->meshes[0];
    EXPECT_EQ(m.triangleCount(), std::size_t(kFaces));
    ASSERT_EQ(m.normals.size(), m.positions.size());
    for (std::size_t i = 0; i < m.normals.size(); ++i) {
      ASSERT_NEAR(glm::length(m.normals[i]), 1.0f, 1e-4f) << i;
      if (!cone) {
        ASSERT_NEAR(m.normals[i].y, 1.0f, 1e-4f) << i;  // a flat disc facing up
      } else {
        ASSERT_GT(m.normals[i].y, 0.5f) << i;  // a cone's sides face up and out
      }
    }
  }
}

}  // namespace
