// The client's probe debug view (client_probe_view.comp): a golden image of the built-in
// scene with the probes drawn as spheres lit by their irradiance, the view against the same
// frame without it (it must draw something), the state colours, and bricks that flash when
// their version changes.
//
// The golden image is tests/golden/probe_view_irradiance.png (160x120). To write it anew after
// a deliberate change to the view, run this test with PC_UPDATE_GOLDEN=1 in the environment:
//   PC_UPDATE_GOLDEN=1 build/bin/test_client_probe_view
// and look at the image before committing it.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>

#include "common/image.h"
#include "test_client_support.h"

namespace pc::client::test {
namespace {

constexpr int kWidth = 160, kHeight = 120;
// Images of the same frame on other Vulkan drivers differ by rounding and filtering; a view
// that draws different probes, or none, falls far below this.
constexpr double kGoldenMinPsnr = 30.0;

std::filesystem::path goldenPath() {
  return std::filesystem::path(PC_SOURCE_DIR) / "tests" / "golden" / "probe_view_irradiance.png";
}

// Mean absolute difference over all channels, in 8-bit steps.
double meanAbsDifference(const Image8& a, const Image8& b) {
  if (a.rgb.size() != b.rgb.size() || a.rgb.empty()) return 255.0;
  double sum = 0;
  for (std::size_t i = 0; i < a.rgb.size(); ++i) sum += std::abs(int(a.rgb[i]) - int(b.rgb[i]));
  return sum / double(a.rgb.size());
}

double meanValue(const Image8& a) {
  double sum = 0;
  for (unsigned char v : a.rgb) sum += v;
  return a.rgb.empty() ? 0.0 : sum / double(a.rgb.size());
}

// One renderer over one mirror, frames rendered with chosen probe views and clocks.
struct ProbeViewRig {
  vk::Context& ctx;
  Scene scene = builtinScene();
  Field field = bakeQuickly(scene, 4);
  FieldMirror mirror;
  std::unique_ptr<Renderer> renderer;
  Camera camera;

  // `offset`: every probe moved by this share of its spacing along +x and +y (relocation).
  explicit ProbeViewRig(vk::Context& c, float offset = 0.0f,
                        Rasterizer rasterizer = Rasterizer::Auto)
      : ctx(c) {
    for (int k = 0; k < field.cascadeCount(); ++k)
      for (int slot = 0; slot < gpu::pcSlotCount(field.cascade(k)); ++slot)
        if (offset != 0.0f)
          field.probe(k, slot).offset = glm::vec3(offset, offset, 0.0f) * field.cascade(k).spacing;
    mirror.reset(field, 0.0);
    camera = sceneCamera(scene, 0).value();
    RendererOptions ro;
    ro.width = kWidth;
    ro.height = kHeight;
    ro.rasterizer = rasterizer;
    auto r = Renderer::create(ctx, scene, mirror, ro);
    EXPECT_TRUE(r.ok()) << (r ? "" : r.error().message);
    if (r) renderer = std::move(r).value();
  }

  Image8 frame(ProbeViewSettings view, double clock = 0.0) {
    FrameInput input;
    input.cameras[0] = camera;
    input.probeView = view;
    input.clock = clock;
    auto images = renderer->renderOffscreen(input);
    EXPECT_TRUE(images.ok()) << (images ? "" : images.error().message);
    if (!images) return {};
    return images->display[0];
  }
};

ProbeViewSettings viewOf(ProbeViewMode mode) {
  ProbeViewSettings v;
  v.mode = mode;
  return v;
}

}  // namespace

TEST(ClientProbeView, IrradianceSpheresMatchTheGoldenImage) {
  auto ctx = validatingContext();
  if (!ctx) GTEST_SKIP() << "no Vulkan device";
  ProbeViewRig rig(*ctx);
  ASSERT_TRUE(rig.renderer);
  const Image8 off = rig.frame(viewOf(ProbeViewMode::Off));
  const Image8 irradiance = rig.frame(viewOf(ProbeViewMode::Irradiance));
  const Image8 state = rig.frame(viewOf(ProbeViewMode::State));
  ProbeViewSettings coarse = viewOf(ProbeViewMode::State);
  coarse.cascade = rig.field.cascadeCount() - 1;
  const Image8 oneCascade = rig.frame(coarse);
  const std::filesystem::path out = testOutputDir("probe_view");
  for (const auto& [name, image] : {std::pair{"off", &off},
                                    {"irradiance", &irradiance},
                                    {"state", &state},
                                    {"coarsest", &oneCascade}})
    ASSERT_TRUE(writePng(out / (std::string(name) + ".png"), *image).ok());

  // The view draws something, and each mode something else.
  const double drawn = meanAbsDifference(off, irradiance);
  const double recoloured = meanAbsDifference(irradiance, state);
  const double fewer = meanAbsDifference(state, oneCascade);
  std::printf("mean |view - no view| %.2f, |irradiance - state| %.2f, |all - coarsest| %.2f\n",
              drawn, recoloured, fewer);
  EXPECT_GT(drawn, 2.0) << "the probe view drew (almost) nothing";
  EXPECT_GT(recoloured, 1.0) << "state colours look like the irradiance view";
  EXPECT_GT(fewer, 0.5) << "choosing one cascade changed nothing";

  if (std::getenv("PC_UPDATE_GOLDEN")) {
    ASSERT_TRUE(writePng(goldenPath(), irradiance).ok());
    std::printf("wrote %s\n", goldenPath().string().c_str());
    return;
  }
  auto golden = readPng(goldenPath());
  ASSERT_TRUE(golden.ok()) << golden.error().message << " (PC_UPDATE_GOLDEN=1 writes it)";
  ASSERT_EQ(golden->width, irradiance.width);
  ASSERT_EQ(golden->height, irradiance.height);
  const double psnr = psnr8(irradiance, *golden);
  std::printf("PSNR against the golden image %.2f dB (view off: %.2f dB)\n", psnr,
              psnr8(off, *golden));
  EXPECT_GE(psnr, kGoldenMinPsnr) << "see " << (out / "irradiance.png").string();
  // The golden image itself must tell the view from no view.
  EXPECT_LT(psnr8(off, *golden), kGoldenMinPsnr);
  EXPECT_EQ(ctx->validationErrorCount(), 0u);
}

TEST(ClientProbeView, BricksFlashWhenTheirVersionChanges) {
  auto ctx = validatingContext();
  if (!ctx) GTEST_SKIP() << "no Vulkan device";
  ProbeViewRig rig(*ctx);
  ASSERT_TRUE(rig.renderer);
  const ProbeViewSettings view = viewOf(ProbeViewMode::State);
  const Image8 before = rig.frame(view, 0.0);  // the versions first seen: no flash
  // Every brick arrives again, unchanged but newer: only the flash tells.
  for (int k = 0; k < rig.field.cascadeCount(); ++k)
    for (std::size_t b = 0; b < rig.field.brickVersions[k].size(); ++b)
      ASSERT_TRUE(rig.mirror.applyBrick(rig.field, {k, int(b)}, rig.field.version + 1, 1.0));
  const Image8 flashing = rig.frame(view, 1.0 + 0.1 * gpu::PC_PROBE_VIEW_FLASH_SECONDS);
  const Image8 after = rig.frame(view, 1.0 + 2.0 * gpu::PC_PROBE_VIEW_FLASH_SECONDS);
  std::printf("mean value before %.2f, flashing %.2f, after %.2f\n", meanValue(before),
              meanValue(flashing), meanValue(after));
  EXPECT_GT(meanValue(flashing), meanValue(before) + 2.0);
  EXPECT_LT(meanAbsDifference(before, after), 0.5) << "the flash did not end";
  EXPECT_EQ(ctx->validationErrorCount(), 0u);
}

TEST(ClientProbeView, RelocationLinesLeadFromGridPointsToProbes) {
  auto ctx = validatingContext();
  if (!ctx) GTEST_SKIP() << "no Vulkan device";
  ProbeViewRig rig(*ctx, 0.3f);
  ASSERT_TRUE(rig.renderer);
  ProbeViewSettings view = viewOf(ProbeViewMode::State);
  const Image8 lines = rig.frame(view);
  view.offsets = false;
  const Image8 none = rig.frame(view);
  ASSERT_TRUE(writePng(testOutputDir("probe_view") / "lines.png", lines).ok());
  const double drawn = meanAbsDifference(lines, none);
  std::printf("mean |lines - no lines| %.2f\n", drawn);
  EXPECT_GT(drawn, 0.5) << "no relocation lines drawn";
  EXPECT_EQ(ctx->validationErrorCount(), 0u);
}

// The view reads the scene's depth from either rasterizer's visibility samples.
TEST(ClientProbeView, BothRasterizersHideTheSameProbes) {
  auto ctx = validatingContext();
  if (!ctx) GTEST_SKIP() << "no Vulkan device";
  Image8 images[2];
  const Rasterizer rasterizers[2] = {Rasterizer::FixedFunction, Rasterizer::Compute};
  for (int i = 0; i < 2; ++i) {
    ProbeViewRig rig(*ctx, 0.0f, rasterizers[i]);
    ASSERT_TRUE(rig.renderer);
    images[i] = rig.frame(viewOf(ProbeViewMode::State));
  }
  const double db = psnr8(images[0], images[1]);
  std::printf("fixed-function vs compute rasterizer, state view: %.2f dB\n", db);
  EXPECT_GE(db, 35.0);
  EXPECT_EQ(ctx->validationErrorCount(), 0u);
}

TEST(ProbeViewFlash, FirstVersionsAreTheBaselineAndChangesFadeOut) {
  Field field = Field::create({ProbeVolume{glm::vec3(0.0f), 1.0f, glm::ivec3(8)}}, {});
  FieldMirror mirror;
  mirror.reset(field, 0.0);
  BrickFlash flash;
  const std::vector<float> first = flash.update(mirror, 0.0);
  ASSERT_EQ(first.size(), 8u);  // 2x2x2 bricks
  for (float f : first) EXPECT_EQ(f, 0.0f);
  ASSERT_TRUE(mirror.applyBrick(field, {0, 3}, 5, 1.0));
  const float half = 0.5f * gpu::PC_PROBE_VIEW_FLASH_SECONDS;
  EXPECT_FLOAT_EQ(flash.update(mirror, 1.0)[3], 1.0f);
  const std::vector<float> mid = flash.update(mirror, 1.0 + half);
  EXPECT_NEAR(mid[3], 0.5f, 1e-4f);
  EXPECT_EQ(mid[2], 0.0f);
  EXPECT_EQ(flash.update(mirror, 1.0 + 2 * half)[3], 0.0f);
  EXPECT_EQ(nextProbeViewCascade(-1, 3), 0);
  EXPECT_EQ(nextProbeViewCascade(2, 3), -1);
  EXPECT_EQ(parseProbeViewMode("state"), ProbeViewMode::State);
  EXPECT_FALSE(parseProbeViewMode("sideways"));
}

}  // namespace pc::client::test
