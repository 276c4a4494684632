// The Vulkan ray-tracing backend against the Embree backend, on lavapipe in CI with the
// validation layer on (any validation error fails). Both backends trace the same ray
// directions (same seeds) and shade with the same rules; scenes without light-sampled
// emitters have no other randomness, so after N updates the fields agree up to float
// rounding and traversal differences. Tolerance: mean relative difference <= 1% for
// irradiance and depth over probes active in both.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <glm/gtc/matrix_transform.hpp>
#include <memory>
#include <optional>
#include <thread>
#include <vector>

#include "common/field.h"
#include "common/scene.h"
#include "server/bake.h"
#include "server/embree_tracer.h"
#include "server/field_compare.h"
#include "server/net_field_loop.h"
#include "server/net_hub.h"
#include "server/vulkan_tracer.h"
#include "shaders/interop/gpu_trace.h"
#include "shaders/interop/probe_update.h"
#include "test_meshes.h"
#include "test_tracer_support.h"

namespace pc {
namespace {

// A GPU tracer on any Vulkan ray-tracing device (lavapipe in CI), with the validation layer.
std::unique_ptr<VulkanTracer> makeGpuWith(const Scene& scene, VulkanTracerOptions vo,
                                          std::string* why, const TracerOptions& options = {}) {
  vo.validation = true;
  vo.allowCpuDevice = true;
  auto t = VulkanTracer::create(scene, options, vo);
  if (!t) {
    *why = t.error().message;
    // Only a missing driver or device is a reason to skip; anything else (a shader missing
    // from the build, a failed pipeline) is a failure.
    if (why->rfind("no Vulkan", 0) != 0)
      ADD_FAILURE() << "the GPU tracer failed to start: " << *why;
    return nullptr;
  }
  return std::move(t).value();
}

std::unique_ptr<VulkanTracer> makeGpu(
    const Scene& scene, std::string* why, bool boundedShadowLaunch = false,
    const TracerOptions& options = {},
    std::size_t shadowMemoryBudget = VulkanTracerOptions{}.shadowMemoryBudget) {
  VulkanTracerOptions vo;
  vo.boundedShadowLaunch = boundedShadowLaunch;
  vo.shadowMemoryBudget = shadowMemoryBudget;
  return makeGpuWith(scene, vo, why, options);
}

// Both backends on one scene, a field for each at `rays` per probe and a request for every
// probe: what the comparisons below share. `gpu` is null where the GPU tracer did not start
// (`why` says why; makeGpu fails the test unless no device is present).
struct Backends {
  std::unique_ptr<VulkanTracer> gpu;
  std::unique_ptr<Tracer> cpu;
  Field fg, fc;
  UpdateRequest request;
};

Backends makeBackends(const Scene& scene, int rays, std::string* why,
                      const TracerOptions& options = {}) {
  Backends b;
  b.gpu = makeGpu(scene, why, false, options);
  auto cpu = makeEmbreeTracer(scene, options);
  if (!cpu) {
    ADD_FAILURE() << "the Embree tracer failed to start: " << cpu.error().message;
    b.gpu.reset();
    return b;
  }
  b.cpu = std::move(cpu).value();
  FieldSettings settings;
  settings.raysPerProbe = rays;
  b.fg = Field::create(scene.volumes, settings);
  b.fc = Field::create(scene.volumes, settings);
  b.request.probes = allProbes(b.fc);
  return b;
}

// `updates` updates of every probe on both backends, seeds firstSeed, firstSeed + 1, ...
void updateBoth(Backends& b, int updates, std::uint32_t firstSeed) {
  for (int i = 0; i < updates; ++i) {
    b.request.rotationSeed = firstSeed + std::uint32_t(i);
    updateOrFail(*b.gpu, b.fg, b.request);
    updateOrFail(*b.cpu, b.fc, b.request);
  }
}

// Every border texel of every tile the update wrote (probes not inside geometry) holds exactly
// its interior source (pcBorderSource), in each of the three atlases.
void expectBordersCopyTheirSources(const Field& f) {
  int checked = 0;
  auto tile = [&](const Atlas& atlas, glm::ivec2 origin, int n) {
    for (int by = 0; by < n + 2; ++by)
      for (int bx = 0; bx < n + 2; ++bx) {
        if (bx != 0 && by != 0 && bx != n + 1 && by != n + 1) continue;
        const glm::ivec2 src = gpu::pcBorderSource(bx, by, n) + glm::ivec2(1);
        const float* b = atlas.at(origin.x + bx, origin.y + by);
        const float* s = atlas.at(origin.x + src.x, origin.y + src.y);
        for (int ch = 0; ch < atlas.channels; ++ch)
          ASSERT_EQ(b[ch], s[ch]) << "border " << bx << "," << by << " channel " << ch;
        ++checked;
      }
  };
  for (int k = 0; k < f.cascadeCount(); ++k) {
    const gpu::CascadeDesc& c = f.cascade(k);
    for (int s = 0; s < gpu::pcSlotCount(c); ++s) {
      if (!gpu::pcSlotValid(c, s) || f.probe(k, s).state == gpu::PC_PROBE_INSIDE) continue;
      tile(f.irradiance, gpu::pcAtlasTileOrigin(c, s, gpu::PC_IRRADIANCE_TEXELS + 2),
           gpu::PC_IRRADIANCE_TEXELS);
      tile(f.depth, gpu::pcAtlasTileOrigin(c, s, gpu::PC_DEPTH_TEXELS + 2), gpu::PC_DEPTH_TEXELS);
      tile(f.occlusion, gpu::pcAtlasTileOrigin(c, s, gpu::PC_OCCLUSION_TEXELS + 2),
           gpu::PC_OCCLUSION_TEXELS);
      if (::testing::Test::HasFatalFailure()) return;
    }
  }
  EXPECT_GT(checked, 0);
}

void expectSameBrickVersions(const Field& gpu, const Field& cpu) {
  EXPECT_EQ(gpu.version, cpu.version);
  ASSERT_EQ(gpu.brickVersions.size(), cpu.brickVersions.size());
  for (std::size_t k = 0; k < cpu.brickVersions.size(); ++k)
    EXPECT_EQ(gpu.brickVersions[k], cpu.brickVersions[k]);
}

// Two GPU fields that two ways of running the same updates must leave bit for bit the same.
void expectIdenticalFields(const Field& a, const Field& b) {
  EXPECT_TRUE(a.irradiance.texels == b.irradiance.texels);
  EXPECT_TRUE(a.depth.texels == b.depth.texels);
  EXPECT_TRUE(a.occlusion.texels == b.occlusion.texels);
  expectSameBrickVersions(a, b);
}

TEST(VulkanTracer, BuiltinSceneMatchesEmbree) {
  const Scene scene = builtinScene();
  std::string why;
  auto gpu = makeGpu(scene, &why);
  if (!gpu) GTEST_SKIP() << "no Vulkan ray-tracing device: " << why;
  auto cpu = makeEmbreeTracer(scene);
  ASSERT_TRUE(cpu) << cpu.error().message;

  Field fg = Field::create(scene.volumes, FieldSettings{});
  Field fc = Field::create(scene.volumes, FieldSettings{});
  // Few updates: the comparison is exact up to rounding at any update count, and lavapipe
  // runs this in about a second per update on two cores.
  BakeOptions bake;
  bake.updates = 6;
  BakeStats sg = bakeOrFail(fg, *gpu, bake);
  BakeStats sc = bakeOrFail(fc, **cpu, bake);
  std::printf("bake: vulkan %.0f ms (%.2f Mrays/s incl. shadow rays), embree %.0f ms\n", sg.ms,
              double(sg.probeRays + sg.shadowRays) / (sg.ms * 1e3), sc.ms);
  EXPECT_EQ(sg.probeRays, sc.probeRays);
  // Shadow rays depend only on geometry and light: the same count within traversal noise.
  EXPECT_NEAR(double(sg.shadowRays), double(sc.shadowRays), 0.01 * double(sc.shadowRays));

  FieldDifference d = compareFields(fg, fc);
  std::printf(
      "builtin (%s): %d active probes, irradiance rel diff %.2e, depth rel diff %.2e, "
      "state mismatches %d\n",
      gpu->name().c_str(), d.probes, d.irradiance, d.depth, d.stateMismatches);
  EXPECT_GT(d.probes, 100);
  EXPECT_LE(d.irradiance, 0.01);
  EXPECT_LE(d.depth, 0.01);
  EXPECT_LE(d.stateMismatches, 2);
  expectSameBrickVersions(fg, fc);
  expectBordersCopyTheirSources(fg);

  // Move the light and the turning block (TLAS rebuild), then a few more updates each.
  const SceneState later = evaluateScene(scene, 3.0);
  setStateOrFail(*gpu, later);
  setStateOrFail(**cpu, later);
  UpdateRequest request;
  request.probes = allProbes(fc);
  for (int i = 0; i < 2; ++i) {
    request.rotationSeed = 5000u + std::uint32_t(i);
    UpdateStats ug = updateOrFail(*gpu, fg, request);
    UpdateStats uc = updateOrFail(**cpu, fc, request);
    EXPECT_EQ(ug.bricksChanged, uc.bricksChanged);
    EXPECT_FALSE(ug.gpuPasses.empty());
  }
  d = compareFields(fg, fc);
  std::printf("builtin after motion: irradiance rel diff %.2e, depth rel diff %.2e\n", d.irradiance,
              d.depth);
  EXPECT_LE(d.irradiance, 0.01);
  EXPECT_LE(d.depth, 0.01);
  EXPECT_EQ(gpu->validationErrorCount(), 0u);
}

TEST(VulkanTracer, FurnaceEnergyMatchesEmbreeAndTheory) {
  const float albedo = 0.5f, emission = 1.0f;
  const Scene scene = furnaceBox(albedo, emission);
  std::string why;
  auto gpu = makeGpu(scene, &why);
  if (!gpu) GTEST_SKIP() << "no Vulkan ray-tracing device: " << why;
  auto cpu = makeEmbreeTracer(scene);
  ASSERT_TRUE(cpu) << cpu.error().message;
  Field fg = Field::create(scene.volumes, FieldSettings{});
  Field fc = Field::create(scene.volumes, FieldSettings{});
  BakeOptions bake;
  bake.updates = 48;
  bakeOrFail(fg, *gpu, bake);
  bakeOrFail(fc, **cpu, bake);
  FieldDifference d = compareFields(fg, fc);
  std::printf("furnace: irradiance rel diff %.2e, depth rel diff %.2e\n", d.irradiance, d.depth);
  EXPECT_GE(d.probes, 56);  // the 8 central probes see no wall within reach: sleeping
  EXPECT_EQ(d.stateMismatches, 0);
  EXPECT_LE(d.irradiance, 0.01);
  EXPECT_LE(d.depth, 0.01);
  // Every point sees walls only: E = pi Le / (1 - a), minus what the finite bounce count lost.
  const double expected = 3.14159265358979 * emission / (1.0 - albedo);
  double sum = 0;
  int n = 0;
  for (const ProbeRef& p : allProbes(fg)) {
    sum += fetchIrradiance(fg, p.cascade, p.slot, glm::vec3(0, 1, 0)).x;
    ++n;
  }
  const double mean = sum / n;
  std::printf("furnace: GPU mean irradiance %.4f, expected %.4f\n", mean, expected);
  EXPECT_NEAR(mean, expected, 0.03 * expected);
  EXPECT_EQ(gpu->validationErrorCount(), 0u);
}

TEST(VulkanTracer, OnlyRequestedProbesChangeAndHostEditsReachTheGpu) {
  const Scene scene = builtinScene();
  std::string why;
  auto gpu = makeGpu(scene, &why);
  if (!gpu) GTEST_SKIP() << "no Vulkan ray-tracing device: " << why;
  Field f = Field::create(scene.volumes, FieldSettings{});
  UpdateRequest request;
  request.rotationSeed = 1;
  request.probes = {{0, 0}, {0, 1}, {1, 0}};
  UpdateStats s = updateOrFail(*gpu, f, request);
  EXPECT_EQ(s.probesUpdated, 3);
  EXPECT_EQ(s.bricksChanged, 2);  // brick 0 of each cascade
  EXPECT_EQ(f.version, 1u);
  EXPECT_EQ(f.brickVersions[0][0], 1u);
  EXPECT_EQ(f.brickVersions[1][0], 1u);
  EXPECT_EQ(f.brickVersions[0][1], 0u);
  EXPECT_NE(f.probe(0, 0).state, gpu::PC_PROBE_UNINITIALIZED);
  EXPECT_EQ(f.probe(0, 64).state, gpu::PC_PROBE_UNINITIALIZED);
  EXPECT_EQ(f.probe(0, 0).updates, 1u);

  // A host-side history reset must reach the GPU: the next blend starts a fresh mean.
  restartHistory(f);
  f.probe(0, 0).updates = 0;
  request.rotationSeed = 2;
  updateOrFail(*gpu, f, request);
  EXPECT_EQ(f.probe(0, 0).updates, 1u);
  EXPECT_EQ(f.probe(0, 1).updates, 2u);
  EXPECT_EQ(gpu->validationErrorCount(), 0u);
}

// Where the device launches from a buffer, the shadow rays are launched exactly as many as the
// shade pass listed; the fallback launches the most the list can hold. Each shadow ray sets only
// its own bit and the blend sums the set bits in slot order, so both give the same field to the
// bit, whatever order the list was appended in.
TEST(VulkanTracer, ExactShadowLaunchMatchesTheBoundedOne) {
  const Scene scene = builtinScene();
  std::string why;
  auto exact = makeGpu(scene, &why);
  if (!exact) GTEST_SKIP() << "no Vulkan ray-tracing device: " << why;
  if (!exact->context().rt().cmdTraceRaysIndirect)
    GTEST_SKIP() << "the device cannot launch rays from a buffer";
  auto bounded = makeGpu(scene, &why, true);
  ASSERT_TRUE(bounded) << why;

  Field fe = Field::create(scene.volumes, FieldSettings{});
  Field fb = Field::create(scene.volumes, FieldSettings{});
  BakeOptions bake;
  bake.updates = 3;
  const BakeStats se = bakeOrFail(fe, *exact, bake);
  const BakeStats sb = bakeOrFail(fb, *bounded, bake);
  EXPECT_GT(se.shadowRays, 0u);
  EXPECT_EQ(se.shadowRays, sb.shadowRays);
  expectIdenticalFields(fe, fb);
  EXPECT_EQ(exact->validationErrorCount(), 0u);
  EXPECT_EQ(bounded->validationErrorCount(), 0u);
}

}  // namespace
}  // namespace pc

namespace pc {
namespace {

// The McGuire Cornell box lights the room with a small emissive quad, sampled as a light with
// shadow rays. Both backends draw a ray's emitter samples from the same stream
// (gpu::pcRayRandomSeed: keyed by the update's seed and the ray), so after the same updates
// they hold the same field up to rounding: lavapipe measured 3.6e-7 irradiance after 2 updates
// of 8x8x8 probes, where streams drawn per probe on the CPU had left 0.66% after a 24-update
// bake. Tolerance 1e-3: far under the sampling noise two different streams would leave.
TEST(VulkanTracer, LightSampledEmittersMatchEmbree) {
  const std::string path =
      std::string(PC_SCENES_DIR) + "/mcguire-cornellbox/CornellBox-Original.obj";
  auto scene = loadScene(path);
  if (!scene) GTEST_SKIP() << "no shared scenes: " << scene.error().message;
  std::string why;
  auto gpu = makeGpu(*scene, &why);
  if (!gpu) GTEST_SKIP() << "no Vulkan ray-tracing device: " << why;
  auto cpu = makeEmbreeTracer(*scene);
  ASSERT_TRUE(cpu) << cpu.error().message;
  const FieldDifference d = bakeBothAndCompare(*scene, *gpu, **cpu, 4);
  std::printf(
      "cornell box (sampled emitter): %d active probes, irradiance rel diff %.2e, depth rel diff "
      "%.2e\n",
      d.probes, d.irradiance, d.depth);
  EXPECT_GT(d.probes, 32);
  EXPECT_LE(d.irradiance, 1e-3);
  EXPECT_LE(d.depth, 1e-3);
  EXPECT_EQ(gpu->validationErrorCount(), 0u);
}

}  // namespace
}  // namespace pc

namespace pc {
namespace {

// Static instances share one bottom-level structure with their vertices in world space; a
// mirrored static instance (front faces flip) and a second static instance of the animated
// block's mesh must shade as on the CPU. 64 rays per probe and a probe count that is no
// multiple of the launch tile also exercise the blend taps and the last, partial tile.
TEST(VulkanTracer, MirroredAndSharedStaticInstancesMatchEmbree) {
  Scene scene = builtinScene();
  glm::mat4 mirrored = glm::translate(glm::mat4(1.0f), {0.4f, 0.25f, -0.45f});
  mirrored = glm::scale(mirrored, {-0.3f, 0.5f, 0.3f});
  scene.instances.push_back({.name = "mirrored-block", .mesh = 3, .transform = mirrored});
  std::string why;
  Backends b = makeBackends(scene, 64, &why);
  if (!b.gpu) GTEST_SKIP() << "no Vulkan ray-tracing device: " << why;
  auto& [gpu, cpu, fg, fc, request] = b;
  request.probes.pop_back();  // not a whole number of launch tiles
  for (int i = 0; i < 4; ++i) {
    request.rotationSeed = 700u + std::uint32_t(i);
    const UpdateStats ug = updateOrFail(*gpu, fg, request);
    const UpdateStats uc = updateOrFail(*cpu, fc, request);
    EXPECT_EQ(ug.bricksChanged, uc.bricksChanged);
  }
  const FieldDifference d = compareFields(fg, fc);
  std::printf(
      "builtin + mirrored static block: %d active probes, irradiance rel diff %.2e, depth rel diff "
      "%.2e\n",
      d.probes, d.irradiance, d.depth);
  EXPECT_GT(d.probes, 100);
  EXPECT_LE(d.irradiance, 0.01);
  EXPECT_LE(d.depth, 0.01);
  EXPECT_LE(d.stateMismatches, 2);
  expectSameBrickVersions(fg, fc);
  EXPECT_EQ(gpu->validationErrorCount(), 0u);
}

}  // namespace
}  // namespace pc

namespace pc {
namespace {

// More shadow slots than one 32-bit mask word holds: 40 lights (points, spots and a sun, most
// of them dim) in the built-in room. The sun, the brightest, is slot 39, in each ray's second
// mask word: a blend that read only the first word measured 4.9e-2 here.
// The built-in room with 40 lights: 39 dim point and spot lights over the room (half of them
// with a range) and a sun.
Scene manyLightsScene() {
  Scene scene = builtinScene();
  const glm::vec3 lo = scene.boundsMin, hi = scene.boundsMax;
  for (int i = 0; i < 39; ++i) {
    Light l;
    l.name = "extra-" + std::to_string(i);
    l.type = i % 3 == 2 ? LightType::Spot : LightType::Point;
    const float u = float(i % 7) / 6.0f, v = float((i / 7) % 3) / 2.0f, w = float(i % 5) / 4.0f;
    l.position = glm::mix(lo, hi, glm::vec3(0.15f + 0.7f * u, 0.3f + 0.5f * v, 0.15f + 0.7f * w));
    l.direction = glm::normalize(glm::vec3(u - 0.5f, -1.0f, w - 0.5f));
    l.color = glm::vec3(0.4f + 0.6f * u, 0.7f, 1.0f - 0.5f * w);
    l.intensity = 0.05f;
    l.range = i % 2 == 0 ? 0.0f : 0.6f * glm::length(hi - lo);
    scene.lights.push_back(l);
  }
  Light sun;
  sun.name = "sun";
  sun.type = LightType::Directional;
  sun.direction = glm::normalize(glm::vec3(0.3f, -1.0f, 0.2f));
  sun.intensity = 0.5f;
  scene.lights.push_back(sun);
  return scene;
}

// Mean decoded irradiance over the field's active probes' texels.
double meanIrradiance(const Field& f) {
  double sum = 0;
  std::size_t n = 0;
  constexpr int ni = gpu::PC_IRRADIANCE_TEXELS;
  for (int k = 0; k < f.cascadeCount(); ++k) {
    const gpu::CascadeDesc& c = f.cascade(k);
    for (int s = 0; s < gpu::pcSlotCount(c); ++s) {
      if (!gpu::pcSlotValid(c, s) || f.probe(k, s).state != gpu::PC_PROBE_ACTIVE) continue;
      const glm::ivec2 o = gpu::pcAtlasTileOrigin(c, s, ni + 2);
      for (int y = 1; y <= ni; ++y)
        for (int x = 1; x <= ni; ++x) {
          const float* t = f.irradiance.at(o.x + x, o.y + y);
          const glm::vec3 e = gpu::pcDecodeIrradiance(glm::vec3(t[0], t[1], t[2]));
          sum += double(e.x + e.y + e.z) / 3.0;
          ++n;
        }
    }
  }
  return n > 0 ? sum / double(n) : 0.0;
}

TEST(VulkanTracer, ManyLightsSpanTwoMaskWordsAndMatchEmbree) {
  Scene scene = manyLightsScene();
  ASSERT_GT(scene.lights.size(), 32u);
  std::string why;
  TracerOptions everyRay;  // every light's shadow ray, so that both mask words fill
  everyRay.shadowRouletteShare = 0.0f;
  Backends b = makeBackends(scene, 32, &why, everyRay);
  if (!b.gpu) GTEST_SKIP() << "no Vulkan ray-tracing device: " << why;
  auto& [gpu, cpu, fg, fc, request] = b;
  std::uint64_t shadowRays = 0;
  for (int i = 0; i < 2; ++i) {
    request.rotationSeed = 900u + std::uint32_t(i);
    const UpdateStats ug = updateOrFail(*gpu, fg, request);
    const UpdateStats uc = updateOrFail(*cpu, fc, request);
    EXPECT_NEAR(double(ug.shadowRays), double(uc.shadowRays), 0.01 * double(uc.shadowRays));
    shadowRays += ug.shadowRays;
  }
  const FieldDifference d = compareFields(fg, fc);
  std::printf(
      "builtin + 40 lights: %llu shadow rays, irradiance rel diff %.2e, depth rel diff %.2e\n",
      static_cast<unsigned long long>(shadowRays), d.irradiance, d.depth);
  // Probe rays ask for most of the 40 lights' shadow rays (24 per probe ray on average here).
  EXPECT_GT(shadowRays, 2u * 32u * std::uint64_t(request.probes.size()) * 32u / 2u);
  EXPECT_GT(d.probes, 100);
  EXPECT_LE(d.irradiance, 0.01);
  EXPECT_LE(d.depth, 0.01);
  EXPECT_EQ(gpu->validationErrorCount(), 0u);
}

// Shadow rounds (gpu_trace.h, pcShadowRounds): with a shadow memory budget that holds 7 of the
// 40 lights' records, or a buffer range that does, the update shades and traces shadow rays in
// 6 rounds and must give the very field of one round, with the same shadow rays.
TEST(VulkanTracer, ShadowRoundsGiveTheFieldOfOneRound) {
  const Scene scene = manyLightsScene();
  TracerOptions everyRay;  // every light's shadow ray, so that every round has work
  everyRay.shadowRouletteShare = 0.0f;
  std::string why;
  auto oneRound = makeGpu(scene, &why, false, everyRay);
  if (!oneRound) GTEST_SKIP() << "no Vulkan ray-tracing device: " << why;
  FieldSettings settings;
  settings.raysPerProbe = 32;
  Field f1 = Field::create(scene.volumes, settings), fr = f1;
  UpdateRequest request;
  request.probes = allProbes(f1);
  const std::size_t slotBytes =
      request.probes.size() * 32 * (sizeof(gpu::GpuShadowRay) + sizeof(gpu::GpuShadowLight));
  // Through the factory, as the server passes its --gpu-shadow-memory.
  VulkanTracerOptions budget;
  budget.validation = true;
  budget.shadowMemoryBudget = 7 * slotBytes;
  auto made = makeTracer(scene, "vulkan", everyRay, &budget);
  ASSERT_TRUE(made) << made.error().message;
  auto* rounds = dynamic_cast<VulkanTracer*>(made.value().get());
  ASSERT_NE(rounds, nullptr);
  // The same rounds where a buffer may span no more than 7 slots' shadow rays (a device's
  // storage-buffer range), the memory budget unbounded.
  VulkanTracerOptions narrow;
  narrow.validation = true;
  narrow.allowCpuDevice = true;
  narrow.shadowMemoryBudget = std::size_t(1) << 40;
  narrow.maxStorageBufferBytes = 7 * request.probes.size() * 32 * sizeof(gpu::GpuShadowRay);
  auto ranged = VulkanTracer::create(scene, everyRay, narrow);
  ASSERT_TRUE(ranged) << ranged.error().message;
  Field fn = f1;
  std::uint64_t rays1 = 0, raysR = 0;
  for (int i = 0; i < 2; ++i) {
    request.rotationSeed = 910u + std::uint32_t(i);
    rays1 += updateOrFail(*oneRound, f1, request).shadowRays;
    const UpdateStats sn = updateOrFail(**ranged, fn, request);
    const UpdateStats s = updateOrFail(*rounds, fr, request);
    raysR += s.shadowRays;
    // Where the device has timestamps, the rounds are one timed span.
    auto has = [&](const UpdateStats& st, const char* pass) {
      return std::any_of(st.gpuPasses.begin(), st.gpuPasses.end(),
                         [&](const auto& p) { return p.first == pass; });
    };
    if (has(s, "blend")) {
      EXPECT_TRUE(has(s, "shadow rounds"));
      EXPECT_TRUE(has(sn, "shadow rounds"));
    }
  }
  std::printf("40 lights in rounds of 7: %llu shadow rays, one round %llu\n",
              static_cast<unsigned long long>(raysR), static_cast<unsigned long long>(rays1));
  EXPECT_GT(rays1, 0u);
  EXPECT_EQ(raysR, rays1);
  expectIdenticalFields(fr, f1);
  expectIdenticalFields(fn, f1);
  EXPECT_EQ(oneRound->validationErrorCount(), 0u);
  EXPECT_EQ(rounds->validationErrorCount(), 0u);
  EXPECT_EQ((*ranged)->validationErrorCount(), 0u);
}

// Shadow-ray roulette (interop/shadow_roulette.h): the GPU draws the same lights as Embree for
// the same rays, traces far fewer shadow rays than without it, and keeps the mean light (the
// weak lights that win the draw count 1/p times; without that weight most of the 40 dim lights'
// light would be lost).
TEST(VulkanTracer, ShadowRouletteMatchesEmbreeAndKeepsTheMeanLight) {
  const Scene scene = manyLightsScene();
  TracerOptions roulette;
  roulette.shadowRouletteShare = 0.25f;
  std::string why;
  Backends b = makeBackends(scene, 32, &why, roulette);
  if (!b.gpu) GTEST_SKIP() << "no Vulkan ray-tracing device: " << why;
  auto& [gpu, cpu, fg, fc, request] = b;
  TracerOptions everyRay;
  everyRay.shadowRouletteShare = 0.0f;
  auto plain = makeEmbreeTracer(scene, everyRay);
  ASSERT_TRUE(plain) << plain.error().message;
  Field fp = Field::create(scene.volumes, fc.settings);
  std::uint64_t gpuRays = 0, cpuRays = 0, plainRays = 0;
  for (int i = 0; i < 4; ++i) {
    request.rotationSeed = 700u + std::uint32_t(i);
    gpuRays += updateOrFail(*gpu, fg, request).shadowRays;
    cpuRays += updateOrFail(*cpu, fc, request).shadowRays;
    plainRays += updateOrFail(**plain, fp, request).shadowRays;
  }
  const FieldDifference d = compareFields(fg, fc);
  const double meanRoulette = meanIrradiance(fc), meanPlain = meanIrradiance(fp);
  std::printf(
      "roulette 0.25, 40 lights: shadow rays GPU %llu, Embree %llu, without roulette %llu; "
      "GPU vs Embree irradiance %.2e, depth %.2e; mean irradiance %.5f against %.5f\n",
      static_cast<unsigned long long>(gpuRays), static_cast<unsigned long long>(cpuRays),
      static_cast<unsigned long long>(plainRays), d.irradiance, d.depth, meanRoulette, meanPlain);
  EXPECT_NEAR(double(gpuRays), double(cpuRays), 0.01 * double(cpuRays));
  EXPECT_LT(double(cpuRays), 0.6 * double(plainRays));
  EXPECT_GT(d.probes, 100);
  EXPECT_LE(d.irradiance, 0.01);
  EXPECT_LE(d.depth, 0.01);
  EXPECT_NEAR(meanRoulette, meanPlain, 0.02 * meanPlain);
  EXPECT_EQ(gpu->validationErrorCount(), 0u);
}

// Cut-outs: the GPU's any-hit shader must let probe and shadow rays through the grille's open
// texels as Embree's filters do. The same grille opaque gives a field far from both, so a
// backend that ignored the cut-out would fail. The grille again with other wrap modes (its
// coordinates run to 3): the GPU's samplers must wrap as Texture::sample does.
TEST(VulkanTracer, CutOutGrilleMatchesEmbree) {
  struct Variant {
    TextureWrap u, v;
    const char* name;
  };
  std::optional<Field> repeating;  // the first variant's Embree field
  for (const Variant& variant :
       {Variant{TextureWrap::Repeat, TextureWrap::Repeat, "repeat"},
        Variant{TextureWrap::ClampToEdge, TextureWrap::MirroredRepeat, "clamp x mirror"}}) {
    const Scene scene = testmesh::grilleRoom(true, variant.u, variant.v);
    std::string why;
    Backends b = makeBackends(scene, 64, &why);
    if (!b.gpu) GTEST_SKIP() << "no Vulkan ray-tracing device: " << why;
    auto& [gpu, cpu, fg, fc, request] = b;
    const Scene solid = testmesh::grilleRoom(false);
    auto opaque = makeEmbreeTracer(solid);
    ASSERT_TRUE(opaque) << opaque.error().message;
    Field fo = Field::create(solid.volumes, fc.settings);
    for (int i = 0; i < 4; ++i) {
      request.rotationSeed = 1100u + std::uint32_t(i);
      updateOrFail(*gpu, fg, request);
      updateOrFail(*cpu, fc, request);
      updateOrFail(**opaque, fo, request);
    }
    const FieldDifference d = compareFields(fg, fc);
    const FieldDifference o = compareFields(fo, fc);
    std::printf(
        "grille room (%s): GPU vs Embree irradiance rel diff %.2e, depth %.2e; opaque "
        "grille vs cut-out %.2e, %.2e\n",
        variant.name, d.irradiance, d.depth, o.irradiance, o.depth);
    EXPECT_GT(d.probes, 100);
    EXPECT_LE(d.irradiance, 0.01) << variant.name;
    EXPECT_LE(d.depth, 0.01) << variant.name;
    EXPECT_GT(o.irradiance, 0.05);  // measured 0.11 with repeat (GPU vs Embree: 2.0e-5)
    EXPECT_EQ(gpu->validationErrorCount(), 0u);
    if (!repeating) {
      repeating = std::move(fc);
    } else {
      // The wrap modes change the field well past the bound, so a tracer that repeated
      // regardless would fail it.
      const double w = compareFields(*repeating, fc).irradiance;
      std::printf("grille room: clamp x mirror vs repeat (Embree) %.2e\n", w);
      EXPECT_GT(w, 0.02);
    }
  }
}

// Probes among one-sided cut-out cards (testmesh::cardRoom): a card's back is shaded as a
// surface on both backends (pcBackfaceIsSurface), so the fields and the probe states agree,
// and no probe among the cards is classed inside. The same cards opaque mark probes inside on
// both, which the cut-outs' figure must stay clear of.
TEST(VulkanTracer, ProbesAmongCutOutCardsMatchEmbree) {
  const Scene scene = testmesh::cardRoom(true);
  std::string why;
  Backends b = makeBackends(scene, 64, &why);
  if (!b.gpu) GTEST_SKIP() << "no Vulkan ray-tracing device: " << why;
  updateBoth(b, 3, 2100u);
  const FieldDifference d = compareFields(b.fg, b.fc);
  auto inside = [](const Field& f) {
    int n = 0;
    for (const ProbeRecord& r : f.probes) n += r.state == gpu::PC_PROBE_INSIDE ? 1 : 0;
    return n;
  };
  const Scene opaque = testmesh::cardRoom(false);
  auto solid = makeEmbreeTracer(opaque);
  ASSERT_TRUE(solid) << solid.error().message;
  Field fo = Field::create(opaque.volumes, b.fc.settings);
  for (int i = 0; i < 3; ++i) {
    b.request.rotationSeed = 2100u + std::uint32_t(i);
    updateOrFail(**solid, fo, b.request);
  }
  std::printf(
      "cut-out cards: GPU vs Embree irradiance rel diff %.2e, depth %.2e, state mismatches %d; "
      "probes inside: GPU %d, Embree %d, opaque cards %d\n",
      d.irradiance, d.depth, d.stateMismatches, inside(b.fg), inside(b.fc), inside(fo));
  EXPECT_GT(d.probes, 100);
  EXPECT_LE(d.irradiance, 0.01);
  EXPECT_LE(d.depth, 0.01);
  EXPECT_LE(d.stateMismatches, 2);
  EXPECT_LE(inside(b.fg), inside(b.fc) + 2);
  EXPECT_GT(inside(fo), inside(b.fc) + 20);
  EXPECT_EQ(b.gpu->validationErrorCount(), 0u);
}

// The wavefront's passes find a ray's records by launch index (gpu_trace.h): the blend maps
// (request, ray) back to it, so the two mappings must be inverses over whole and partial tiles.
TEST(VulkanTracer, LaunchOrderMapsBothWays) {
  for (int probes : {1, 31, 32, 33, 100}) {
    for (int rays : {1, 64, 256}) {
      std::vector<int> seen(std::size_t(probes) * rays, 0);
      for (std::uint32_t id = 0; id < std::uint32_t(probes * rays); ++id) {
        const glm::ivec2 pr = gpu::pcLaunchProbeRay(id, probes, rays);
        ASSERT_LT(pr.x, probes);
        ASSERT_LT(pr.y, rays);
        ++seen[std::size_t(pr.x) * rays + pr.y];
        EXPECT_EQ(gpu::pcProbeRayLaunchIndex(pr.x, pr.y, probes, rays), id);
      }
      for (int n : seen) EXPECT_EQ(n, 1);
    }
  }
}

// Above 256 rays a blend workgroup holds two probes' rays, above 512 one (pcBlendProbes), and
// sums them in per-probe arrays instead of the four-probe vec4 lanes: those layouts of the
// shared ray scratch must blend as the CPU does too.
TEST(VulkanTracer, BlendGroupsOfTwoAndOneProbeMatchEmbree) {
  const Scene scene = builtinScene();
  for (int rays : {512, 1024}) {
    SCOPED_TRACE(rays);
    std::string why;
    Backends b = makeBackends(scene, rays, &why);
    if (!b.gpu) GTEST_SKIP() << "no Vulkan ray-tracing device: " << why;
    auto& [gpu, cpu, fg, fc, request] = b;
    ASSERT_EQ(gpu::pcBlendProbes(rays), rays == 512 ? 2 : 1);
    updateBoth(b, 2, 900u);
    const FieldDifference d = compareFields(fg, fc);
    std::printf(
        "builtin, %d rays: %d active probes, irradiance rel diff %.2e, depth rel diff %.2e\n", rays,
        d.probes, d.irradiance, d.depth);
    EXPECT_GT(d.probes, 100);
    EXPECT_LE(d.irradiance, 0.01);
    EXPECT_LE(d.depth, 0.01);
    expectBordersCopyTheirSources(fg);
    expectSameBrickVersions(fg, fc);
    EXPECT_EQ(gpu->validationErrorCount(), 0u);
  }
}

}  // namespace
}  // namespace pc

namespace pc {
namespace {

// Probes whose grid points lie on the walls' planes (a grid aligned with the architecture),
// inside and outside the room. A ray from a point on a plane hits it at t = 0 or misses it as
// each tracer's rounding falls; probe rays start past pcProbeRayNear, so both backends see the
// same surfaces and classify and relocate these probes alike. With rays from t = 0 the room's
// on-wall probes came out in different states on the two backends.
TEST(VulkanTracer, ProbesOnWallPlanesMatchEmbree) {
  Scene scene = builtinScene();
  // Walls at x, z = +-1, floor at y = 0, ceiling at y = 2: every grid plane but x, z = +-0.5,
  // 0, +-1.5 and y = -0.5, 0.5, 1, 1.5 is a wall.
  scene.volumes = {
      {.origin = glm::vec3(-1.5f, -0.5f, -1.5f), .spacing = 0.5f, .counts = glm::ivec3(7, 6, 7)}};
  // The blocks stand a little above the floor: their bottoms on it would make rays from the
  // probes under the floor meet two surfaces at one distance, the floor's back and a block's
  // front, and which one counts is each tracer's own choice.
  for (Instance& inst : scene.instances)
    if (inst.mesh == 3)
      inst.transform = glm::translate(glm::mat4(1.0f), {0.0f, 0.01f, 0.0f}) * inst.transform;
  std::string why;
  Backends b = makeBackends(scene, 128, &why);
  if (!b.gpu) GTEST_SKIP() << "no Vulkan ray-tracing device: " << why;
  auto& [gpu, cpu, fg, fc, request] = b;
  updateBoth(b, 4, 1100u);
  int probes = 0, onWalls = 0, offsetMismatches = 0;
  const gpu::CascadeDesc& c = fc.cascade(0);
  for (int s = 0; s < gpu::pcSlotCount(c); ++s) {
    if (!gpu::pcSlotValid(c, s)) continue;
    ++probes;
    const glm::vec3 p = gpu::pcProbeGridPosition(c, gpu::pcLogicalCoord(c, gpu::pcSlotCoord(c, s)));
    const bool onWall = std::abs(std::abs(p.x) - 1.0f) < 1e-6f ||
                        std::abs(std::abs(p.z) - 1.0f) < 1e-6f || std::abs(p.y) < 1e-6f ||
                        std::abs(p.y - 2.0f) < 1e-6f;
    onWalls += onWall ? 1 : 0;
    if (glm::length(fg.probe(0, s).offset - fc.probe(0, s).offset) > 1e-4f) ++offsetMismatches;
  }
  const FieldDifference d = compareFields(fg, fc);
  std::printf(
      "probes on wall planes: %d of %d on a wall, %d active in both, state mismatches %d, offset "
      "mismatches %d, irradiance rel diff %.2e, depth rel diff %.2e\n",
      onWalls, probes, d.probes, d.stateMismatches, offsetMismatches, d.irradiance, d.depth);
  EXPECT_GT(onWalls, 100);
  EXPECT_GT(d.probes, 50);
  EXPECT_EQ(d.stateMismatches, 0);
  EXPECT_EQ(offsetMismatches, 0);
  EXPECT_LE(d.irradiance, 1e-3);
  EXPECT_LE(d.depth, 1e-3);
  EXPECT_EQ(gpu->validationErrorCount(), 0u);
}

}  // namespace
}  // namespace pc

namespace pc {
namespace {

// The built-in room 3000 units from the world's origin, where a float step is 2.4e-4: shadow
// rays that left from the hit point itself found their own triangles there (Embree's field 2.1%
// darker than at the origin, lavapipe's 9.3e-3 from Embree's); shadow rays and light both
// taken 256 steps off the surface made it 17% brighter, 16 steps 0.9%. pcShadowOrigin's 16
// steps for the shadow rays alone: 0.2% darker, 4e-5 between the backends.
TEST(VulkanTracer, RoomFarFromTheOriginLightsAsAtTheOrigin) {
  double means[3] = {0, 0, 0};
  FieldDifference far;
  const float shifts[2] = {0.0f, 3000.0f};
  for (int i = 0; i < 2; ++i) {
    const Scene scene = testmesh::shiftedRoom(shifts[i]);
    std::string why;
    Backends b = makeBackends(scene, 128, &why);
    if (!b.gpu) GTEST_SKIP() << "no Vulkan ray-tracing device: " << why;
    auto& [gpu, cpu, fg, fc, request] = b;
    updateBoth(b, 4, 1300u);
    means[i] = meanIrradiance(fc);
    if (i == 1) {
      means[2] = meanIrradiance(fg);
      far = compareFields(fg, fc);
    }
    EXPECT_EQ(gpu->validationErrorCount(), 0u);
  }
  std::printf(
      "room at the origin: mean irradiance %.5f; 3000 away: Embree %.5f, GPU %.5f; GPU vs Embree "
      "there %.2e / %.2e, state mismatches %d\n",
      means[0], means[1], means[2], far.irradiance, far.depth, far.stateMismatches);
  EXPECT_NEAR(means[1] / means[0], 1.0, 0.005);
  EXPECT_LE(far.irradiance, 1e-3);
  EXPECT_LE(far.depth, 1e-3);
  EXPECT_EQ(far.stateMismatches, 0);
}

// An update of more probe rays than one pass holds runs in slices of its probes, each lit by
// the field as the update found it (a snapshot): the field is the one pass's to the bit. The
// first slice blended must not light the next: from a fresh field, a later slice would
// otherwise see the first slice's probes initialized, and the field would differ. With 40
// lights the shadow-ray roulette draws at random, keyed by the ray's index in the whole
// request, which a slice must keep.
TEST(VulkanTracer, UpdateInSlicesGivesTheFieldOfOnePass) {
  const Scene scene = manyLightsScene();
  std::string why;
  auto onePass = makeGpu(scene, &why);
  if (!onePass) GTEST_SKIP() << "no Vulkan ray-tracing device: " << why;
  FieldSettings settings;
  settings.raysPerProbe = 32;
  Field f1 = Field::create(scene.volumes, settings), fs = f1;
  UpdateRequest all;
  all.probes = allProbes(f1);
  // Five slices (576 probes: four of 116, one of 112).
  const std::size_t perSlice = all.probes.size() / 5 + 5;
  VulkanTracerOptions vo;
  vo.validation = true;
  vo.allowCpuDevice = true;
  vo.maxPassRays = perSlice * 32;
  auto made = VulkanTracer::create(scene, TracerOptions{}, vo);
  ASSERT_TRUE(made) << made.error().message;
  VulkanTracer& slices = **made;
  // The same slices, each in shadow rounds of 7 of the 41 slots (40 lights, one emitter sample).
  vo.shadowMemoryBudget =
      7 * perSlice * 32 * (sizeof(gpu::GpuShadowRay) + sizeof(gpu::GpuShadowLight));
  auto madeRounds = VulkanTracer::create(scene, TracerOptions{}, vo);
  ASSERT_TRUE(madeRounds) << madeRounds.error().message;
  VulkanTracer& slicesInRounds = **madeRounds;
  Field fr = f1;
  // Every probe twice, then every third probe (a request that is not the field's order).
  UpdateRequest some;
  for (std::size_t i = 0; i < all.probes.size(); i += 3) some.probes.push_back(all.probes[i]);
  const UpdateRequest* requests[3] = {&all, &all, &some};
  for (int i = 0; i < 3; ++i) {
    UpdateRequest r = *requests[i];
    r.rotationSeed = 1400u + std::uint32_t(i);
    const UpdateStats a = updateOrFail(*onePass, f1, r);
    const UpdateStats b = updateOrFail(slices, fs, r);
    const UpdateStats c = updateOrFail(slicesInRounds, fr, r);
    EXPECT_EQ(c.shadowRays, a.shadowRays);
    EXPECT_EQ(b.probesUpdated, a.probesUpdated);
    EXPECT_EQ(b.probeRays, a.probeRays);
    EXPECT_EQ(b.shadowRays, a.shadowRays);
    EXPECT_EQ(b.bricksChanged, a.bricksChanged);
    // Where the device has timestamps: one snapshot an update, and only where sliced (every
    // request here, 192 probes in two slices the last).
    auto count = [](const UpdateStats& st, const char* pass) {
      return std::count_if(st.gpuPasses.begin(), st.gpuPasses.end(),
                           [&](const auto& p) { return p.first == pass; });
    };
    if (count(a, "blend") > 0) {
      EXPECT_EQ(count(a, "snapshot"), 0);
      EXPECT_EQ(count(b, "snapshot"), 1) << "update " << i;
      EXPECT_EQ(count(b, "shadow rounds"), 0);
      EXPECT_EQ(count(c, "shadow rounds"), 1) << "update " << i;
    }
  }
  expectIdenticalFields(fs, f1);
  expectIdenticalFields(fr, f1);
  ASSERT_EQ(fs.probes.size(), f1.probes.size());
  int moved = 0;
  for (std::size_t i = 0; i < f1.probes.size(); ++i) {
    EXPECT_EQ(fs.probes[i].state, f1.probes[i].state) << "probe " << i;
    EXPECT_EQ(fs.probes[i].offset, f1.probes[i].offset) << "probe " << i;
    EXPECT_EQ(fs.probes[i].updates, f1.probes[i].updates) << "probe " << i;
    moved += f1.probes[i].offset != glm::vec3(0.0f) ? 1 : 0;
  }
  std::printf("%zu probes in slices of at most %zu: %d relocated\n", all.probes.size(), perSlice,
              moved);
  EXPECT_EQ(onePass->validationErrorCount(), 0u);
  EXPECT_EQ(slices.validationErrorCount(), 0u);
  EXPECT_EQ(slicesInRounds.validationErrorCount(), 0u);
}

// The slices' size: one round of shadow slots where that leaves passes of at least 4 M rays.
TEST(VulkanTracer, PassesHoldEveryShadowSlotInOneRoundWhereLargeEnough) {
  const std::size_t perSlot = sizeof(gpu::GpuShadowRay) + sizeof(gpu::GpuShadowLight);
  const std::size_t gib = std::size_t(1) << 30, fourM = std::size_t(1) << 22;
  const std::size_t rangeRays = 4 * gib / sizeof(gpu::GpuShadowRay);
  // No shadow rays, or one slot: rounds never repeat, so the pass holds all it can.
  EXPECT_EQ(vulkanPassRays(rangeRays, 0, 8 * gib, 4 * gib), rangeRays);
  EXPECT_EQ(vulkanPassRays(rangeRays, 1, 8 * gib, 4 * gib), rangeRays);
  // Four lights: their shadow rays share one buffer, so the range bounds the pass first.
  EXPECT_EQ(vulkanPassRays(rangeRays, 4, 8 * gib, 4 * gib),
            4 * gib / (4 * sizeof(gpu::GpuShadowRay)));
  // ... and the memory budget where it is the smaller.
  EXPECT_EQ(vulkanPassRays(rangeRays, 4, gib, 4 * gib), gib / (4 * perSlot));
  // Many lights: no fewer than 4 M rays a pass; rounds take the rest.
  EXPECT_EQ(vulkanPassRays(rangeRays, 400, 8 * gib, 4 * gib), fourM);
  // Never more than the buffers hold.
  EXPECT_EQ(vulkanPassRays(1000, 4, 8 * gib, 4 * gib), 1000u);
}

// A GPU tracer whose third submission fails as a lost device's would (the failure drill), and
// a field of the scene at 32 rays per probe.
std::unique_ptr<VulkanTracer> makeFailingGpu(const Scene& scene, std::string* why) {
  VulkanTracerOptions vo;
  vo.failSubmission = 3;
  return makeGpuWith(scene, vo, why);
}

Field smallField(const Scene& scene) {
  FieldSettings settings;
  settings.raysPerProbe = 32;
  Field f = Field::create(scene.volumes, settings);
  f.sceneHash = scene.hash;
  return f;
}

// A GPU that fails (here the third submission reports VK_ERROR_DEVICE_LOST, as a lost device's
// does) fails the update with an Error naming the Tracer call, the Vulkan call and the error,
// and leaves the field as the last completed update left it, probe records included. Every
// later call is refused, naming the first failure, and the Embree backend goes on from that
// field.
TEST(VulkanTracer, AFailedUpdateLeavesTheFieldAsTheLastOneLeftIt) {
  const Scene scene = builtinScene();
  std::string why;
  auto gpu = makeFailingGpu(scene, &why);
  if (!gpu) GTEST_SKIP() << "no Vulkan ray-tracing device: " << why;
  Field f = smallField(scene);
  UpdateRequest request;
  request.probes = allProbes(f);
  for (std::uint32_t seed : {1u, 2u}) {
    request.rotationSeed = seed;
    updateOrFail(*gpu, f, request);
  }
  ASSERT_EQ(f.version, 2u);
  const Field before = f;

  request.rotationSeed = 3;
  const Result<UpdateStats> failed = gpu->update(f, request);
  ASSERT_FALSE(failed.ok());
  const std::string& message = failed.error().message;
  EXPECT_NE(message.find("update"), std::string::npos) << message;
  EXPECT_NE(message.find("vkQueueSubmit"), std::string::npos) << message;
  EXPECT_NE(message.find("VK_ERROR_DEVICE_LOST"), std::string::npos) << message;
  auto expectUnchanged = [&] {
    expectIdenticalFields(f, before);
    ASSERT_EQ(f.probes.size(), before.probes.size());
    for (std::size_t i = 0; i < f.probes.size(); ++i) {
      EXPECT_EQ(f.probes[i].state, before.probes[i].state) << "probe " << i;
      EXPECT_EQ(f.probes[i].updates, before.probes[i].updates) << "probe " << i;
      EXPECT_EQ(f.probes[i].offset, before.probes[i].offset) << "probe " << i;
    }
  };
  expectUnchanged();
  const Result<UpdateStats> again = gpu->update(f, request);
  ASSERT_FALSE(again.ok());
  EXPECT_NE(again.error().message.find("refused"), std::string::npos) << again.error().message;
  EXPECT_NE(again.error().message.find("VK_ERROR_DEVICE_LOST"), std::string::npos)
      << again.error().message;
  const Status moved = gpu->setState(evaluateScene(scene, 0.0));
  ASSERT_FALSE(moved.ok());
  EXPECT_NE(moved.error().message.find("setState"), std::string::npos) << moved.error().message;
  EXPECT_NE(moved.error().message.find("VK_ERROR_DEVICE_LOST"), std::string::npos)
      << moved.error().message;
  const Result<double> traced = gpu->traceOnly(f, request);
  EXPECT_FALSE(traced.ok());
  expectUnchanged();
  EXPECT_EQ(gpu->validationErrorCount(), 0u);

  auto cpu = makeEmbreeTracer(scene);
  ASSERT_TRUE(cpu.ok());
  updateOrFail(**cpu, f, request);
  EXPECT_EQ(f.version, 3u);
  int continued = 0;  // probes whose running mean went on from the GPU's two updates
  for (const ProbeRecord& r : f.probes) continued += r.updates == 3u;
  EXPECT_GT(continued, 0);
}

// The server's field thread through a GPU failure: the failed tick's update is redone on the
// fallback (Embree) from the field the last completed update left, and the ticks go on. With
// no fallback the field stays at that version and ticks (publishing it) go on.
TEST(VulkanTracer, FieldLoopGoesOnWithTheFallbackWhenTheGpuFails) {
  const Scene scene = builtinScene();
  for (bool withFallback : {true, false}) {
    SCOPED_TRACE(withFallback ? "with the Embree fallback" : "without a fallback");
    std::string why;
    auto gpu = makeFailingGpu(scene, &why);
    if (!gpu) GTEST_SKIP() << "no Vulkan ray-tracing device: " << why;
    Field field = smallField(scene);
    FieldHub hub(field);
    FieldLoopOptions options;
    options.rate = 10;
    if (withFallback) options.fallback = [&scene] { return makeEmbreeTracer(scene); };
    FieldLoop loop(scene, *gpu, field, hub, options);
    // A clock a tick ahead at every reading: the ticks run back to back.
    double clock = 0.0;
    std::atomic<bool> stop{false};
    std::thread thread([&] { loop.run(stop, [&clock] { return clock += 0.1; }); });
    const auto start = std::chrono::steady_clock::now();
    while (loop.stats().ticks < 6 &&
           std::chrono::steady_clock::now() - start < std::chrono::seconds(120))
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    stop = true;
    thread.join();
    const FieldLoopStats s = loop.stats();
    ASSERT_GE(s.ticks, 6u);
    EXPECT_EQ(s.tracerFailures, 1u);
    EXPECT_NE(s.lastFailure.find("VK_ERROR_DEVICE_LOST"), std::string::npos) << s.lastFailure;
    if (withFallback) {
      EXPECT_EQ(s.tracer.rfind("embree", 0), 0u) << s.tracer;
      EXPECT_EQ(s.updates, s.ticks);  // the failed tick's update was redone
      EXPECT_EQ(field.version, s.updates);
    } else {
      EXPECT_EQ(s.tracer, "");
      EXPECT_EQ(s.updates, 2u);
      EXPECT_EQ(field.version, 2u);
    }
    EXPECT_EQ(s.fieldVersion, field.version);
    EXPECT_EQ(gpu->validationErrorCount(), 0u);
  }
}

}  // namespace
}  // namespace pc
