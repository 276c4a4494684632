// Client renderer on lavapipe with validation: golden images against the CPU probe-lit render
// of the same field and camera and against the path-traced reference, stereo against mono.
#include <cstdio>

#include "cpu/probe_lit_render.h"
#include "test_client_support.h"

namespace pc::client::test {
namespace {

constexpr int kWidth = 160, kHeight = 120;

struct Golden {
  double vsCpu = 0, vsReference = 0;
};

// Client frame vs CPU probe-lit render (same field, camera) and vs the path-traced reference.
Golden measure(const std::string& file, int updates, int spp, const std::string& slug) {
  auto scene = loadScene(scenePath(file));
  EXPECT_TRUE(scene.ok()) << (scene ? "" : scene.error().message);
  if (!scene) return {};
  auto ctx = validatingContext();
  if (!ctx) return {};
  auto camera = sceneCamera(*scene, 0);
  EXPECT_TRUE(camera.ok());
  const Field field = bakeQuickly(*scene, updates);

  const ClientFrame client =
      renderClientFrame(*ctx, *scene, &field, *camera, nullptr, kWidth, kHeight);
  if (client.display.empty()) return {};

  ProbeLitOptions lit;
  lit.width = kWidth;
  lit.height = kHeight;
  lit.primarySamples = 8;
  lit.emissiveSamples = 32;
  lit.explicitCamera = *camera;
  auto cpu = renderProbeLit(*scene, field, lit);
  EXPECT_TRUE(cpu.ok());
  PathTraceOptions pt;
  pt.width = kWidth;
  pt.height = kHeight;
  pt.spp = spp;
  pt.explicitCamera = *camera;
  auto reference = renderReference(*scene, pt);
  EXPECT_TRUE(reference.ok());
  if (!cpu || !reference) return {};

  const Image8 cpu8 = tonemap(*cpu, scene->exposure);
  const Image8 ref8 = tonemap(reference->image, scene->exposure);
  Golden g{psnr8(client.display[0], cpu8), psnr8(client.display[0], ref8)};
  const std::filesystem::path dir = std::filesystem::path(PC_BUILD_DIR) / "test-client" / slug;
  std::filesystem::create_directories(dir);
  writePng(dir / "client.png", client.display[0]);
  writePng(dir / "cpu_probe_lit.png", cpu8);
  writePng(dir / "reference.png", ref8);
  writePng(dir / "diff_cpu.png", differenceImage(client.display[0], cpu8));
  std::printf(
      "%s: client vs CPU probe-lit %.2f dB, client vs reference %.2f dB, CPU probe-lit "
      "vs reference %.2f dB (reference noise limit %.1f dB)\n",
      slug.c_str(), g.vsCpu, g.vsReference, psnr8(cpu8, ref8), reference->noisePsnr);
  return g;
}

TEST(ClientGolden, McGuireCornellBoxOriginal) {
  if (!std::filesystem::exists(scenePath("mcguire-cornellbox/CornellBox-Original.obj")))
    GTEST_SKIP() << "no shared scenes at " << PC_SCENES_DIR;
  const Golden g =
      measure("mcguire-cornellbox/CornellBox-Original.obj", 24, 256, "cornellbox-original");
  // Achieved on lavapipe: 36.5 dB vs CPU, 34.1 dB vs reference.
  EXPECT_GE(g.vsCpu, 34.5);
  EXPECT_GE(g.vsReference, 32.5);
}

TEST(ClientGolden, RtxgiCornell) {
  if (!std::filesystem::exists(scenePath("rtxgi-cornell/cornell.glb")))
    GTEST_SKIP() << "no shared scenes at " << PC_SCENES_DIR;
  const Golden g = measure("rtxgi-cornell/cornell.glb", 24, 256, "rtxgi-cornell");
  // Achieved on lavapipe: 33.6 dB vs CPU, 33.6 dB vs reference.
  EXPECT_GE(g.vsCpu, 32.0);
  EXPECT_GE(g.vsReference, 32.0);
}

TEST(ClientStereo, LeftEyeEqualsMonoRenderOfTheSamePose) {
  const Scene scene = builtinScene();
  auto ctx = validatingContext();
  if (!ctx) GTEST_SKIP() << "no Vulkan device";
  auto camera = sceneCamera(scene, 0);
  ASSERT_TRUE(camera.ok());
  const Field field = bakeQuickly(scene, 8);
  const Camera left = offsetCamera(*camera, -0.032f), right = offsetCamera(*camera, 0.032f);
  const ClientFrame stereo = renderClientFrame(*ctx, scene, &field, left, &right, kWidth, kHeight);
  const ClientFrame mono = renderClientFrame(*ctx, scene, &field, left, nullptr, kWidth, kHeight);
  ASSERT_EQ(stereo.display.size(), 2u);
  ASSERT_EQ(mono.display.size(), 1u);
  const double leftVsMono = psnr8(stereo.display[0], mono.display[0]);
  const double rightVsMono = psnr8(stereo.display[1], mono.display[0]);
  std::printf("stereo left vs mono: %.2f dB; right vs mono (must differ): %.2f dB\n", leftVsMono,
              rightVsMono);
  EXPECT_GE(leftVsMono, 50.0);
  EXPECT_LT(rightVsMono, leftVsMono);
}

TEST(ClientFallback, NoFieldGivesAnAmbientLitImage) {
  const Scene scene = builtinScene();
  auto ctx = validatingContext();
  if (!ctx) GTEST_SKIP() << "no Vulkan device";
  auto camera = sceneCamera(scene, 0);
  ASSERT_TRUE(camera.ok());
  const ClientFrame frame =
      renderClientFrame(*ctx, scene, nullptr, *camera, nullptr, kWidth, kHeight);
  ASSERT_EQ(frame.linear.size(), 1u);
  // Every surface the direct light misses still gets the ambient term: no pixel of geometry
  // is black.
  double sum = 0;
  for (const glm::vec3& p : frame.linear[0].pixels) sum += p.x + p.y + p.z;
  EXPECT_GT(sum, 0.0);
}

}  // namespace
}  // namespace pc::client::test
