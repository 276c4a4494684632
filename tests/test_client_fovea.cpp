// Foveated field sampling (RendererOptions::foveaRadius, client_indirect.comp): outside the
// fovea the field is sampled once per 2x2 quad and shared where the surface matches. The
// fovea's pixels are exactly those of full-rate sampling, the periphery stays close to them,
// and a fovea that covers the view changes nothing (lavapipe with validation).
#include <cmath>
#include <cstdio>

#include "test_client_support.h"

namespace pc::client::test {
namespace {

constexpr int kWidth = 128, kHeight = 96;

Image renderWithFovea(vk::Context& ctx, const Scene& scene, FieldMirror& mirror,
                      const Camera& camera, float foveaRadius) {
  RendererOptions ro;
  ro.width = kWidth;
  ro.height = kHeight;
  ro.foveaRadius = foveaRadius;
  auto renderer = Renderer::create(ctx, scene, mirror, ro);
  EXPECT_TRUE(renderer.ok()) << (renderer ? "" : renderer.error().message);
  if (!renderer) return Image{};
  FrameInput input;
  input.cameras[0] = camera;
  auto frame = (*renderer)->renderOffscreen(input);
  EXPECT_TRUE(frame.ok()) << (frame ? "" : frame.error().message);
  if (!frame) return Image{};
  return frame->linear[0];
}

TEST(ClientFovea, FoveaIsExactAndThePeripheryClose) {
  auto ctx = validatingContext();
  if (!ctx) GTEST_SKIP() << "no Vulkan device";
  const Scene scene = builtinScene();
  const Field field = bakeQuickly(scene, 8);
  FieldMirror mirror;
  mirror.reset(field, 0.0);
  auto camera = sceneCamera(scene, 0);
  ASSERT_TRUE(camera.ok());

  const Image full = renderWithFovea(*ctx, scene, mirror, *camera, 0.0f);
  const Image foveated = renderWithFovea(*ctx, scene, mirror, *camera, 0.4f);
  const Image covering = renderWithFovea(*ctx, scene, mirror, *camera, 2.0f);
  ASSERT_EQ(full.pixels.size(), std::size_t(kWidth * kHeight));
  ASSERT_EQ(foveated.pixels.size(), full.pixels.size());
  ASSERT_EQ(covering.pixels.size(), full.pixels.size());

  // Every 8x8 workgroup reaching within the fovea keeps full-rate sampling, bit for bit.
  int inside = 0, outsideDiffering = 0, outside = 0;
  double worst = 0.0;
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x) {
      const std::size_t i = std::size_t(y * kWidth + x);
      const glm::vec2 half(0.5f * kWidth, 0.5f * kHeight);
      const glm::vec2 lo(float(x / 8 * 8), float(y / 8 * 8));
      const glm::vec2 nearest = glm::clamp(half, lo, lo + glm::vec2(8.0f));
      const bool inFovea = glm::length((nearest - half) / half) <= 0.4f;
      if (inFovea) {
        ++inside;
        ASSERT_EQ(foveated.pixels[i], full.pixels[i]) << "pixel " << x << ", " << y;
      } else {
        ++outside;
        const glm::vec3 d = glm::abs(foveated.pixels[i] - full.pixels[i]);
        const float m = std::max(std::max(full.pixels[i].x, full.pixels[i].y), full.pixels[i].z);
        worst = std::max(worst, double(std::max(std::max(d.x, d.y), d.z) / std::max(m, 1e-3f)));
        if (d != glm::vec3(0.0f)) ++outsideDiffering;
      }
      ASSERT_EQ(covering.pixels[i], full.pixels[i]) << "pixel " << x << ", " << y;
    }
  }
  const double db = psnr8(tonemap(foveated, scene.exposure), tonemap(full, scene.exposure));
  std::printf(
      "fovea 0.4 of %dx%d: %d pixels exact inside, %d of %d outside differ (worst %.3g "
      "relative); %.2f dB against full rate\n",
      kWidth, kHeight, inside, outsideDiffering, outside, worst, db);
  EXPECT_GT(inside, 0);
  EXPECT_GT(outsideDiffering, 0) << "the periphery did not share its quads' light";
  EXPECT_GT(db, 40.0);
  EXPECT_EQ(ctx->validationErrorCount(), 0u);
}

}  // namespace
}  // namespace pc::client::test
