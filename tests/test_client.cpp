// Client renderer on lavapipe with validation: golden images against the CPU probe-lit render
// of the same field and camera and against the path-traced reference, stereo against mono.
#include <cstdio>
#include <glm/gtc/matrix_transform.hpp>

#include "cpu/probe_lit_render.h"
#include "test_client_support.h"
#include "test_meshes.h"

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
  const std::filesystem::path dir = testOutputDir(slug);
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
  // Achieved on lavapipe: 34.4 dB vs CPU, 34.5 dB vs reference (33.6 and 33.6 before edge
  // samples were lit where they lie).
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
  // Both rasterizers: fixed-function stereo is one multiview pass, compute stereo one
  // dispatch over both views.
  for (Rasterizer rasterizer : {Rasterizer::FixedFunction, Rasterizer::Compute}) {
    const ClientFrame stereo =
        renderClientFrame(*ctx, scene, &field, left, &right, kWidth, kHeight, {}, rasterizer);
    const ClientFrame mono =
        renderClientFrame(*ctx, scene, &field, left, nullptr, kWidth, kHeight, {}, rasterizer);
    ASSERT_EQ(stereo.display.size(), 2u);
    ASSERT_EQ(mono.display.size(), 1u);
    const double leftVsMono = psnr8(stereo.display[0], mono.display[0]);
    const double rightVsMono = psnr8(stereo.display[1], mono.display[0]);
    std::printf(
        "%s rasterizer: stereo left vs mono: %.2f dB; right vs mono (must differ): %.2f dB\n",
        rasterizerName(rasterizer), leftVsMono, rightVsMono);
    EXPECT_GE(leftVsMono, 50.0);
    EXPECT_LT(rightVsMono, leftVsMono);
  }
}

// Far from the world's origin a float's step is large (1e-3 at 1e4): the client must not
// subtract large coordinates where the difference is small. Its pixel rays came from a point a
// near distance from the eye minus the eye, and its shadow lookups from world-space matrices
// whose translation cancelled against the positions: the room moved 10,000 units away showed
// bands of false shadow (18 dB against the room at the origin). Now rays come from an
// eye-relative inverse and shadow matrices work on offsets from the light.
TEST(ClientFarFromOrigin, RoomRendersAsAtTheOrigin) {
  auto ctx = validatingContext();
  if (!ctx) GTEST_SKIP() << "no Vulkan device";
  const Scene here = testmesh::shiftedRoom(0.0f), there = testmesh::shiftedRoom(10000.0f);
  const Field fieldHere = bakeQuickly(here, 4), fieldThere = bakeQuickly(there, 4);
  auto cameraHere = sceneCamera(here, 0), cameraThere = sceneCamera(there, 0);
  ASSERT_TRUE(cameraHere.ok() && cameraThere.ok());
  for (Rasterizer rasterizer : {Rasterizer::FixedFunction, Rasterizer::Compute}) {
    const ClientFrame a = renderClientFrame(*ctx, here, &fieldHere, *cameraHere, nullptr, kWidth,
                                            kHeight, {}, rasterizer);
    const ClientFrame b = renderClientFrame(*ctx, there, &fieldThere, *cameraThere, nullptr, kWidth,
                                            kHeight, {}, rasterizer);
    ASSERT_EQ(a.display.size(), 1u);
    ASSERT_EQ(b.display.size(), 1u);
    const double p = psnr8(b.display[0], a.display[0]);
    std::printf("%s rasterizer: the room 10,000 away vs at the origin: %.2f dB\n",
                rasterizerName(rasterizer), p);
    EXPECT_GE(p, 40.0);
  }
}

// The compute rasterizer draws the same visibility buffer as the fixed-function one: same
// coverage rule up to ties on edges and depth rounding, so images agree closely, mono and
// stereo, with validation quiet.
TEST(ClientComputeRaster, MatchesTheHardwareRasterizer) {
  const Scene scene = builtinScene();
  auto ctx = validatingContext();
  if (!ctx) GTEST_SKIP() << "no Vulkan device";
  auto camera = sceneCamera(scene, 0);
  ASSERT_TRUE(camera.ok());
  const Field field = bakeQuickly(scene, 8);
  const Camera left = offsetCamera(*camera, -0.032f), right = offsetCamera(*camera, 0.032f);
  const ClientFrame hardware = renderClientFrame(*ctx, scene, &field, left, &right, kWidth, kHeight,
                                                 {}, Rasterizer::FixedFunction);
  const ClientFrame compute = renderClientFrame(*ctx, scene, &field, left, &right, kWidth, kHeight,
                                                {}, Rasterizer::Compute);
  const ClientFrame computeMono = renderClientFrame(*ctx, scene, &field, left, nullptr, kWidth,
                                                    kHeight, {}, Rasterizer::Compute);
  ASSERT_EQ(hardware.display.size(), 2u);
  ASSERT_EQ(compute.display.size(), 2u);
  ASSERT_EQ(computeMono.display.size(), 1u);
  const double leftDb = psnr8(compute.display[0], hardware.display[0]);
  const double rightDb = psnr8(compute.display[1], hardware.display[1]);
  const double monoDb = psnr8(computeMono.display[0], compute.display[0]);
  std::printf(
      "compute vs fixed-function rasterizer: left %.2f dB, right %.2f dB; compute mono "
      "vs stereo left %.2f dB\n",
      leftDb, rightDb, monoDb);
  EXPECT_GE(leftDb, 40.0);
  EXPECT_GE(rightDb, 40.0);
  EXPECT_GE(monoDb, 50.0);
}

// Walls that pass behind the eye and run far past the screen's edges: the compute
// rasterizer clips them against the near plane and its guard band, and must cover what the
// fixed-function clipper covers.
TEST(ClientComputeRaster, ClipsTrianglesThatCrossTheNearPlaneLikeTheFixedFunctionPath) {
  const Scene scene = builtinScene();
  auto ctx = validatingContext();
  if (!ctx) GTEST_SKIP() << "no Vulkan device";
  const Field field = bakeQuickly(scene, 8);
  const glm::vec3 lo = scene.boundsMin, hi = scene.boundsMax, size = hi - lo;
  // A hair inside a corner, looking along one wall at a grazing angle and slightly down, with
  // a wide field of view: the wall and floor start behind the eye and reach far beyond the
  // frame.
  Camera camera;
  camera.position = glm::vec3(lo.x + 0.002f * size.x, lo.y + 0.3f * size.y, lo.z + 0.002f * size.z);
  camera.forward = glm::normalize(glm::vec3(0.15f, -0.1f, 1.0f));
  camera.yfov = 1.6f;
  const ClientFrame fixed = renderClientFrame(*ctx, scene, &field, camera, nullptr, kWidth, kHeight,
                                              {}, Rasterizer::FixedFunction);
  const ClientFrame compute = renderClientFrame(*ctx, scene, &field, camera, nullptr, kWidth,
                                                kHeight, {}, Rasterizer::Compute);
  ASSERT_EQ(fixed.display.size(), 1u);
  ASSERT_EQ(compute.display.size(), 1u);
  const double db = psnr8(compute.display[0], fixed.display[0]);
  std::printf("near-plane view, compute vs fixed-function rasterizer: %.2f dB\n", db);
  EXPECT_GE(db, 40.0);
}

TEST(ClientStereo, SideBySideHoldsBothEyesOfTheLayeredRender) {
  const Scene scene = builtinScene();
  auto ctx = validatingContext();
  if (!ctx) GTEST_SKIP() << "no Vulkan device";
  auto camera = sceneCamera(scene, 0);
  ASSERT_TRUE(camera.ok());
  FieldMirror mirror;
  FrameInput input;
  input.cameras[0] = offsetCamera(*camera, -0.032f);
  input.cameras[1] = offsetCamera(*camera, 0.032f);
  auto render = [&](bool sideBySide) {
    RendererOptions ro;
    ro.width = 80;
    ro.height = 60;
    ro.views = 2;
    ro.sideBySide = sideBySide;
    auto renderer = Renderer::create(*ctx, scene, mirror, ro);
    EXPECT_TRUE(renderer.ok()) << (renderer ? "" : renderer.error().message);
    if (!renderer) return Renderer::Readback{};
    auto frame = (*renderer)->renderOffscreen(input);
    EXPECT_TRUE(frame.ok());
    return frame ? std::move(frame).value() : Renderer::Readback{};
  };
  const Renderer::Readback layered = render(false), sideBySide = render(true);
  ASSERT_EQ(layered.display.size(), 2u);
  ASSERT_EQ(sideBySide.display.size(), 2u);
  EXPECT_EQ(sideBySide.display[0].rgb, layered.display[0].rgb);
  EXPECT_EQ(sideBySide.display[1].rgb, layered.display[1].rgb);
  EXPECT_NE(sideBySide.display[0].rgb, sideBySide.display[1].rgb);
  EXPECT_EQ(ctx->validationErrorCount(), 0u);
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

// Renders frames at the given times with one renderer; returns the last frame's images and
// the number of shadow layers each frame redrew.
struct CachedRun {
  std::vector<int> drawn;
  int layers = 0;
  Renderer::Readback last;
};
CachedRun renderAt(vk::Context& ctx, const Scene& scene, const Camera& camera,
                   std::initializer_list<double> times) {
  FieldMirror mirror;
  RendererOptions ro;
  ro.width = 96;
  ro.height = 72;
  auto renderer = Renderer::create(ctx, scene, mirror, ro);
  EXPECT_TRUE(renderer.ok()) << (renderer ? "" : renderer.error().message);
  CachedRun run;
  if (!renderer) return run;
  for (double t : times) {
    FrameInput input;
    input.time = t;
    input.cameras[0] = camera;
    auto frame = (*renderer)->renderOffscreen(input);
    EXPECT_TRUE(frame.ok());
    if (!frame) return run;
    run.drawn.push_back((*renderer)->lastStats().shadowViewsDrawn);
    run.layers = (*renderer)->lastStats().shadowViews;
    run.last = std::move(frame).value();
  }
  return run;
}

TEST(ClientShadowCache, StillFramesReuseShadowMaps) {
  const Scene scene = builtinScene();
  auto ctx = validatingContext();
  if (!ctx) GTEST_SKIP() << "no Vulkan device";
  auto camera = sceneCamera(scene, 0);
  ASSERT_TRUE(camera.ok());
  // The same moment three times, a moved light, then still again.
  const CachedRun run = renderAt(*ctx, scene, *camera, {0.0, 0.0, 0.0, 1.0, 1.0});
  ASSERT_EQ(run.drawn.size(), 5u);
  EXPECT_GT(run.layers, 0);
  EXPECT_EQ(run.drawn[0], run.layers);
  EXPECT_EQ(run.drawn[1], 0);
  EXPECT_EQ(run.drawn[2], 0);
  EXPECT_EQ(run.drawn[3], run.layers);  // the ceiling light moved: its whole cube
  EXPECT_EQ(run.drawn[4], 0);
  // Kept shadow maps give the image a fresh renderer draws at that moment.
  const CachedRun fresh = renderAt(*ctx, scene, *camera, {1.0});
  ASSERT_EQ(run.last.display.size(), 1u);
  ASSERT_EQ(fresh.last.display.size(), 1u);
  EXPECT_EQ(run.last.display[0].rgb, fresh.last.display[0].rgb);
  EXPECT_EQ(ctx->validationErrorCount(), 0u);
}

TEST(ClientShadowCache, MovingCasterRedrawsOnlyTheFacesItTouches) {
  Scene scene = builtinScene();
  for (Light& l : scene.lights) l.animation = -1;  // only the short block turns
  auto ctx = validatingContext();
  if (!ctx) GTEST_SKIP() << "no Vulkan device";
  auto camera = sceneCamera(scene, 0);
  ASSERT_TRUE(camera.ok());
  const CachedRun run = renderAt(*ctx, scene, *camera, {0.0, 1.0, 2.0});
  ASSERT_EQ(run.drawn.size(), 3u);
  EXPECT_EQ(run.drawn[0], run.layers);
  // The block sits low beside the light: some cube faces see it, not all six.
  EXPECT_GT(run.drawn[1], 0);
  EXPECT_LT(run.drawn[1], run.layers);
  const CachedRun fresh = renderAt(*ctx, scene, *camera, {2.0});
  ASSERT_EQ(run.last.display.size(), 1u);
  ASSERT_EQ(fresh.last.display.size(), 1u);
  EXPECT_EQ(run.last.display[0].rgb, fresh.last.display[0].rgb);
  EXPECT_EQ(ctx->validationErrorCount(), 0u);
}

TEST(ClientShadowCache, BoxFrustumTest) {
  // An orthographic light looking down -z over x, y in [-1, 1], depth 0..10.
  const glm::mat4 m = glm::orthoRH_ZO(-1.0f, 1.0f, -1.0f, 1.0f, 0.0f, 10.0f);
  EXPECT_TRUE(boxTouchesFrustum(m, {-0.5f, -0.5f, -2.0f}, {0.5f, 0.5f, -1.0f}));
  EXPECT_TRUE(boxTouchesFrustum(m, {0.9f, 0.9f, -2.0f}, {3.0f, 3.0f, -1.0f}));  // partly in
  EXPECT_FALSE(boxTouchesFrustum(m, {1.5f, -0.5f, -2.0f}, {2.0f, 0.5f, -1.0f}));
  EXPECT_FALSE(boxTouchesFrustum(m, {-0.5f, -0.5f, 1.0f}, {0.5f, 0.5f, 2.0f}));      // behind
  EXPECT_FALSE(boxTouchesFrustum(m, {-0.5f, -0.5f, -20.0f}, {0.5f, 0.5f, -12.0f}));  // past far
}

}  // namespace
}  // namespace pc::client::test
