// Textures in the client: the mip chains built on upload, what they do to a minified texture
// against the CPU's supersampled render, and cut-outs against the CPU's (lavapipe with
// validation).
#include <cmath>
#include <cstdio>
#include <vector>

#include "client/texture_mips.h"
#include "common/scene_loaders.h"
#include "cpu/probe_lit_render.h"
#include "test_client_support.h"
#include "test_meshes.h"

namespace pc::client::test {
namespace {

constexpr int kWidth = 160, kHeight = 120;

// The client's image of `scene` (one view, kWidth x kHeight); empty unless it rendered exactly
// one.
Image8 clientImage(vk::Context& ctx, const Scene& scene, const Field& field, const Camera& camera,
                   Rasterizer rasterizer = Rasterizer::Auto, bool textureMipmaps = true) {
  ClientFrame frame = renderClientFrame(ctx, scene, &field, camera, nullptr, kWidth, kHeight, {},
                                        rasterizer, textureMipmaps);
  return frame.display.size() == 1 ? std::move(frame.display[0]) : Image8{};
}

// The CPU probe-lit render of `camera` with `rays` jittered rays per pixel, tone mapped
// (empty on failure, with the error reported).
Image8 cpuProbeLit(const Scene& scene, const Field& field, const Camera& camera, int rays) {
  ProbeLitOptions lit;
  lit.width = kWidth;
  lit.height = kHeight;
  lit.primarySamples = rays;
  lit.explicitCamera = camera;
  auto image = renderProbeLit(scene, field, lit);
  EXPECT_TRUE(image.ok()) << (image ? "" : image.error().message);
  return image ? tonemap(*image, scene.exposure) : Image8{};
}

TEST(TextureMips, LevelCountsAndSizesFollowTheLargerSide) {
  EXPECT_EQ(mipLevelCount(1, 1), 1);
  EXPECT_EQ(mipLevelCount(2, 1), 2);
  EXPECT_EQ(mipLevelCount(5, 3), 3);    // 5x3, 2x1, 1x1
  EXPECT_EQ(mipLevelCount(16, 16), 5);  // 16, 8, 4, 2, 1
  std::vector<std::uint8_t> rgba(5 * 3 * 4, 7);
  const MipChain chain = buildSrgbMipChain(5, 3, rgba);
  EXPECT_EQ(chain.levels, 3);
  EXPECT_EQ(chain.rgba.size(), std::size_t(5 * 3 + 2 * 1 + 1 * 1) * 4);
  // A constant image stays constant at every level.
  for (std::uint8_t v : chain.rgba) EXPECT_EQ(v, 7);
}

TEST(TextureMips, TexelsAverageTheirParentsInLinearLight) {
  // Black and white: the average is half the light, sRGB 188, not 128. Alpha averages as
  // stored.
  const std::vector<std::uint8_t> rgba = {0, 0, 0, 0, 255, 255, 255, 255};
  const MipChain chain = buildSrgbMipChain(2, 1, rgba);
  ASSERT_EQ(chain.rgba.size(), 12u);
  const std::uint8_t half =
      std::uint8_t(std::lround(255.0f * (1.055f * std::pow(0.5f, 1.0f / 2.4f) - 0.055f)));
  EXPECT_EQ(half, 188);
  EXPECT_EQ(chain.rgba[8], half);
  EXPECT_EQ(chain.rgba[9], half);
  EXPECT_EQ(chain.rgba[10], half);
  EXPECT_EQ(chain.rgba[11], 128);
  // The last column of an odd width folds into its neighbour's texel: 3 -> 1 averages all
  // three (two white of three: 2/3 of the light).
  const std::vector<std::uint8_t> three = {0, 0, 0, 255, 255, 255, 255, 255, 255, 255, 255, 255};
  const MipChain folded = buildSrgbMipChain(3, 1, three);
  ASSERT_EQ(folded.levels, 2);
  const float twoThirds = scene_detail::srgbToLinear(float(folded.rgba[12]) / 255.0f);
  EXPECT_NEAR(twoThirds, 2.0f / 3.0f, 0.005f);
}

// The built-in room with its white walls, floor and ceiling in a fine checker (1-texel black
// and white cells, 40 repeats across a wall): at this size every pixel covers many texels.
Scene checkeredRoom() {
  Scene scene = builtinScene();
  Texture checker;
  checker.name = "checker";
  checker.width = checker.height = 16;
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 16; ++x) {
      const std::uint8_t v = (x + y) % 2 ? 255 : 0;
      checker.rgba.insert(checker.rgba.end(), {v, v, v, 255});
    }
  scene.textures.push_back(checker);
  scene.materials[0].baseColorTexture = 0;
  scene.materials[0].baseColor = glm::vec3(1.0f);
  for (Mesh& mesh : scene.meshes)
    if (mesh.material == 0 && mesh.name != "block")
      for (glm::vec2& uv : mesh.uvs) uv *= 40.0f;
  return scene;
}

TEST(ClientTextures, MipmapsBringMinifiedTexturesToTheSupersampledAverage) {
  // Against the CPU probe-lit render with 64 jittered rays per pixel (the texture averaged
  // over each pixel), the client with mip chains must come much closer than with one level-0
  // tap per MSAA sample, which aliases.
  const Scene scene = checkeredRoom();
  auto ctx = validatingContext();
  if (!ctx) GTEST_SKIP() << "no Vulkan device";
  auto camera = sceneCamera(scene, 0);
  ASSERT_TRUE(camera.ok());
  const Field field = bakeQuickly(scene, 4);
  const Image8 mipmapped = clientImage(*ctx, scene, field, *camera, Rasterizer::Auto, true);
  const Image8 levelZero = clientImage(*ctx, scene, field, *camera, Rasterizer::Auto, false);
  ASSERT_FALSE(mipmapped.rgb.empty());
  ASSERT_FALSE(levelZero.rgb.empty());

  const Image8 cpu8 = cpuProbeLit(scene, field, *camera, 64);
  ASSERT_FALSE(cpu8.rgb.empty());
  const double withMips = psnr8(mipmapped, cpu8);
  const double without = psnr8(levelZero, cpu8);
  std::printf(
      "checkered room vs CPU probe-lit (64 rays per pixel): mipmapped %.2f dB, level 0 "
      "only %.2f dB\n",
      withMips, without);
  const std::filesystem::path dir = testOutputDir("mipmaps");
  writePng(dir / "client_mipmapped.png", mipmapped);
  writePng(dir / "client_level0.png", levelZero);
  writePng(dir / "cpu_probe_lit_64.png", cpu8);
  // Measured on lavapipe: 38.8 dB against 24.6.
  EXPECT_GT(withMips, 36.0);
  EXPECT_GT(withMips, without + 10.0);
}

TEST(ClientTextures, CutOutsMatchTheCpuInBothRasterizersAndTheirShadows) {
  // The room's grille (test_meshes.h) seen from below, its shadow on the floor: the client's
  // holes (compute rasterizer per sample, fixed-function per fragment, shadow maps per
  // texel) against the CPU probe-lit render, whose rays pass the same holes (Embree filters).
  const Scene scene = testmesh::grilleRoom(true);
  const Scene solid = testmesh::grilleRoom(false);
  auto ctx = validatingContext();
  if (!ctx) GTEST_SKIP() << "no Vulkan device";
  auto camera = sceneCamera(scene, 0);
  ASSERT_TRUE(camera.ok());
  camera->forward = glm::normalize(glm::vec3(0.0f, -0.35f, -1.0f));  // grille above, floor below
  const Field field = bakeQuickly(scene, 4);
  const Image8 compute = clientImage(*ctx, scene, field, *camera, Rasterizer::Auto);
  const Image8 fixed = clientImage(*ctx, scene, field, *camera, Rasterizer::FixedFunction);
  ASSERT_FALSE(compute.rgb.empty());
  ASSERT_FALSE(fixed.rgb.empty());

  const Image8 cpu8 = cpuProbeLit(scene, field, *camera, 16);
  const Image8 solid8 = cpuProbeLit(solid, bakeQuickly(solid, 4), *camera, 16);
  ASSERT_FALSE(cpu8.rgb.empty());
  ASSERT_FALSE(solid8.rgb.empty());
  const double vsCpu = psnr8(compute, cpu8);
  const double fixedVsCpu = psnr8(fixed, cpu8);
  const double vsSolid = psnr8(compute, solid8);
  std::printf(
      "grille room: client vs CPU %.2f dB (fixed-function %.2f dB); against the CPU's "
      "opaque grille %.2f dB\n",
      vsCpu, fixedVsCpu, vsSolid);
  const std::filesystem::path dir = testOutputDir("cut-outs");
  writePng(dir / "client_compute.png", compute);
  writePng(dir / "client_fixed.png", fixed);
  writePng(dir / "cpu_probe_lit.png", cpu8);
  writePng(dir / "cpu_opaque_grille.png", solid8);
  // Measured on lavapipe: 34.2 dB, fixed-function 32.2 dB, against the opaque grille 15.1 dB.
  EXPECT_GT(vsCpu, 31.0);
  EXPECT_GT(fixedVsCpu, 29.0);
  EXPECT_GT(vsCpu, vsSolid + 10.0);

  // The grille texture clamped across and mirrored down (its coordinates run to 3): the
  // client's samplers must wrap as Texture::sample does, in holes and shadows alike.
  const Scene wrapped =
      testmesh::grilleRoom(true, TextureWrap::ClampToEdge, TextureWrap::MirroredRepeat);
  const Field wrappedField = bakeQuickly(wrapped, 4);
  const Image8 wrappedClient = clientImage(*ctx, wrapped, wrappedField, *camera);
  ASSERT_FALSE(wrappedClient.rgb.empty());
  const Image8 wrappedCpu = cpuProbeLit(wrapped, wrappedField, *camera, 16);
  ASSERT_FALSE(wrappedCpu.rgb.empty());
  const double wrappedVsCpu = psnr8(wrappedClient, wrappedCpu);
  const double wrappedVsRepeat = psnr8(wrappedClient, cpu8);
  std::printf(
      "grille room, clamp x mirror: client vs CPU %.2f dB; against the CPU's repeating "
      "grille %.2f dB\n",
      wrappedVsCpu, wrappedVsRepeat);
  writePng(dir / "client_clamp_mirror.png", wrappedClient);
  writePng(dir / "cpu_clamp_mirror.png", wrappedCpu);
  EXPECT_GT(wrappedVsCpu, 31.0);
  EXPECT_GT(wrappedVsCpu, wrappedVsRepeat + 10.0);  // measured 36.3 against 18.9 dB
}

}  // namespace
}  // namespace pc::client::test
