// The field's GPU copy on lavapipe with validation: tiles and borders written on the GPU from
// uploaded interiors equal the CPU field (Field::fixBorders), a changed brick touches only its
// own tiles, and a changed brick fades from the old to the new values over the fade time.
#include <cmath>
#include <cstdio>

#include "client/field_gpu.h"
#include "test_client_support.h"

namespace pc::client::test {
namespace {

// A copy of `field` whose brick `brick` of cascade 0 holds other values (borders re-derived by
// the CPU code).
Field withChangedBrick(const Field& field, int brick) {
  Field changed = field;
  const gpu::CascadeDesc& c = changed.desc.cascades[0];
  auto change = [&](Atlas& atlas, int n, float scale, float add) {
    for (int p = 0; p < gpu::PC_PROBES_PER_BRICK; ++p) {
      const glm::ivec2 o = gpu::pcAtlasTileOrigin(c, brick * gpu::PC_PROBES_PER_BRICK + p, n + 2);
      for (int y = 1; y <= n; ++y) {
        for (int x = 1; x <= n; ++x) {
          float* t = atlas.at(o.x + x, o.y + y);
          for (int ch = 0; ch < atlas.channels; ++ch)
            t[ch] = t[ch] * scale + add + 0.01f * float(x + 3 * y + ch);
        }
      }
    }
  };
  change(changed.irradiance, gpu::PC_IRRADIANCE_TEXELS, 0.5f, 0.25f);
  change(changed.depth, gpu::PC_DEPTH_TEXELS, 1.0f, 0.1f);
  change(changed.occlusion, gpu::PC_OCCLUSION_TEXELS, 0.5f, 0.2f);
  for (int p = 0; p < gpu::PC_PROBES_PER_BRICK; ++p)
    changed.fixBorders(0, brick * gpu::PC_PROBES_PER_BRICK + p);
  return changed;
}

// Texels of `gpu` that differ from `expected` beyond the half-float rounding of the GPU
// formats (depth is float32: tight).
int mismatches(const Atlas& gpu, const Atlas& expected, float tolerance) {
  EXPECT_EQ(gpu.width, expected.width);
  EXPECT_EQ(gpu.height, expected.height);
  EXPECT_EQ(gpu.channels, expected.channels);
  if (gpu.texels.size() != expected.texels.size()) return -1;
  int bad = 0;
  for (std::size_t i = 0; i < gpu.texels.size(); ++i) {
    const float e = expected.texels[i];
    if (std::abs(gpu.texels[i] - e) > tolerance * std::max(1.0f, std::abs(e))) ++bad;
  }
  return bad;
}

// `a` mixed with `b` by `t`, texel by texel.
Atlas mixed(const Atlas& a, const Atlas& b, float t) {
  Atlas m = a;
  for (std::size_t i = 0; i < m.texels.size(); ++i)
    m.texels[i] = a.texels[i] + t * (b.texels[i] - a.texels[i]);
  return m;
}

constexpr float kHalf = 2e-3f;  // half floats: 11 significant bits
constexpr float kFloat = 1e-6f;

void expectAtlases(const FieldAtlases& gpu, const Atlas& irradiance, const Atlas& depth,
                   const Atlas& occlusion, float halfTolerance = kHalf) {
  EXPECT_EQ(mismatches(gpu.irradiance, irradiance, halfTolerance), 0);
  EXPECT_EQ(mismatches(gpu.depth, depth, kFloat + halfTolerance - kHalf), 0);
  EXPECT_EQ(mismatches(gpu.occlusion, occlusion, halfTolerance), 0);
}

TEST(ClientFieldGpu, TilesAndBordersWrittenOnTheGpuMatchTheCpuField) {
  const Scene scene = builtinScene();
  auto ctx = validatingContext();
  if (!ctx) GTEST_SKIP() << "no Vulkan device";
  const Field field = bakeQuickly(scene, 4);
  FieldMirror mirror;
  mirror.reset(field, 0.0);
  auto gpu = FieldGpu::create(*ctx, mirror.desc(), 2, 8, 0.0);
  ASSERT_TRUE(gpu.ok()) << (gpu ? "" : gpu.error().message);
  ASSERT_TRUE(gpu->uploadAll(mirror).ok());
  auto all = gpu->download();
  ASSERT_TRUE(all.ok());
  expectAtlases(*all, field.irradiance, field.depth, field.occlusion);

  // One changed brick: its tiles (borders included) take the new values, nothing else moves.
  const int brick = gpu::pcBrickCount(field.desc.cascades[0]) / 2;
  const Field changed = withChangedBrick(field, brick);
  ASSERT_TRUE(mirror.applyBrick(changed, {0, brick}, field.brickVersions[0][brick] + 1, 1.0));
  FieldUploadStats stats;
  ASSERT_TRUE(ctx->submitAndWait(
                     [&](VkCommandBuffer cmd) { stats = gpu->recordUploads(cmd, 0, mirror, 1.0); })
                  .ok());
  EXPECT_EQ(stats.bricks, 1);
  EXPECT_EQ(stats.fading, 0);
  auto after = gpu->download();
  ASSERT_TRUE(after.ok());
  expectAtlases(*after, changed.irradiance, changed.depth, changed.occlusion);
  EXPECT_EQ(ctx->validationErrorCount(), 0u);
}

TEST(ClientFieldGpu, ChangedBrickFadesInOverTheFadeTime) {
  const Scene scene = builtinScene();
  auto ctx = validatingContext();
  if (!ctx) GTEST_SKIP() << "no Vulkan device";
  auto camera = sceneCamera(scene, 0);
  ASSERT_TRUE(camera.ok());
  const Field field = bakeQuickly(scene, 4);
  FieldMirror mirror;
  mirror.reset(field, 0.0);
  RendererOptions ro;
  ro.width = 64;
  ro.height = 48;
  ro.fieldFadeSeconds = 0.2;
  auto renderer = Renderer::create(*ctx, scene, mirror, ro);
  ASSERT_TRUE(renderer.ok()) << (renderer ? "" : renderer.error().message);
  FrameInput input;
  input.cameras[0] = *camera;
  auto frameAt = [&](double clock) {
    input.clock = clock;
    auto frame = (*renderer)->renderOffscreen(input);
    EXPECT_TRUE(frame.ok());
    auto atlases = (*renderer)->fieldGpu().download();
    EXPECT_TRUE(atlases.ok());
    return atlases ? std::move(atlases).value() : FieldAtlases{};
  };
  frameAt(0.0);

  const int brick = gpu::pcBrickCount(field.desc.cascades[0]) - 1;
  const Field changed = withChangedBrick(field, brick);
  ASSERT_TRUE(mirror.applyBrick(changed, {0, brick}, field.brickVersions[0][brick] + 1, 10.0));
  // The frame that uploads it still shows the old values.
  const FieldAtlases start = frameAt(10.0);
  EXPECT_EQ((*renderer)->lastStats().bricksUploaded, 1);
  EXPECT_EQ((*renderer)->lastStats().bricksFading, 1);
  expectAtlases(start, field.irradiance, field.depth, field.occlusion);
  // A quarter and half way: the old values mixed with the new ones by 0.25 and 0.5 (the half
  // formats round each step).
  const FieldAtlases quarter = frameAt(10.05);
  expectAtlases(quarter, mixed(field.irradiance, changed.irradiance, 0.25f),
                mixed(field.depth, changed.depth, 0.25f),
                mixed(field.occlusion, changed.occlusion, 0.25f), 2 * kHalf);
  const FieldAtlases half = frameAt(10.1);
  EXPECT_EQ((*renderer)->lastStats().bricksFading, 1);
  expectAtlases(half, mixed(field.irradiance, changed.irradiance, 0.5f),
                mixed(field.depth, changed.depth, 0.5f),
                mixed(field.occlusion, changed.occlusion, 0.5f), 3 * kHalf);
  // After the fade time: the new values.
  const FieldAtlases done = frameAt(10.25);
  EXPECT_EQ((*renderer)->lastStats().bricksFading, 0);
  expectAtlases(done, changed.irradiance, changed.depth, changed.occlusion);
  EXPECT_EQ(ctx->validationErrorCount(), 0u);
}

}  // namespace
}  // namespace pc::client::test
