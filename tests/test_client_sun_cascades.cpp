// The sun's cascaded shadow maps: how they are fitted to the camera (every visible point held,
// the near slice finer than one map over the whole scene, texels on a fixed grid), and a thin
// post's shadow far from the scene's centre drawn by the client against the visibility the
// CPU computes exactly. One map over the 100-unit yard spreads a texel over 7 cm and its filter
// over three: the 15 cm post's shadow, 42 units from the yard's centre, comes out grey.
#include <glm/gtc/matrix_transform.hpp>

#include "client/light_pack.h"
#include "cpu/camera.h"
#include "test_client_support.h"
#include "test_meshes.h"

namespace pc::client::test {
namespace {

constexpr int kMapSize = 2048;
const glm::vec3 kSun = glm::normalize(glm::vec3(0.4f, -1.0f, 0.3f));
const glm::vec3 kPostLo(30.0f, 0.0f, 30.0f), kPostHi(30.15f, 3.0f, 30.15f);

// A camera a few metres from the post, which stands 42 units from the yard's centre, looking
// down at its shadow on the floor.
Camera postCamera() {
  return lookAtCamera(glm::vec3(31.6f, 3.0f, 32.8f), glm::vec3(30.7f, 0.0f, 30.5f),
                      glm::radians(50.0f));
}

// A white yard 100 x 100 units under a sun, with a post of `postLo..postHi` (moved away, the
// same scene without its shadow in view). Black sky: the only other light is the client's
// constant ambient. `sunIntensity` 0: that ambient alone.
Scene yard(glm::vec3 postLo, glm::vec3 postHi, float sunIntensity, Camera camera = postCamera()) {
  Scene s;
  s.name = "sunlit-yard";
  s.materials = {{.name = "white", .baseColor = glm::vec3(0.8f)}};
  Mesh floor{.name = "floor", .material = 0};
  testmesh::addQuad(floor, {-50, 0, 50}, {50, 0, 50}, {50, 0, -50}, {-50, 0, -50});
  Mesh post = testmesh::boxMesh(postLo, postHi, false);
  post.name = "post";
  s.meshes = {floor, post};
  s.instances = {{.name = "floor", .mesh = 0}, {.name = "post", .mesh = 1}};
  s.lights.push_back({.name = "sun",
                      .type = LightType::Directional,
                      .direction = kSun,
                      .intensity = sunIntensity});
  s.cameras.push_back(camera);
  // Fixed bounds whichever post: the cascades and the shadow origin depend on them.
  s.boundsMin = glm::vec3(-50.0f, 0.0f, -50.0f);
  s.boundsMax = glm::vec3(50.0f, 3.0f, 50.0f);
  return s;
}

// The cascades of yard(post) for `camera` at the client's default map size.
SunCascadeMatrices cascadesFor(const Camera& camera, float aspect = 4.0f / 3.0f) {
  const glm::mat4 view = glm::lookAtRH(glm::vec3(0.0f), kSun, glm::vec3(0.0f, 1.0f, 0.0f));
  ShadowFocus focus{{camera}, aspect, 0.05f};
  return fitSunCascades(view, glm::vec3(0.0f, 60.0f, 0.0f), glm::vec3(-50.0f, 0.0f, -50.0f),
                        glm::vec3(50.0f, 3.0f, 50.0f), focus, kMapSize);
}

// World width of one texel of an orthographic cascade (its x row has length 2 / width).
float texelWidth(const glm::mat4& m) {
  return 2.0f / glm::length(glm::vec3(m[0][0], m[1][0], m[2][0])) / float(kMapSize);
}

// The first cascade that holds `p` (as the shader picks it), or -1.
int cascadeHolding(const SunCascadeMatrices& cascades, glm::vec3 p) {
  for (int c = 0; c < gpu::PC_SUN_CASCADES; ++c) {
    const glm::vec3 ndc =
        glm::vec3(cascades[std::size_t(c)] * glm::vec4(p - glm::vec3(0.0f, 60.0f, 0.0f), 1.0f));
    const glm::vec2 uv = glm::vec2(ndc) * 0.5f + 0.5f;
    if (gpu::pcSunCascadeWeight(uv, ndc.z, 1.0f / float(kMapSize)) >= 0.0f) return c;
  }
  return -1;
}

TEST(SunCascades, EveryVisiblePointIsHeldAndTheNearSliceIsFine) {
  const Camera camera = postCamera();
  const SunCascadeMatrices cascades = cascadesFor(camera);
  const float whole = 100.0f * std::sqrt(2.0f) / float(kMapSize);  // at least the whole map's
  // The floor as the camera sees it, pixel by pixel at 64 x 48.
  const PinholeCamera pinhole(camera, 64, 48);
  int held = 0, floorPixels = 0;
  float nearTexel = 0.0f;
  for (int y = 0; y < 48; ++y) {
    for (int x = 0; x < 64; ++x) {
      const glm::vec3 d = pinhole.direction(x, y);
      if (d.y >= 0.0f) continue;
      const glm::vec3 p = camera.position + d * (-camera.position.y / d.y);
      if (std::abs(p.x) > 50.0f || std::abs(p.z) > 50.0f) continue;
      ++floorPixels;
      const int c = cascadeHolding(cascades, p);
      held += c >= 0;
      if (glm::distance(p, glm::vec3(30.7f, 0.0f, 30.5f)) < 0.5f && c >= 0)
        nearTexel = std::max(nearTexel, texelWidth(cascades[std::size_t(c)]));
    }
  }
  std::printf("floor pixels %d, held %d; texel at the post's shadow %.4f, whole-scene map %.4f\n",
              floorPixels, held, nearTexel, whole);
  EXPECT_GT(floorPixels, 1000);
  EXPECT_EQ(held, floorPixels);
  EXPECT_GT(nearTexel, 0.0f);
  EXPECT_LT(nearTexel, whole / 8.0f);
  // Splits cover the range in order.
  const auto s = sunCascadeSplits(0.1f, 100.0f);
  EXPECT_EQ(s.front(), 0.1f);
  EXPECT_EQ(s.back(), 100.0f);
  for (std::size_t i = 1; i < s.size(); ++i) EXPECT_GT(s[i], s[i - 1]);
}

TEST(SunCascades, TexelsStayOnTheirGridWhileTheCameraMoves) {
  Camera camera = postCamera();
  const SunCascadeMatrices before = cascadesFor(camera);
  // A step a small share of a texel: the same maps (the shadow cache redraws nothing).
  camera.position.x += 1e-4f;
  EXPECT_EQ(cascadesFor(camera), before);
  // A step of 0.3 units: the nearest map keeps its width and moves by whole texels.
  camera.position += glm::vec3(0.3f, 0.0f, -0.2f);
  const SunCascadeMatrices after = cascadesFor(camera);
  const glm::mat4& a = before[0];
  const glm::mat4& b = after[0];
  EXPECT_NEAR(texelWidth(a), texelWidth(b), 1e-6f * texelWidth(a));
  // Map offsets in texels: the projection's translation differs by whole texels (2 / size per
  // texel in clip units).
  for (int axis = 0; axis < 2; ++axis) {
    const float texels = (b[3][axis] - a[3][axis]) * float(kMapSize) / 2.0f;
    EXPECT_NEAR(texels, std::round(texels), 0.02f) << "axis " << axis;
  }
}

// Where the ray from `o` along `d` enters the box `lo..hi` (INFINITY: it misses).
float boxHit(glm::vec3 o, glm::vec3 d, glm::vec3 lo, glm::vec3 hi) {
  float t0 = 0.0f, t1 = INFINITY;
  for (int a = 0; a < 3; ++a) {
    const float l = (lo[a] - o[a]) / d[a], h = (hi[a] - o[a]) / d[a];
    t0 = std::max(t0, std::min(l, h));
    t1 = std::min(t1, std::max(l, h));
  }
  return t0 <= t1 ? t0 : INFINITY;
}

// True when the ray from `o` along `d` meets the post.
bool hitsPost(glm::vec3 o, glm::vec3 d) { return boxHit(o, d, kPostLo, kPostHi) < INFINITY; }

struct PostShadow {
  double shadowMean = 1.0;  // the client's sun visibility where the exact one is 0
  double meanError = 1.0;   // mean |client - exact| in and around the shadow
  int shadowPixels = 0;
};

// The post's shadow in the client (`cascades` false: one map over the whole yard) against the
// exact visibility.
PostShadow measurePostShadow(vk::Context& ctx, bool cascades) {
  constexpr int w = 160, h = 120;
  const Camera camera = postCamera();
  const glm::vec3 away(-45.0f, 0.0f, -45.0f);
  ShadowSettings shadows;
  shadows.sunCascades = cascades;
  auto render = [&](const Scene& scene) {
    return renderClientFrame(ctx, scene, nullptr, camera, nullptr, w, h, shadows, Rasterizer::Auto,
                             true, 0.0f);
  };
  const ClientFrame lit = render(yard(kPostLo, kPostHi, 3.0f));
  const ClientFrame open = render(yard(away, away + (kPostHi - kPostLo), 3.0f));
  const ClientFrame dark = render(yard(kPostLo, kPostHi, 0.0f));
  if (lit.linear.size() != 1 || open.linear.size() != 1 || dark.linear.size() != 1) {
    ADD_FAILURE() << "no client frame";
    return {};
  }

  // Per floor pixel: the client's sun visibility, from its radiance between the ambient alone
  // and the open yard's, against the exact visibility averaged over 4 x 4 sub-pixel rays.
  const PinholeCamera pinhole(camera, w, h);
  double shadowSum = 0.0, errorSum = 0.0;
  int shadowPixels = 0, floorPixels = 0;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      float expected = 0.0f;
      bool floor = true;
      for (int s = 0; s < 16 && floor; ++s) {
        const glm::vec3 d =
            pinhole.direction(x, y, (float(s % 4) + 0.5f) / 4.0f, (float(s / 4) + 0.5f) / 4.0f);
        // Only pixels wholly on the floor: each sub-pixel ray meets it, not the post first.
        floor = d.y < 0.0f && !hitsPost(camera.position, d);
        const glm::vec3 p = camera.position + d * (-camera.position.y / d.y);
        expected += hitsPost(p, -kSun) ? 0.0f : 1.0f / 16.0f;
      }
      if (!floor) continue;
      const std::size_t i = std::size_t(y) * w + std::size_t(x);
      const float a = dark.linear[0].pixels[i].y, full = open.linear[0].pixels[i].y;
      if (!(full - a > 1e-3f)) continue;
      const float visibility = (lit.linear[0].pixels[i].y - a) / (full - a);
      // The shadow and its surroundings: where either side sees less than full sun.
      if (expected == 1.0f && visibility > 0.95f) continue;
      ++floorPixels;
      errorSum += std::abs(visibility - expected);
      if (expected == 0.0f) {
        ++shadowPixels;
        shadowSum += visibility;
      }
    }
  }
  PostShadow r;
  r.shadowPixels = shadowPixels;
  if (shadowPixels > 0) r.shadowMean = shadowSum / shadowPixels;
  if (floorPixels > 0) r.meanError = errorSum / floorPixels;
  std::printf(
      "%s: pixels in and around the shadow %d, in the post's full shadow %d: client visibility "
      "there %.3f (exact "
      "0); mean |error| in and around the shadow %.4f\n",
      cascades ? "cascades" : "one whole-scene map", floorPixels, shadowPixels, r.shadowMean,
      r.meanError);
  writePng(testOutputDir("sun-cascades") / (cascades ? "post.png" : "post_single_map.png"),
           lit.display[0]);
  return r;
}

TEST(ClientSunCascades, ThinPostShadowFarFromTheCentreMatchesCpuVisibility) {
  auto ctx = validatingContext();
  if (!ctx) GTEST_SKIP() << "no Vulkan device";
  const PostShadow cascaded = measurePostShadow(*ctx, true);
  const PostShadow single = measurePostShadow(*ctx, false);
  ASSERT_GT(cascaded.shadowPixels, 100);
  // Cascades (lavapipe): visibility 0.000 in the full shadow, mean error 0.032 in and around
  // it (the filter's soft edge). One map over the yard, as before cascades: 0.43 and 0.30.
  EXPECT_LT(cascaded.shadowMean, 0.1);
  EXPECT_LT(cascaded.meanError, 0.08);
  // The same bounds fail with one map: the test can tell the two apart.
  EXPECT_GT(single.shadowMean, 0.1);
  EXPECT_GT(single.meanError, 0.08);
  EXPECT_EQ(ctx->validationErrorCount(), 0u);
}

// The shadow cache with cascades: a still camera keeps every cascade, a moved one redraws
// those whose fit changed, and the kept maps give the image a fresh renderer draws.
TEST(ClientSunCascades, StillCameraKeepsTheMapsAMovedOneRedrawsThem) {
  auto ctx = validatingContext();
  if (!ctx) GTEST_SKIP() << "no Vulkan device";
  const Scene scene = yard(kPostLo, kPostHi, 3.0f);
  Camera moved = postCamera();
  moved.position += glm::vec3(1.0f, 0.0f, -0.5f);
  FieldMirror mirror;
  RendererOptions ro;
  ro.width = 96;
  ro.height = 72;
  auto renderer = Renderer::create(*ctx, scene, mirror, ro);
  ASSERT_TRUE(renderer.ok()) << (renderer ? "" : renderer.error().message);
  std::vector<int> drawn;
  int layers = 0;
  Renderer::Readback last;
  for (const Camera& camera : {postCamera(), postCamera(), moved, moved}) {
    FrameInput input;
    input.cameras[0] = camera;
    auto frame = (*renderer)->renderOffscreen(input);
    ASSERT_TRUE(frame.ok());
    drawn.push_back((*renderer)->lastStats().shadowViewsDrawn);
    layers = (*renderer)->lastStats().shadowViews;
    last = std::move(frame).value();
  }
  EXPECT_EQ(layers, gpu::PC_SUN_CASCADES);
  EXPECT_EQ(drawn, (std::vector<int>{layers, 0, drawn[2], 0}));
  EXPECT_GT(drawn[2], 0);  // at least the nearest slice's map moved
  const ClientFrame fresh = renderClientFrame(*ctx, scene, nullptr, moved, nullptr, 96, 72);
  ASSERT_EQ(last.display.size(), 1u);
  ASSERT_EQ(fresh.display.size(), 1u);
  EXPECT_EQ(last.display[0].rgb, fresh.display[0].rgb);
  EXPECT_EQ(ctx->validationErrorCount(), 0u);
}

// A wall standing on the yard, the sun behind it: the camera sees its shaded face and the
// floor in its shadow, so no pixel there may hold sunlight. Edge samples of the floor along the
// junction were lit where the pixel-centre ray meets the floor's plane, past the wall's foot:
// behind the 2 mm wall, in the sun (a bright line along every such junction, most of the 2 dB
// the RTXGI Cornell box lost).
TEST(ClientEdgeSamples, NoSunlightAlongAShadedJunction) {
  auto ctx = validatingContext();
  if (!ctx) GTEST_SKIP() << "no Vulkan device";
  const glm::vec3 wallLo(28.0f, 0.0f, 30.0f), wallHi(32.0f, 2.0f, 30.002f);  // 2 mm thin
  const Camera camera = lookAtCamera(glm::vec3(30.3f, 1.2f, 32.5f), glm::vec3(30.0f, 0.1f, 30.1f),
                                     glm::radians(50.0f));
  constexpr int w = 160, h = 120;
  auto render = [&](float sun) {
    return renderClientFrame(*ctx, yard(wallLo, wallHi, sun, camera), nullptr, camera, nullptr, w,
                             h, {}, Rasterizer::Auto, true, 0.0f);
  };
  const ClientFrame lit = render(3.0f), dark = render(0.0f);
  ASSERT_EQ(lit.linear.size(), 1u);
  ASSERT_EQ(dark.linear.size(), 1u);
  // Per pixel: the share of its 4 x 4 sub-pixel rays that end in sunlight (the floor out of
  // the wall's shadow, or a wall face the sun reaches).
  const PinholeCamera pinhole(camera, w, h);
  float sunLevel = 0.0f;
  std::vector<float> expected(std::size_t(w) * h, 0.0f);
  std::vector<char> junction(std::size_t(w) * h, 0);  // both the wall and the floor in the pixel
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      float& e = expected[std::size_t(y) * w + std::size_t(x)];
      int onWall = 0;
      for (int s = 0; s < 16; ++s) {
        const glm::vec3 d =
            pinhole.direction(x, y, (float(s % 4) + 0.5f) / 4.0f, (float(s / 4) + 0.5f) / 4.0f);
        const float tWall = boxHit(camera.position, d, wallLo, wallHi);
        const float tFloor = d.y < 0.0f ? -camera.position.y / d.y : INFINITY;
        if (tWall < tFloor) {
          ++onWall;
          // The wall's face toward the camera (+z) is turned from the sun; its ends are not.
          const glm::vec3 p = camera.position + d * tWall;
          if (p.z < wallHi.z - 1e-4f) e += 1.0f / 16.0f;
        } else if (tFloor < INFINITY) {
          const glm::vec3 p = camera.position + d * tFloor;
          if (boxHit(p, -kSun, wallLo, wallHi) == INFINITY) e += 1.0f / 16.0f;
        }
      }
      // The sun's share on the open floor: what a fully lit floor pixel gains.
      const std::size_t i = std::size_t(y) * w + std::size_t(x);
      junction[i] = onWall > 0 && onWall < 16;
      if (e == 1.0f)
        sunLevel = std::max(sunLevel, lit.linear[0].pixels[i].y - dark.linear[0].pixels[i].y);
    }
  }
  ASSERT_GT(sunLevel, 0.0f);
  // The junction's pixels (wall and floor both in them) that see no sunlit point: the sun's
  // share the client gives them.
  int pixels = 0;
  float worst = 0.0f, sum = 0.0f;
  for (std::size_t i = 0; i < expected.size(); ++i) {
    if (!junction[i] || expected[i] > 0.0f) continue;
    ++pixels;
    const float gain = (lit.linear[0].pixels[i].y - dark.linear[0].pixels[i].y) / sunLevel;
    worst = std::max(worst, gain);
    sum += gain;
  }
  const float mean = pixels > 0 ? sum / float(pixels) : 1.0f;
  std::printf(
      "junction pixels in the shade %d: sunlight among them %.4f of the open floor's on "
      "average, %.3f at most\n",
      pixels, mean, worst);
  writePng(testOutputDir("sun-cascades") / "junction.png", lit.display[0]);
  ASSERT_GT(pixels, 50);
  // Lit where a sample shows the floor: 0.018 on average (lavapipe; what is left is the shadow
  // map's own reach at the contact). Lit on the pixel-centre ray, past the wall's foot: 0.148.
  EXPECT_LT(mean, 0.05);
}

}  // namespace
}  // namespace pc::client::test
