// "Never black": no surface a camera sees may go without indirect light because the probes
// around it hold no data (inside geometry, untraced). Counted per pixel by
// measureIndirectCoverage on every shared scene and on constructed cases where the fallbacks
// of probe_sampling.h (coarser cascade, the nearest probes with data, the ambient term) or the
// classification of probes among cut-out cards (pcBackfaceIsSurface) are what keeps them lit.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "common/field.h"
#include "common/scene.h"
#include "cpu/indirect_coverage.h"
#include "server/bake.h"
#include "server/embree_tracer.h"
#include "shaders/interop/field_desc.h"
#include "test_meshes.h"

namespace pc {
namespace {

namespace fs = std::filesystem;

// A field as the bake tool makes it, but short (few updates and rays): classification and
// coverage settle in the first update; the light's exact value does not matter here.
Field bakeShort(const Scene& scene, int updates = 2, int rays = 64) {
  const std::vector<ProbeVolume> volumes =
      scene.volumes.empty() ? defaultVolumes(scene) : scene.volumes;
  FieldSettings settings;
  settings.raysPerProbe = rays;
  Field field = Field::create(volumes, settings);
  field.sceneHash = scene.hash;
  auto tracer = makeEmbreeTracer(scene);
  EXPECT_TRUE(tracer) << (tracer ? "" : tracer.error().message);
  if (!tracer) return field;
  BakeOptions options;
  options.updates = updates;
  auto baked = bakeField(field, **tracer, options);
  EXPECT_TRUE(baked) << (baked ? "" : baked.error().message);
  return field;
}

IndirectCoverage coverageOf(const Scene& scene, const Field& field, int flags,
                            const std::optional<Camera>& camera = std::nullopt, int width = 64,
                            int height = 48) {
  auto c = measureIndirectCoverage(scene, field, camera, 0, width, height, flags);
  EXPECT_TRUE(c) << (c ? "" : c.error().message);
  return c ? *c : IndirectCoverage{};
}

int probesInside(const Field& field) {
  int n = 0;
  for (const ProbeRecord& r : field.probes) n += r.state == gpu::PC_PROBE_INSIDE ? 1 : 0;
  return n;
}

// Every scene file of the shared scenes folder (all McGuire variants included).
std::vector<fs::path> sharedSceneFiles() {
  std::vector<fs::path> files;
  for (const auto& dir : fs::directory_iterator(PC_SCENES_DIR)) {
    if (!dir.is_directory()) continue;
    for (const auto& e : fs::directory_iterator(dir.path())) {
      const std::string ext = e.path().extension().string();
      if (ext == ".glb" || ext == ".gltf" || ext == ".obj") files.push_back(e.path());
    }
  }
  std::sort(files.begin(), files.end());
  return files;
}

TEST(NeverBlack, NoSharedScenePixelLacksIndirectLight) {
  if (!fs::is_directory(PC_SCENES_DIR))
    GTEST_SKIP() << "the shared scenes folder " << PC_SCENES_DIR
                 << " is absent: no shared scene to count black pixels on";
  int measured = 0;
  for (const fs::path& path : sharedSceneFiles()) {
    auto scene = loadScene(path);  // finds the sidecar in data/sidecars
    ASSERT_TRUE(scene) << path << ": " << scene.error().message;
    // Without lights or sky nothing lights the field, and black is right.
    if (!scene->hasLights() && scene->sky.isBlack()) {
      std::printf("%s: no lights and a black sky, skipped\n", path.filename().c_str());
      continue;
    }
    const Field field = bakeShort(*scene);
    const IndirectCoverage with = coverageOf(*scene, field, gpu::PC_SAMPLE_DEFAULT);
    const IndirectCoverage without = coverageOf(*scene, field, gpu::PC_SAMPLE_NO_FALLBACK);
    std::printf(
        "%s: %d surface pixels; black %d (cages without data %d; %d without the fallback), "
        "probes inside %d of %d\n",
        path.filename().c_str(), with.surfacePixels, with.blackPixels, without.uncoveredPixels,
        without.blackPixels, probesInside(field), field.probeCount());
    EXPECT_GT(with.surfacePixels, 0) << path;
    EXPECT_EQ(with.blackPixels, 0) << path;
    ++measured;
  }
  EXPECT_GT(measured, 0) << "the shared scenes folder holds no scene with lights";
}

// The built-in room with the probes of its left half (x below 0, both cascades) marked inside
// geometry, as a wall of probes walled in by thin geometry would be: there every cage lacks
// data. Without the fallback those pixels are black, so the count can fail; with it, the
// nearest probes with data (or the ambient term) light them.
TEST(NeverBlack, PointsWhoseCagesLackDataFallBack) {
  const Scene scene = builtinScene();
  Field field = bakeShort(scene);
  for (int k = 0; k < field.cascadeCount(); ++k) {
    const gpu::CascadeDesc& c = field.cascade(k);
    for (int s = 0; s < gpu::pcSlotCount(c); ++s)
      if (gpu::pcSlotValid(c, s) && field.probePosition(k, s).x < 0.0f)
        field.probe(k, s).state = gpu::PC_PROBE_INSIDE;
  }
  const IndirectCoverage without = coverageOf(scene, field, gpu::PC_SAMPLE_NO_FALLBACK);
  const IndirectCoverage with = coverageOf(scene, field, gpu::PC_SAMPLE_DEFAULT);
  std::printf(
      "half the probes inside: black %d of %d without the fallback, %d with (%d left to "
      "the ambient term)\n",
      without.blackPixels, without.surfacePixels, with.blackPixels, with.uncoveredPixels);
  EXPECT_GT(without.blackPixels, without.surfacePixels / 10);
  EXPECT_EQ(with.blackPixels, 0);
  // The nearest probes with data take most of them; only those more than two cells from any
  // are left to the ambient term.
  EXPECT_LT(with.uncoveredPixels, without.uncoveredPixels / 2);
}

// A camera deep among the cards of cardRoom, between the cards at z = -0.56 and -0.43, looking
// at the farther one: each point it sees has cages (both cascades) of probes that stand between
// cards.
Camera amongTheCards() {
  return {
      .name = "among the cards",
      .position = {0.0f, 0.8f, 0.5f * (testmesh::cardRoomCardZ(1) + testmesh::cardRoomCardZ(2))},
      .forward = {0.0f, 0.0f, -1.0f},
      .up = {0.0f, 1.0f, 0.0f},
      .yfov = 1.2f};
}

// Probes among one-sided cut-out cards (a bush of leaf cards) see the cards' backs; those are
// surfaces, so the probes stay active and the cards' surfaces get light from them, even with no
// fallback. The same cards opaque: probes between one-sided walls are classed inside, and the
// pixels among them are black without the fallback, lit with it.
TEST(NeverBlack, ProbesAmongCutOutCardsAreNotInside) {
  const Scene builtin = builtinScene();
  const int insideWithoutCards = probesInside(bakeShort(builtin));

  const Scene leaves = testmesh::cardRoom(true);
  const Field leafField = bakeShort(leaves);
  const IndirectCoverage leaf =
      coverageOf(leaves, leafField, gpu::PC_SAMPLE_NO_FALLBACK, amongTheCards());

  const Scene walls = testmesh::cardRoom(false);
  const Field wallField = bakeShort(walls);
  const IndirectCoverage wall =
      coverageOf(walls, wallField, gpu::PC_SAMPLE_NO_FALLBACK, amongTheCards());
  const IndirectCoverage wallFallback =
      coverageOf(walls, wallField, gpu::PC_SAMPLE_DEFAULT, amongTheCards());

  std::printf(
      "probes inside: %d in the room alone, %d among cut-out cards, %d among opaque cards; "
      "black pixels among the cards without the fallback: cut-out %d of %d, opaque %d of %d "
      "(%d with the fallback)\n",
      insideWithoutCards, probesInside(leafField), probesInside(wallField), leaf.blackPixels,
      leaf.surfacePixels, wall.blackPixels, wall.surfacePixels, wallFallback.blackPixels);
  EXPECT_LE(probesInside(leafField), insideWithoutCards);
  EXPECT_GT(probesInside(wallField), insideWithoutCards + 20);
  EXPECT_GT(leaf.surfacePixels, 1000);
  EXPECT_EQ(leaf.blackPixels, 0);
  EXPECT_GT(wall.blackPixels, wall.surfacePixels / 4);
  EXPECT_EQ(wallFallback.blackPixels, 0);
}

}  // namespace
}  // namespace pc
