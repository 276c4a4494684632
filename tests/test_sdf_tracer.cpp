// The SDF backend (VulkanTracing::DistanceField) on lavapipe with the validation layer on (any
// validation error fails): its distance field against exact distances, its hits against the
// ray-tracing backend's ray by ray, and its field against the Embree backend's.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <vector>

#include "common/field.h"
#include "common/scene.h"
#include "common/scene_glossy.h"
#include "server/bake.h"
#include "server/embree_tracer.h"
#include "server/field_compare.h"
#include "server/vulkan_tracer.h"
#include "shaders/interop/sdf_grid.h"
#include "test_meshes.h"
#include "test_tracer_support.h"

namespace pc {
namespace {

// A Vulkan tracer on any device (lavapipe in CI) with the validation layer; null where no
// device is present (`why` says why: only that skips, any other failure fails the test).
std::unique_ptr<VulkanTracer> makeVulkan(const Scene& scene, VulkanTracing tracing,
                                         std::string* why, int sdfVoxels = 128) {
  VulkanTracerOptions vo;
  vo.validation = true;
  vo.allowCpuDevice = true;
  vo.tracing = tracing;
  vo.sdfVoxels = sdfVoxels;
  auto t = VulkanTracer::create(scene, TracerOptions{}, vo);
  if (!t) {
    *why = t.error().message;
    if (why->rfind("no Vulkan", 0) != 0) ADD_FAILURE() << "the tracer failed to start: " << *why;
    return nullptr;
  }
  return std::move(t).value();
}

// A scene of one instance of `mesh`, lit by nothing (the distance field needs only geometry).
Scene oneMeshScene(Mesh mesh) {
  Scene scene;
  scene.name = "one mesh";
  scene.materials.push_back(Material{.name = "grey", .baseColor = glm::vec3(0.5f)});
  mesh.material = 0;
  scene.boundsMin = scene.boundsMax = mesh.positions.front();
  for (const glm::vec3& p : mesh.positions) {
    scene.boundsMin = glm::min(scene.boundsMin, p);
    scene.boundsMax = glm::max(scene.boundsMax, p);
  }
  scene.meshes.push_back(std::move(mesh));
  scene.instances.push_back(Instance{.name = "mesh", .mesh = 0});
  return scene;
}

// Calls f(sample position, sample) for every sample of every brick.
template <typename F>
void forEachSample(const SdfFieldCopy& sdf, F&& f) {
  const gpu::SdfHeader& h = sdf.header;
  for (int cell = 0; cell < int(sdf.cells.size()); ++cell) {
    const int brick = sdf.cells[std::size_t(cell)].brick;
    if (brick < 0) continue;
    const glm::ivec3 c = gpu::pcSdfCellCoord(h, cell);
    for (int z = 0; z < gpu::PC_SDF_BRICK_SIDE; ++z)
      for (int y = 0; y < gpu::PC_SDF_BRICK_SIDE; ++y)
        for (int x = 0; x < gpu::PC_SDF_BRICK_SIDE; ++x) {
          const glm::ivec3 s(x, y, z);
          f(gpu::pcSdfSamplePosition(h, c, s),
            sdf.samples[std::size_t(gpu::pcSdfSampleIndex(brick, s))]);
        }
  }
}

// Unsigned distance from p to the surface of the box [lo, hi].
float boxDistance(glm::vec3 p, glm::vec3 lo, glm::vec3 hi) {
  const glm::vec3 centre = 0.5f * (lo + hi), half = 0.5f * (hi - lo);
  const glm::vec3 q = glm::abs(p - centre) - half;
  const float outside = glm::length(glm::max(q, glm::vec3(0.0f)));
  const float inside = std::min(std::max(q.x, std::max(q.y, q.z)), 0.0f);
  return outside > 0.0f ? outside : -inside;
}

Result<SdfFieldCopy> readField(VulkanTracer& tracer) { return tracer.readSdf(); }

// The distance field of a box: every sample within the band holds the exact distance to the
// box's surface (analytic), the rest the band; each sample's triangle is at that distance; the
// cells without a brick bound their points' distance from below; and every cell the surface
// crosses has a brick.
TEST(SdfTracer, BoxDistancesAreExactAtTheSamples) {
  const glm::vec3 lo(-0.7f, -0.4f, -0.5f), hi(0.6f, 0.5f, 0.3f);
  const Scene scene = oneMeshScene(testmesh::boxMesh(lo, hi, false));
  std::string why;
  auto sdf = makeVulkan(scene, VulkanTracing::DistanceField, &why, 64);
  if (!sdf) GTEST_SKIP() << "no Vulkan device: " << why;
  auto field = readField(*sdf);
  ASSERT_TRUE(field) << field.error().message;
  const gpu::SdfHeader& h = field->header;
  EXPECT_NEAR(h.voxel, 1.3f / 64.0f, 1e-6f);
  EXPECT_GT(h.brickCount, 0u);
  int exact = 0, clamped = 0;
  double worst = 0;
  forEachSample(*field, [&](glm::vec3 p, const gpu::SdfSample& s) {
    const float d = boxDistance(p, lo, hi);
    const float expected = std::min(d, h.band);
    worst = std::max(worst, double(std::abs(s.distance - expected)));
    ASSERT_NEAR(s.distance, expected, 2e-6f) << "at " << p.x << "," << p.y << "," << p.z;
    if (d < h.band) {
      ++exact;
      ASSERT_NE(s.triangle, gpu::PC_SDF_NO_TRIANGLE);
      const gpu::SdfTriangle& t = field->triangles[s.triangle];
      ASSERT_NEAR(gpu::pcPointTriangleDistance(p, t.p0, t.p1, t.p2), d, 2e-6f);
    } else {
      ++clamped;
    }
  });
  std::printf("box: %u bricks, %d exact samples, %d clamped, worst error %.2e m\n", h.brickCount,
              exact, clamped, worst);
  EXPECT_GT(exact, 1000);
  // Empty cells: the bound holds at their corners and centre; cells the surface crosses (a
  // corner inside the box and one outside) all have bricks.
  const float size = gpu::pcSdfCellSize(h);
  for (int cell = 0; cell < int(field->cells.size()); ++cell) {
    const glm::ivec3 c = gpu::pcSdfCellCoord(h, cell);
    const glm::vec3 base = h.origin + glm::vec3(c) * size;
    int inside = 0;
    for (int k = 0; k < 8; ++k) {
      const glm::vec3 p = base + size * glm::vec3(k & 1, (k >> 1) & 1, k >> 2);
      inside += glm::all(glm::greaterThan(p, lo)) && glm::all(glm::lessThan(p, hi)) ? 1 : 0;
      if (field->cells[std::size_t(cell)].brick < 0) {
        ASSERT_LE(field->cells[std::size_t(cell)].distance, boxDistance(p, lo, hi) + 1e-6f);
      }
    }
    if (inside > 0 && inside < 8) {
      ASSERT_GE(field->cells[std::size_t(cell)].brick, 0);
    }
  }
  EXPECT_EQ(sdf->validationErrorCount(), 0u);
}

// A triangulated sphere: samples within the band hold the distance to the nearest of its
// triangles (brute force on the CPU), and lie within the tessellation's sag of the round
// sphere's distance.
TEST(SdfTracer, SphereDistancesMatchBruteForce) {
  Mesh mesh;
  const int rings = 12, segments = 24;
  const float radius = 0.5f;
  for (int r = 0; r <= rings; ++r)
    for (int s = 0; s <= segments; ++s) {
      const float theta = 3.14159265f * float(r) / float(rings);
      const float phi = 2.0f * 3.14159265f * float(s) / float(segments);
      const glm::vec3 n(std::sin(theta) * std::cos(phi), std::cos(theta),
                        std::sin(theta) * std::sin(phi));
      mesh.positions.push_back(radius * n);
      mesh.normals.push_back(n);
    }
  for (int r = 0; r < rings; ++r)
    for (int s = 0; s < segments; ++s) {
      const std::uint32_t a = std::uint32_t(r * (segments + 1) + s), b = a + 1,
                          c = a + std::uint32_t(segments + 1), d = c + 1;
      for (std::uint32_t i : {a, c, b, b, c, d}) mesh.indices.push_back(i);
    }
  const Scene scene = oneMeshScene(std::move(mesh));
  std::string why;
  auto sdf = makeVulkan(scene, VulkanTracing::DistanceField, &why, 48);
  if (!sdf) GTEST_SKIP() << "no Vulkan device: " << why;
  auto field = readField(*sdf);
  ASSERT_TRUE(field) << field.error().message;
  const gpu::SdfHeader& h = field->header;
  // The sag of the tessellation: how far a flat triangle lies inside the round sphere.
  const float sag = radius * (1.0f - std::cos(3.14159265f / float(rings)));
  int checked = 0;
  forEachSample(*field, [&](glm::vec3 p, const gpu::SdfSample& s) {
    float nearest = 1e30f;
    for (const gpu::SdfTriangle& t : field->triangles)
      nearest = std::min(nearest, gpu::pcPointTriangleDistance(p, t.p0, t.p1, t.p2));
    ASSERT_NEAR(s.distance, std::min(nearest, h.band), 2e-6f);
    if (nearest < h.band) {
      ASSERT_NEAR(s.distance, std::abs(glm::length(p) - radius), sag + 1e-5f);
      ++checked;
    }
  });
  EXPECT_GT(checked, 1000);
  EXPECT_EQ(sdf->validationErrorCount(), 0u);
}

// The built-in room's short block turns: setState to a later time updates the field where the
// block was and is (only the bricks near its old and new triangles are filled again), and the
// update holds exactly what a whole build for that state holds, cell by cell and sample by
// sample. Lights alone moving leave the field as it is.
TEST(SdfTracer, MovedInstancesUpdateTheFieldAsAWholeBuildWould) {
  const Scene scene = builtinScene();
  std::string why;
  auto updated = makeVulkan(scene, VulkanTracing::DistanceField, &why, 32);
  if (!updated) GTEST_SKIP() << "no Vulkan device: " << why;
  auto whole = makeVulkan(scene, VulkanTracing::DistanceField, &why, 32);
  ASSERT_TRUE(whole);
  auto before = readField(*updated);
  ASSERT_TRUE(before) << before.error().message;
  const SdfBuildStats first = updated->sdfBuildStats();
  const SceneState later = evaluateScene(scene, 1.5);
  setStateOrFail(*updated, later);
  auto after = readField(*updated);
  ASSERT_TRUE(after) << after.error().message;
  const SdfBuildStats& u = updated->sdfBuildStats();
  EXPECT_EQ(u.builds, 2);
  EXPECT_TRUE(u.update);
  EXPECT_GT(u.bricksBuilt, 0);
  EXPECT_LT(u.bricksBuilt, first.bricksBuilt) << "an update refills only the bricks it reaches";
  std::printf(
      "built-in room on %s: whole build %.1f ms (%d bricks), update after the block "
      "turned %.1f ms (%d bricks filled, %d allocated)\n",
      updated->context().deviceName().c_str(), first.gpuMs, first.bricksBuilt, u.gpuMs,
      u.bricksBuilt, u.bricks);
  int moved = 0;
  for (std::size_t i = 0; i < after->triangles.size(); ++i)
    moved += glm::length(after->triangles[i].p0 - before->triangles[i].p0) > 1e-4f ? 1 : 0;
  EXPECT_GT(moved, 0) << "the animated block did not move";

  setStateOrFail(*whole, later);
  auto reference = readField(*whole);
  ASSERT_TRUE(reference) << reference.error().message;
  EXPECT_FALSE(whole->sdfBuildStats().update);
  ASSERT_EQ(after->cells.size(), reference->cells.size());
  int compared = 0;
  for (std::size_t c = 0; c < after->cells.size(); ++c) {
    const gpu::SdfCell &x = after->cells[c], &y = reference->cells[c];
    ASSERT_EQ(x.brick < 0, y.brick < 0) << "cell " << c;
    if (x.brick < 0) {
      ASSERT_EQ(x.distance, y.distance) << "cell " << c;
      continue;
    }
    for (int s = 0; s < gpu::PC_SDF_BRICK_SAMPLES; ++s) {
      const gpu::SdfSample& a =
          after->samples[std::size_t(x.brick) * gpu::PC_SDF_BRICK_SAMPLES + std::size_t(s)];
      const gpu::SdfSample& b =
          reference->samples[std::size_t(y.brick) * gpu::PC_SDF_BRICK_SAMPLES + std::size_t(s)];
      ASSERT_EQ(a.distance, b.distance) << "cell " << c << " sample " << s;
      if (a.distance < after->header.band) {
        ASSERT_EQ(a.triangle, b.triangle) << "cell " << c << " sample " << s;
      }
      ++compared;
    }
  }
  EXPECT_GT(compared, 10000);

  SceneState lightsMoved = later;
  for (Light& l : lightsMoved.lights) l.position += glm::vec3(0.1f);
  setStateOrFail(*updated, lightsMoved);
  ASSERT_TRUE(readField(*updated));
  EXPECT_EQ(updated->sdfBuildStats().builds, 2);
  EXPECT_EQ(updated->validationErrorCount(), 0u);
  EXPECT_EQ(whole->validationErrorCount(), 0u);
}

// Ray by ray against the ray-tracing backend (same probes, same directions, same launch
// order): the same hits and misses, the same triangle of the same record at the same distance,
// or (rays through an edge or corner two triangles share) another at the same distance.
void expectTheHitsOfRayTracing(const Scene& scene, const char* what) {
  std::string why;
  auto sdf = makeVulkan(scene, VulkanTracing::DistanceField, &why);
  if (!sdf) GTEST_SKIP() << "no Vulkan device: " << why;
  auto rt = makeVulkan(scene, VulkanTracing::RayPipelines, &why);
  if (!rt) GTEST_SKIP() << "no Vulkan ray-tracing device: " << why;
  FieldSettings settings;
  settings.raysPerProbe = 64;
  Field fs = Field::create(scene.volumes, settings), fr = Field::create(scene.volumes, settings);
  UpdateRequest request;
  request.probes = allProbes(fs);
  request.rotationSeed = 7;
  auto a = sdf->traceHits(fs, request);
  ASSERT_TRUE(a) << a.error().message;
  auto b = rt->traceHits(fr, request);
  ASSERT_TRUE(b) << b.error().message;
  ASSERT_EQ(a->size(), b->size());
  std::size_t same = 0, hitsBoth = 0, missMismatch = 0;
  double worstT = 0, worstOther = 0;
  for (std::size_t i = 0; i < a->size(); ++i) {
    const gpu::GpuHit& x = (*a)[i];
    const gpu::GpuHit& y = (*b)[i];
    if ((x.instance < 0) != (y.instance < 0)) {
      ++missMismatch;
      continue;
    }
    if (x.instance < 0) {
      ++same;
      continue;
    }
    ++hitsBoth;
    const double dt = double(std::abs(x.t - y.t)) / std::max(1.0, double(y.t));
    if (x.instance == y.instance && x.primitive == y.primitive) {
      ++same;
      worstT = std::max(worstT, dt);
    } else {
      // Another triangle at the same distance: the ray meets an edge or corner both share.
      worstOther = std::max(worstOther, dt);
    }
  }
  const double share = double(same) / double(a->size());
  std::printf(
      "%s, %zu rays: %.4f%% the same triangle (or both miss), %zu hit/miss mismatches, "
      "worst relative distance difference %.2e (%.2e where the triangles differ)\n",
      what, a->size(), 100.0 * share, missMismatch, worstT, worstOther);
  EXPECT_GT(hitsBoth, a->size() / 2);
  EXPECT_GE(share, 0.995);
  EXPECT_LE(worstT, 1e-4);
  EXPECT_LE(worstOther, 1e-4);
  EXPECT_EQ(missMismatch, 0u);
  EXPECT_EQ(sdf->validationErrorCount(), 0u);
  EXPECT_EQ(rt->validationErrorCount(), 0u);
}

TEST(SdfTracer, RaysHitTheTrianglesRayTracingHits) {
  expectTheHitsOfRayTracing(builtinScene(), "built-in room");
}

// Through a cut-out: rays pass the grille's open texels and stop on its covered ones.
TEST(SdfTracer, RaysThroughCutOutsHitWhatRayTracingHits) {
  expectTheHitsOfRayTracing(testmesh::grilleRoom(true), "grille room");
}

// The McGuire Cornell box (a sampled emitter, shadow rays) baked on both backends: the SDF
// backend's field against Embree's. compareFields' irradiance figure (what gpu-trace prints as
// field_rel_diff_irradiance) is sum |a - b| / sum |b| over the decoded irradiance texels of the
// probes active in both. The SDF backend's hits are exact ray-triangle hits on the triangles
// ray tracing finds (RaysHitTheTrianglesRayTracingHits) and both backends draw the same random
// streams, so the fields agree up to rounding as the ray-tracing backend's do (measured
// 3.7e-7 on lavapipe); tolerance 1e-3 as for that backend: a ray in a thousand that missed or
// leaked (sky light where a wall is) would move the irradiance by about that much, far below
// the 0.66% that two different random streams leave.
TEST(SdfTracer, CornellBoxFieldMatchesEmbree) {
  const std::string path =
      std::string(PC_SCENES_DIR) + "/mcguire-cornellbox/CornellBox-Original.obj";
  auto scene = loadScene(path);
  if (!scene) GTEST_SKIP() << "no shared scenes: " << scene.error().message;
  std::string why;
  auto gpu = makeVulkan(*scene, VulkanTracing::DistanceField, &why);
  if (!gpu) GTEST_SKIP() << "no Vulkan device: " << why;
  auto cpu = makeEmbreeTracer(*scene);
  ASSERT_TRUE(cpu) << cpu.error().message;
  const FieldDifference d = bakeBothAndCompare(*scene, *gpu, **cpu, 2);
  std::printf(
      "cornell box, sdf vs embree: %d active probes, irradiance rel diff %.2e, depth rel "
      "diff %.2e, %d state mismatches\n",
      d.probes, d.irradiance, d.depth, d.stateMismatches);
  EXPECT_GT(d.probes, 32);
  EXPECT_LE(d.irradiance, 1e-3);
  EXPECT_LE(d.depth, 1e-3);
  EXPECT_EQ(gpu->validationErrorCount(), 0u);
}

// Glossy hits (shaders/interop/probe_hit_shading.h): McGuire's Cornell box with its floor a
// dielectric and its boxes metals (kGlossyCornellMaterials) at roughness 0.4, so probe rays
// see lights and the field through the GGX lobe. Both GPU backends shade hits in the one
// shade pass with the function the Embree tracer calls, and draw the same random streams: the
// fields agree to rounding as the diffuse box's do, within the same 1e-3 (measured 5.9e-7 ray
// tracing, 6.1e-7 SDF on lavapipe). The glossy box's Embree field differs from the diffuse
// box's by far more (measured 0.16), so a shade pass that ignored the material would fail.
// The same box with its roughness from a metallic-roughness texture (linear data, G = 102:
// 0.4) must give the same fields: a GPU that decoded the texture as sRGB would read 0.13.
TEST(SdfTracer, GlossyCornellBoxFieldsMatchEmbree) {
  const std::string path =
      std::string(PC_SCENES_DIR) + "/mcguire-cornellbox/CornellBox-Original.obj";
  auto diffuse = loadScene(path);
  if (!diffuse) GTEST_SKIP() << "no shared scenes: " << diffuse.error().message;
  const auto glossyScene = [&](bool textured) {
    Scene scene = *diffuse;
    if (textured) {
      Texture t;
      t.name = "metallic-roughness";
      t.width = t.height = 1;
      t.rgba = {0, 102, 255, 255};  // G roughness 0.4, B metallic 1
      t.linear = true;
      scene.textures.push_back(t);
    }
    int glossy = 0;
    for (Material& m : scene.materials)
      for (const GlossyOverride& o : kGlossyCornellMaterials)
        if (m.name == o.material) {
          m.metallic = o.metallic;
          m.roughness = textured ? 1.0f : 0.4f;
          if (textured) m.metallicRoughnessTexture = int(scene.textures.size()) - 1;
          ++glossy;
        }
    EXPECT_EQ(glossy, 3);
    return scene;
  };
  auto cpuDiffuse = makeEmbreeTracer(*diffuse);
  ASSERT_TRUE(cpuDiffuse) << cpuDiffuse.error().message;
  for (bool textured : {false, true}) {
    const Scene scene = glossyScene(textured);
    const char* kind = textured ? "textured" : "factors";
    auto cpu = makeEmbreeTracer(scene);
    ASSERT_TRUE(cpu) << cpu.error().message;
    const FieldDifference fromDiffuse = bakeBothAndCompare(scene, **cpu, **cpuDiffuse, 3);
    std::printf("glossy cornell box (%s) vs the diffuse one, embree: irradiance rel diff %.2e\n",
                kind, fromDiffuse.irradiance);
    EXPECT_GT(fromDiffuse.irradiance, 0.05) << kind;
    for (VulkanTracing tracing : {VulkanTracing::RayPipelines, VulkanTracing::DistanceField}) {
      const char* name = tracing == VulkanTracing::RayPipelines ? "ray tracing" : "sdf";
      std::string why;
      auto gpu = makeVulkan(scene, tracing, &why);
      if (!gpu) {
        std::printf("%s: no device (%s)\n", name, why.c_str());
        continue;
      }
      const FieldDifference d = bakeBothAndCompare(scene, *gpu, **cpu, 3);
      std::printf(
          "glossy cornell box (%s), %s vs embree: %d active probes, irradiance rel diff %.2e, "
          "depth rel diff %.2e\n",
          kind, name, d.probes, d.irradiance, d.depth);
      EXPECT_GT(d.probes, 32) << kind << ", " << name;
      EXPECT_LE(d.irradiance, 1e-3) << kind << ", " << name;
      EXPECT_LE(d.depth, 1e-3) << kind << ", " << name;
      EXPECT_EQ(gpu->validationErrorCount(), 0u) << kind << ", " << name;
    }
  }
}

// Cut-outs: the SDF backend's traversal tests the coverage of a cut-out's candidate hits
// (cutout_coverage.glsl, the any-hit shader's test), so probe and shadow rays pass the
// grille's open texels as Embree's filters let them, and meet what lies just behind them (the
// tall block's top, 5 mm under the upper face: in the cell's triangle list, and for cells
// whose list overflowed, the samples' nearest opaque triangle; with the corners' nearest
// triangles alone, lavapipe measured 2.9e-2 here). The same grille opaque gives a field far
// from both (1.1e-1), so a backend that ignored the cut-out would fail; measured 2.4e-5
// against the bound of 1e-2 the ray-tracing backend's test holds.
TEST(SdfTracer, CutOutGrilleMatchesEmbree) {
  const Scene scene = testmesh::grilleRoom(true);
  std::string why;
  auto gpu = makeVulkan(scene, VulkanTracing::DistanceField, &why);
  if (!gpu) GTEST_SKIP() << "no Vulkan device: " << why;
  auto cpu = makeEmbreeTracer(scene);
  ASSERT_TRUE(cpu) << cpu.error().message;
  const Scene solid = testmesh::grilleRoom(false);
  auto opaque = makeEmbreeTracer(solid);
  ASSERT_TRUE(opaque) << opaque.error().message;
  FieldSettings settings;
  settings.raysPerProbe = 64;
  Field fg = Field::create(scene.volumes, settings), fc = Field::create(scene.volumes, settings),
        fo = Field::create(scene.volumes, settings);
  UpdateRequest request;
  request.probes = allProbes(fc);
  for (int i = 0; i < 3; ++i) {
    request.rotationSeed = 1100u + std::uint32_t(i);
    updateOrFail(*gpu, fg, request);
    updateOrFail(**cpu, fc, request);
    updateOrFail(**opaque, fo, request);
  }
  const FieldDifference d = compareFields(fg, fc);
  const FieldDifference o = compareFields(fo, fc);
  std::printf(
      "grille room: sdf vs Embree irradiance rel diff %.2e, depth %.2e; opaque grille vs "
      "cut-out %.2e\n",
      d.irradiance, d.depth, o.irradiance);
  EXPECT_GT(d.probes, 100);
  EXPECT_LE(d.irradiance, 0.01);
  EXPECT_LE(d.depth, 0.01);
  EXPECT_GT(o.irradiance, 0.05);
  EXPECT_EQ(gpu->validationErrorCount(), 0u);
}

// The factory: "sdf" by name gives the SDF backend (a CPU device allowed); an unknown name is
// refused with the list of names.
TEST(SdfTracer, FactoryMakesTheSdfBackendByName) {
  const Scene scene = builtinScene();
  auto made = makeTracer(scene, "sdf");
  if (!made && made.error().message.rfind("no Vulkan", 0) == 0)
    GTEST_SKIP() << "no Vulkan device: " << made.error().message;
  ASSERT_TRUE(made) << made.error().message;
  EXPECT_EQ((*made)->name().rfind("sdf (", 0), 0u) << (*made)->name();
  auto unknown = makeTracer(scene, "raymarch");
  ASSERT_FALSE(unknown);
  EXPECT_NE(unknown.error().message.find("sdf"), std::string::npos) << unknown.error().message;
}

}  // namespace
}  // namespace pc
