// Image quality floors on the shared scenes: the probe-lit render (direct light + indirect
// from a baked field) against the path-traced reference, and light leaking into a sealed
// room. Sized for CI (small images, a modest reference); the benchmarks (`probecast-bench
// quality`, `probecast-bench leak`) measure the same at full size. Skipped where the shared
// scenes folder is absent.
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>

#include "common/field.h"
#include "common/image.h"
#include "common/scene.h"
#include "cpu/path_tracer.h"
#include "cpu/probe_lit_render.h"
#include "server/bake.h"
#include "server/embree_tracer.h"
#include "test_meshes.h"
#include "test_timing.h"

namespace pc {
namespace {

namespace fs = std::filesystem;

double secondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// Sets `path` to a scene in the shared scenes folder, or leaves it empty and marks the test
// skipped when the scene is absent. A scene that is there but fails to load is a failure.
void findSharedScene(const std::string& relative, fs::path& path) {
  const fs::path candidate = fs::path(PC_SCENES_DIR) / relative;
  if (!fs::exists(candidate)) {
    GTEST_SKIP() << "shared scene " << candidate.string()
                 << " is absent (the shared scenes folder is not available here)";
  }
  path = candidate;
}

// Bakes the scene's field from its volumes (the sidecar's, or the defaults) as the bake tool
// and the benchmarks do.
Result<Field> bake(const Scene& scene, int updates) {
  const std::vector<ProbeVolume> volumes =
      scene.volumes.empty() ? defaultVolumes(scene) : scene.volumes;
  Field field = Field::create(volumes, FieldSettings{});
  field.sceneHash = scene.hash;
  auto tracer = makeEmbreeTracer(scene);
  if (!tracer) return tracer.error();
  BakeOptions options;
  options.updates = updates;
  auto baked = bakeField(field, **tracer, options);
  if (!baked) return baked.error();
  return field;
}

struct QualityResult {
  double psnr = 0;            // probe-lit vs reference, tone-mapped 8-bit
  double referenceNoise = 0;  // the reference's own expected PSNR against its noise-free limit
};

// Camera 0 at `width` x `height`: bake, render probe-lit, path-trace the reference, compare.
QualityResult measureQuality(const Scene& scene, int width, int height, int spp, int updates) {
  QualityResult q;
  auto t0 = std::chrono::steady_clock::now();
  auto field = bake(scene, updates);
  EXPECT_TRUE(field.ok()) << (field.ok() ? "" : field.error().message);
  if (!field) return q;
  const double bakeSeconds = secondsSince(t0);

  t0 = std::chrono::steady_clock::now();
  ProbeLitOptions lit;
  lit.width = width;
  lit.height = height;
  lit.primarySamples = 4;  // as the quality benchmark: anti-aliasing comparable to the reference's
  lit.emissiveSamples = 32;
  lit.camera = 0;
  auto probeLit = renderProbeLit(scene, *field, lit);
  EXPECT_TRUE(probeLit.ok()) << (probeLit.ok() ? "" : probeLit.error().message);
  if (!probeLit) return q;
  const double litSeconds = secondsSince(t0);

  t0 = std::chrono::steady_clock::now();
  PathTraceOptions pt;
  pt.width = width;
  pt.height = height;
  pt.spp = spp;
  pt.camera = 0;
  auto reference = renderReference(scene, pt);
  EXPECT_TRUE(reference.ok()) << (reference.ok() ? "" : reference.error().message);
  if (!reference) return q;
  const double refSeconds = secondsSince(t0);

  q.psnr = psnr8(tonemap(*probeLit, scene.exposure), tonemap(reference->image, scene.exposure));
  q.referenceNoise = reference->noisePsnr;
  std::printf(
      "%s %dx%d: PSNR %.2f dB (probe-lit vs %d spp reference), reference noise PSNR %.2f dB; "
      "bake %.1f s (%d probes, %d updates), probe-lit %.1f s, reference %.1f s\n",
      scene.name.c_str(), width, height, q.psnr, spp, q.referenceNoise, bakeSeconds,
      field->probeCount(), updates, litSeconds, refSeconds);
  return q;
}

// CI size: 128 x 96 and a 32-update bake. At this size PSNR saturates by 32 updates (31.4 and
// 33.4 dB; 64 and 128 updates measure the same within 0.03 dB). The reference takes 256 spp:
// its noise (37.5 and 40.3 dB) is then a small part of the measured error, yet it renders in
// a few seconds.
constexpr int kWidth = 128, kHeight = 96, kSpp = 256, kUpdates = 32;

void checkQualityFloor(const std::string& relative, double floorDb) {
  fs::path path;
  findSharedScene(relative, path);
  if (path.empty()) return;
  auto scene = loadScene(path);  // finds the sidecar in data/sidecars
  ASSERT_TRUE(scene.ok()) << scene.error().message;
  const QualityResult q = measureQuality(*scene, kWidth, kHeight, kSpp, kUpdates);
  std::printf("floor %.2f dB\n", floorDb);
  // The reference's own noise must not decide the comparison: its PSNR against its noise-free
  // limit sits at least 3 dB above the floor, so at the floor at most half of the measured
  // error can be the reference's noise.
  EXPECT_GT(q.referenceNoise, floorDb + 3.0) << "reference too noisy for this floor";
  EXPECT_GE(q.psnr, floorDb) << relative << ": probe-lit quality regressed";
}

// Floors: 1 dB under what this size measures (31.4 dB and 33.4 dB; the goal at benchmark
// size is >= 30 dB). A real regression in tracing, shading, blending or sampling costs more
// than that, while run-to-run variation is nil: every render is seeded, so only floating-point
// differences between machines (Embree's code paths per instruction set) remain.
TEST(Quality, McGuireCornellBoxOriginal) {
  test::ScopedTestTimer timer;
  checkQualityFloor("mcguire-cornellbox/CornellBox-Original.obj", 30.4);
}

TEST(Quality, RtxgiCornell) {
  test::ScopedTestTimer timer;
  checkQualityFloor("rtxgi-cornell/cornell.glb", 32.4);
}

// ---- leaks ------------------------------------------------------------------------------------

int findCamera(const Scene& scene, const std::string& word) {
  for (std::size_t i = 0; i < scene.cameras.size(); ++i) {
    std::string name = scene.cameras[i].name;
    std::transform(name.begin(), name.end(), name.begin(),
                   [](unsigned char c) { return char(std::tolower(c)); });
    if (name.find(word) != std::string::npos) return int(i);
  }
  return -1;
}

double meanLuminance(const Image& image) {
  double sum = 0;
  for (const glm::vec3& p : image.pixels) sum += 0.2126 * p.x + 0.7152 * p.y + 0.0722 * p.z;
  return image.pixels.empty() ? 0.0 : sum / double(image.pixels.size());
}

// rtxgi-two-rooms is lit by the sun alone and its closed room is sealed: no light path reaches
// it, so whatever its camera sees in the probe-lit render is light leaking through walls from
// probes that see the sunlit room or the outside. The goal of the foundation issue: <= 1% of
// the open room's mean luminance with visibility weighting; the naive trilinear field
// (PC_SAMPLE_NO_VISIBILITY) is printed beside it and must leak more.
TEST(Quality, SealedRoomDoesNotLeak) {
  test::ScopedTestTimer timer;
  const auto t0 = std::chrono::steady_clock::now();
  fs::path path;
  findSharedScene("rtxgi-two-rooms/two-rooms.glb", path);
  if (path.empty()) return;
  auto scene = loadScene(path);
  ASSERT_TRUE(scene.ok()) << scene.error().message;
  const int closed = findCamera(*scene, "closed"), open = findCamera(*scene, "open");
  ASSERT_GE(closed, 0) << "the sidecar names a closed-room camera";
  ASSERT_GE(open, 0) << "the sidecar names an open-room camera";

  // 8 updates: the depth moments that visibility relies on are set by the first update, and
  // fewer bounces leave the open room darker, which only makes the ratio stricter.
  const int updates = 8;
  auto field = bake(*scene, updates);
  ASSERT_TRUE(field.ok()) << field.error().message;
  const double bakeSeconds = secondsSince(t0);

  double mean[2][2];  // [naive][closed, open]
  for (int naive = 0; naive < 2; ++naive) {
    for (int which = 0; which < 2; ++which) {
      ProbeLitOptions lit;
      lit.width = 96;
      lit.height = 72;
      lit.primarySamples = 2;
      lit.camera = which == 0 ? closed : open;
      lit.sampleFlags = naive ? gpu::PC_SAMPLE_NO_VISIBILITY : gpu::PC_SAMPLE_DEFAULT;
      auto image = renderProbeLit(*scene, *field, lit);
      ASSERT_TRUE(image.ok()) << image.error().message;
      mean[naive][which] = meanLuminance(*image);
    }
  }
  ASSERT_GT(mean[0][1], 0.0) << "the open room must be lit";
  const double ratio = mean[0][0] / mean[0][1];
  const double naiveRatio = mean[1][0] / std::max(mean[1][1], 1e-30);
  std::printf(
      "two-rooms leak (%d probes, %d updates, bake %.1f s): closed/open mean luminance "
      "%.3g%% with visibility (%.4g / %.4g), %.3g%% naive (%.4g / %.4g)\n",
      field->probeCount(), updates, bakeSeconds, 100 * ratio, mean[0][0], mean[0][1],
      100 * naiveRatio, mean[1][0], mean[1][1]);
  // The scene must exercise leaking at all: without visibility the closed room picks up a
  // large share (about 29% at this size) of the open room's light from probes beyond its walls.
  EXPECT_GT(naiveRatio, 0.05) << "the naive field no longer leaks: the test lost its teeth";
  EXPECT_LT(ratio, naiveRatio) << "visibility weighting must leak less than the naive field";
  EXPECT_LE(ratio, 0.01) << "goal: the sealed room sees at most 1% of the open room's light";
}

double meanRadiance(const Image& image) {
  double sum = 0.0;
  for (const glm::vec3& p : image.pixels) sum += double(p.x + p.y + p.z) / 3.0;
  return sum / double(image.pixels.size());
}

// The reference and the probe-lit render light a room far from the world's origin as at it:
// the built-in room 3000 units out, where a float step is 2.4e-4. With their secondary rays
// leaving 256 float steps of the hit point's own coordinates off the surface, and the lights
// evaluated there, the reference rendered it 7.7% brighter than at the origin (the probe-lit
// render likewise); now both leave from pcShadowOrigin with the lights at the hit point.
TEST(Quality, RoomFarFromTheOriginRendersAsAtTheOrigin) {
  double reference[2] = {0, 0}, probeLit[2] = {0, 0};
  for (int i = 0; i < 2; ++i) {
    const Scene scene = testmesh::shiftedRoom(i == 0 ? 0.0f : 3000.0f);
    PathTraceOptions pt;
    pt.width = 96;
    pt.height = 54;
    pt.spp = 64;
    auto ref = renderReference(scene, pt);
    ASSERT_TRUE(ref.ok()) << ref.error().message;
    reference[i] = meanRadiance(ref->image);
    auto field = bake(scene, 8);
    ASSERT_TRUE(field.ok()) << field.error().message;
    ProbeLitOptions lit;
    lit.width = pt.width;
    lit.height = pt.height;
    lit.primarySamples = 2;
    auto image = renderProbeLit(scene, *field, lit);
    ASSERT_TRUE(image.ok()) << image.error().message;
    probeLit[i] = meanRadiance(*image);
  }
  std::printf(
      "mean radiance at the origin / 3000 away: reference %.5f / %.5f, probe-lit %.5f / %.5f\n",
      reference[0], reference[1], probeLit[0], probeLit[1]);
  EXPECT_NEAR(reference[1] / reference[0], 1.0, 0.01);
  EXPECT_NEAR(probeLit[1] / probeLit[0], 1.0, 0.01);
}

}  // namespace
}  // namespace pc
