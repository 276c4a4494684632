// The client's ambient occlusion of the indirect light against the CPU probe-lit render's
// (both shaders/interop/screen_ao.h, fed from their own surface buffers): on the block on a
// floor (common/scene_contact.h) the two images agree with it on as they do with it off, and
// both darken the contact by about as much.
#include <cstdio>

#include "common/scene_contact.h"
#include "cpu/camera.h"
#include "cpu/contact_band.h"
#include "cpu/probe_lit_render.h"
#include "cpu/render_setup.h"
#include "test_client_support.h"

namespace pc::client::test {
namespace {

constexpr int kWidth = 160, kHeight = 120;

// Mean of the 8-bit channels where `mask` is set.
double meanWhere(const Image8& image, const std::vector<bool>& mask) {
  double sum = 0;
  int n = 0;
  for (std::size_t i = 0; i < mask.size(); ++i) {
    if (!mask[i]) continue;
    for (int c = 0; c < 3; ++c) sum += image.rgb[i * 3 + c];
    n += 3;
  }
  return n ? sum / n : 0.0;
}

TEST(ClientAo, AgreesWithTheCpuRenderAndDarkensTheContactAlike) {
  auto ctx = validatingContext();
  if (!ctx) GTEST_SKIP() << "no Vulkan device";
  const Scene scene = contactScene();
  const Field field = bakeQuickly(scene, 24);
  auto setup = prepareCpuRender(scene, kWidth, kHeight, std::nullopt, 0, 0.0);
  ASSERT_TRUE(setup.ok());
  const Camera camera = setup->camera;
  const std::vector<bool> band = contactBandMask(
      traceViewSurfaces(*setup->embree, PinholeCamera(camera, kWidth, kHeight), kWidth, kHeight),
      contactSceneEdges(), 0.08f);

  double psnr[2], clientBand[2], cpuBand[2];
  for (int on = 0; on < 2; ++on) {
    const float radius = on ? gpu::PC_AO_DEFAULT_RADIUS : 0.0f;
    const ClientFrame client = renderClientFrame(*ctx, scene, &field, camera, nullptr, kWidth,
                                                 kHeight, {}, Rasterizer::Auto, true, radius);
    ASSERT_FALSE(client.display.empty());
    ProbeLitOptions lit;
    lit.width = kWidth;
    lit.height = kHeight;
    lit.primarySamples = 8;
    lit.aoRadius = radius;
    const Image8 cpu =
        tonemap(renderProbeLit(*setup->embree, setup->state, setup->emissive, field, camera, lit),
                scene.exposure);
    psnr[on] = psnr8(client.display[0], cpu);
    clientBand[on] = meanWhere(client.display[0], band);
    cpuBand[on] = meanWhere(cpu, band);
    if (on) {
      const std::filesystem::path dir = testOutputDir("client-ao");
      writePng(dir / "client.png", client.display[0]);
      writePng(dir / "cpu_probe_lit.png", cpu);
      writePng(dir / "diff_cpu.png", differenceImage(client.display[0], cpu));
    }
  }
  std::printf(
      "client vs CPU probe-lit: %.2f dB without occlusion, %.2f dB with it; contact band "
      "darkened by %.2f levels (client), %.2f (CPU)\n",
      psnr[0], psnr[1], clientBand[0] - clientBand[1], cpuBand[0] - cpuBand[1]);
  // The occlusion costs the agreement less than 1 dB.
  EXPECT_GT(psnr[1], psnr[0] - 1.0);
  EXPECT_GT(psnr[1], 30.0);
  // Both darken the contact, by amounts within a third of each other.
  const double cpuDrop = cpuBand[0] - cpuBand[1], clientDrop = clientBand[0] - clientBand[1];
  EXPECT_GT(cpuDrop, 1.0);
  EXPECT_NEAR(clientDrop, cpuDrop, cpuDrop / 3.0);
}

// The surface pass reads sample 0 of either visibility buffer: the fixed-function one (an
// image) and the compute rasterizer's (a buffer) give the same occlusion.
TEST(ClientAo, BothRasterizersGiveTheSameOcclusion) {
  auto ctx = validatingContext();
  if (!ctx) GTEST_SKIP() << "no Vulkan device";
  const Scene scene = contactScene();
  const Field field = bakeQuickly(scene, 8);
  const Camera camera = scene.cameras[0];
  ClientFrame frames[2];
  int i = 0;
  for (Rasterizer r : {Rasterizer::FixedFunction, Rasterizer::Compute}) {
    frames[i] = renderClientFrame(*ctx, scene, &field, camera, nullptr, kWidth, kHeight, {}, r);
    ASSERT_FALSE(frames[i].display.empty());
    ++i;
  }
  const double db = psnr8(frames[0].display[0], frames[1].display[0]);
  std::printf("fixed-function vs compute rasterizer, occlusion on: %.2f dB\n", db);
  EXPECT_GT(db, 40.0);
}

}  // namespace
}  // namespace pc::client::test
