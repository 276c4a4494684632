// The CPU field update end to end: energy conservation in a furnace box, probe
// classification and relocation, change detection and versions, the scheduler, determinism
// across thread counts, and baked files of a traced field.
#include <gtest/gtest.h>
#include <tbb/global_control.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "common/field.h"
#include "common/scene.h"
#include "protocol/baked_file.h"
#include "server/bake.h"
#include "server/embree_tracer.h"
#include "server/field_hit_sampler.h"
#include "server/probe_scheduler.h"
#include "shaders/interop/probe_math.h"
#include "shaders/interop/probe_update.h"
#include "test_meshes.h"
#include "test_timing.h"
#include "test_tracer_support.h"

namespace pc {
namespace {

namespace fs = std::filesystem;
constexpr double kPi = std::numbers::pi;

// ---- scenes built in code -----------------------------------------------------------------

using testmesh::addQuad;
using testmesh::boxMesh;

void addObject(Scene& scene, Mesh mesh, float albedo) {
  Material m;
  m.baseColor = glm::vec3(albedo);
  mesh.material = static_cast<int>(scene.materials.size());
  scene.materials.push_back(m);
  scene.meshes.push_back(std::move(mesh));
  Instance inst;
  inst.mesh = static_cast<int>(scene.meshes.size()) - 1;
  scene.instances.push_back(inst);
}

// A solid axis-aligned cube.
struct Cube {
  glm::vec3 centre{0.0f};
  float half = 0.5f;
  bool contains(glm::vec3 p) const {
    const glm::vec3 d = glm::abs(p - centre);
    return d.x < half && d.y < half && d.z < half;
  }
  // Distance from an outside point to the cube's surface.
  float distance(glm::vec3 p) const {
    return glm::length(glm::max(glm::abs(p - centre) - glm::vec3(half), glm::vec3(0.0f)));
  }
};

// A closed room [0, size]^3 (walls facing in) lit by a point light, with solid cubes in it.
Scene roomWithCubes(float size, const std::vector<Cube>& cubes) {
  Scene s;
  s.name = "room with cubes";
  addObject(s, boxMesh(glm::vec3(0.0f), glm::vec3(size), true), 0.5f);
  for (const Cube& c : cubes) {
    addObject(s, boxMesh(c.centre - glm::vec3(c.half), c.centre + glm::vec3(c.half), false), 0.5f);
  }
  Light light;
  light.position = glm::vec3(size * 0.5f, size * 0.9f, size * 0.5f);
  light.intensity = 5.0f;
  s.lights.push_back(light);
  s.boundsMin = glm::vec3(0.0f);
  s.boundsMax = glm::vec3(size);
  return s;
}

// Distance from p (inside the room [0, size]^3) to its nearest wall.
float wallDistance(glm::vec3 p, float size) {
  const glm::vec3 hi = glm::vec3(size) - p;
  return std::min({p.x, p.y, p.z, hi.x, hi.y, hi.z});
}

std::unique_ptr<Tracer> tracerFor(const Scene& scene) {
  auto t = makeEmbreeTracer(scene);
  EXPECT_TRUE(t.ok()) << (t.ok() ? "" : t.error().message);
  return t.ok() ? std::move(t).value() : nullptr;
}

// Runs `updates` full updates with consecutive rotation seeds.
void runUpdates(Field& field, Tracer& tracer, int updates, std::uint32_t firstSeed = 1) {
  UpdateRequest request;
  request.probes = allProbes(field);
  for (int i = 0; i < updates; ++i) {
    request.rotationSeed = firstSeed + std::uint32_t(i);
    updateOrFail(tracer, field, request);
  }
}

// ---- energy ---------------------------------------------------------------------------------

double grey(glm::vec3 v) { return (double(v.x) + v.y + v.z) / 3.0; }

struct FurnaceMeasurement {
  double meanTexel = 0;    // over every probe, 64 directions each
  double worstTexel = 0;   // the texel farthest from the expectation
  double meanSampled = 0;  // sampleField on the walls
  double minCoverage = 1;
};

// Bakes the furnace box and reads its irradiance two ways: the stored texels (what the
// update wrote) and sampleField on the walls (what shading sees).
FurnaceMeasurement measureFurnace(float albedo, float emission, int shading, int updates,
                                  double expected) {
  const Scene scene = furnaceBox(albedo, emission);
  Field field = Field::create(scene.volumes, FieldSettings{});
  auto tracer = tracerFor(scene);
  if (!tracer) return {};
  BakeOptions options;
  options.updates = updates;
  options.shading = shading;
  bakeOrFail(field, *tracer, options);

  FurnaceMeasurement m;
  double sum = 0;
  long count = 0;
  for (const ProbeRef& p : allProbes(field)) {
    // The outer probes are one spacing from the walls (active); the inner 2x2x2 are farther
    // than the sleeping reach. None is inside geometry or without data.
    const int state = field.probe(p.cascade, p.slot).state;
    EXPECT_TRUE(state == gpu::PC_PROBE_ACTIVE || state == gpu::PC_PROBE_SLEEPING)
        << "state " << state;
    for (int i = 0; i < 64; ++i) {
      const double v =
          grey(fetchIrradiance(field, p.cascade, p.slot, gpu::pcFibonacciDirection(i, 64)));
      sum += v;
      if (count++ == 0 || std::abs(v - expected) > std::abs(m.worstTexel - expected))
        m.worstTexel = v;
    }
  }
  m.meanTexel = sum / double(std::max(count, 1L));

  // Points spread over all six walls, normal facing into the box, seen along the normal.
  double sampled = 0;
  int samples = 0;
  const float L = scene.boundsMax.x;
  for (int axis = 0; axis < 3; ++axis) {
    const int u = (axis + 1) % 3, v = (axis + 2) % 3;
    for (int side = 0; side < 2; ++side) {
      for (int i = 0; i < 5; ++i) {
        for (int j = 0; j < 5; ++j) {
          glm::vec3 P(0.0f), N(0.0f);
          P[axis] = side == 0 ? 0.0f : L;
          P[u] = L * (0.1f + 0.2f * float(i));
          P[v] = L * (0.1f + 0.2f * float(j));
          N[axis] = side == 0 ? 1.0f : -1.0f;
          float coverage = 0;
          sampled +=
              grey(glm::vec3(sampleField(field, P, N, N, gpu::PC_SAMPLE_DEFAULT, &coverage)));
          m.minCoverage = std::min<double>(m.minCoverage, coverage);
          ++samples;
        }
      }
    }
  }
  m.meanSampled = sampled / samples;
  return m;
}

// A closed box whose walls all have albedo a and emit Le holds radiance Le / (1 - a)
// everywhere, so irradiance pi Le / (1 - a). Any gain or loss in tracing, shading the hits
// with the previous field, blending, the irradiance encoding or sampling shows here.
TEST(FieldEnergy, FurnaceBoxConvergesToAnalyticIrradiance) {
  test::ScopedTestTimer timer;
  const float Le = 1.0f;
  for (float albedo : {0.5f, 0.8f}) {
    const double expected = kPi * Le / (1.0 - albedo);
    // 128 updates: the benchmark converges to 0.05% with this many (a = 0.8 needs ~60
    // bounces to get within 1e-6 of the geometric series; the bake's short-hysteresis phase
    // adds one bounce per update).
    const FurnaceMeasurement m = measureFurnace(albedo, Le, kShadeDefault, 128, expected);
    const double errMean = m.meanTexel / expected - 1.0;
    const double errWorst = m.worstTexel / expected - 1.0;
    const double errSampled = m.meanSampled / expected - 1.0;
    std::printf(
        "furnace a=%.1f: expected %.5f, mean texel %.5f (%+.3f%%), worst texel %.5f (%+.3f%%), "
        "sampled on walls %.5f (%+.3f%%)\n",
        albedo, expected, m.meanTexel, 100 * errMean, m.worstTexel, 100 * errWorst, m.meanSampled,
        100 * errSampled);
    // The goal of the foundation issue: within 2%, without any energy fudge factor.
    EXPECT_NEAR(m.meanTexel, expected, 0.02 * expected) << "albedo " << albedo;
    EXPECT_NEAR(m.meanSampled, expected, 0.02 * expected) << "albedo " << albedo;
    // No single direction of any probe may stray far either: a bias in one octahedral region
    // (a texel mapping or border bug) would average out of the means above. 5% leaves room for
    // the ray noise of one texel (the radiance is uniform, so the noise is small).
    EXPECT_NEAR(m.worstTexel, expected, 0.05 * expected) << "albedo " << albedo;
    // Every wall point lies within the cascade's blend margin: fully covered.
    EXPECT_GE(m.minCoverage, 0.999);
  }
}

// Without indirect light at the hits, each probe ray returns only the emission of the wall it
// hits: one bounce of nothing. The field then holds pi Le, whatever the albedo, which shows the
// multi-bounce above comes from shading hits with the field itself.
TEST(FieldEnergy, SingleBounceHoldsEmissionOnly) {
  test::ScopedTestTimer timer;
  const float Le = 1.0f, albedo = 0.8f;
  const double expected = kPi * Le;
  const FurnaceMeasurement m = measureFurnace(albedo, Le, kShadeNoIndirect, 16, expected);
  std::printf(
      "furnace a=%.1f, no indirect: expected %.5f, mean texel %.5f, worst %.5f, sampled %.5f\n",
      albedo, expected, m.meanTexel, m.worstTexel, m.meanSampled);
  // Every ray returns exactly Le: only float rounding in the weighted means and the gamma
  // encoding separates the result from pi Le.
  EXPECT_NEAR(m.meanTexel, expected, 1e-3 * expected);
  EXPECT_NEAR(m.worstTexel, expected, 1e-3 * expected);
  EXPECT_NEAR(m.meanSampled, expected, 1e-3 * expected);
  // The multi-bounce answer for a = 0.8 is five times larger: far outside this tolerance.
}

// ---- classification and relocation ----------------------------------------------------------

// A 12^3 room with probes every unit, half a unit in from the walls, and two solid cubes each
// centred on a probe: a big one (half side 0.7 spacing, so the 0.45-spacing relocation limit
// cannot get its probe out) and a small one (half side 0.15 spacing, which relocation escapes).
TEST(ProbeClassification, InsideSleepingActive) {
  test::ScopedTestTimer timer;
  const float size = 12.0f, spacing = 1.0f;
  const ProbeVolume volume{glm::vec3(0.5f), spacing, glm::ivec3(12)};
  const glm::ivec3 bigProbe(8, 8, 8), smallProbe(3, 8, 3);
  const Cube big{volume.origin + glm::vec3(bigProbe) * spacing, 0.7f * spacing};
  const Cube small{volume.origin + glm::vec3(smallProbe) * spacing, 0.15f * spacing};
  const Scene scene = roomWithCubes(size, {big, small});
  Field field = Field::create({volume}, FieldSettings{});
  auto tracer = tracerFor(scene);
  ASSERT_TRUE(tracer);
  // A few updates: relocation moves a probe at most once per update, and the small cube's
  // probe needs one update to step out and one to back away from the face it stepped through.
  runUpdates(field, *tracer, 4);

  const gpu::CascadeDesc& c = field.cascade(0);
  const float reach = std::sqrt(3.0f) * spacing;  // the sleeping rule's distance
  int sleeping = 0, active = 0, checkedActive = 0;
  for (const ProbeRef& p : allProbes(field)) {
    const ProbeRecord& r = field.probe(p.cascade, p.slot);
    const glm::ivec3 logical = gpu::pcLogicalCoord(c, gpu::pcSlotCoord(c, p.slot));
    const glm::vec3 grid = gpu::pcProbeGridPosition(c, logical);
    const glm::vec3 pos = field.probePosition(p.cascade, p.slot);
    sleeping += r.state == gpu::PC_PROBE_SLEEPING;
    active += r.state == gpu::PC_PROBE_ACTIVE;
    // The relocation limit holds for every probe.
    EXPECT_LE(glm::length(r.offset), 0.45f * spacing + 1e-4f)
        << "probe " << logical.x << "," << logical.y << "," << logical.z;

    if (logical == bigProbe) {
      EXPECT_EQ(r.state, gpu::PC_PROBE_INSIDE) << "probe in a cube it cannot leave";
      EXPECT_TRUE(big.contains(pos));
      // Every way out is longer than the relocation limit: the probe stays where it is rather
      // than being clamped to a spot still inside (from where it would flip back and forth).
      EXPECT_EQ(glm::length(r.offset), 0.0f);
      continue;
    }
    if (logical == smallProbe) {
      EXPECT_EQ(r.state, gpu::PC_PROBE_ACTIVE) << "relocated out of the small cube";
      EXPECT_FALSE(small.contains(pos))
          << "relocated position " << pos.x << "," << pos.y << "," << pos.z;
      EXPECT_GT(glm::length(r.offset), small.half);
      continue;
    }
    const float nearest =
        std::min({wallDistance(grid, size), big.distance(grid), small.distance(grid)});
    if (nearest > reach) {
      // Every ray from here travels farther than `reach` before it hits anything, and only
      // front faces are visible: the probe must sleep.
      EXPECT_EQ(r.state, gpu::PC_PROBE_SLEEPING)
          << "probe " << logical.x << "," << logical.y << "," << logical.z << " is " << nearest
          << " from the nearest surface";
    } else if (wallDistance(grid, size) < 0.9f * reach) {
      // A room wall (a large plane) is well within reach: some ray hits it within reach.
      EXPECT_EQ(r.state, gpu::PC_PROBE_ACTIVE)
          << "probe " << logical.x << "," << logical.y << "," << logical.z << " is "
          << wallDistance(grid, size) << " from a wall";
      ++checkedActive;
    }
    // Only probes nearer a surface than the push distance may move (none here: the nearest,
    // the big cube's six neighbours, are 0.3 spacing from its faces), and no farther than to
    // that distance.
    const float push = gpu::PC_RELOCATE_MIN_FRONTFACE * spacing;
    if (nearest > push) {
      EXPECT_EQ(r.offset, glm::vec3(0.0f))
          << "probe " << logical.x << "," << logical.y << "," << logical.z;
    } else {
      EXPECT_LE(glm::length(r.offset), push - nearest + 0.01f * spacing)
          << "probe " << logical.x << "," << logical.y << "," << logical.z;
    }
  }
  std::printf("classification: %d active, %d sleeping of %d probes\n", active, sleeping,
              field.probeCount());
  // The room's 12^3 probes: the inner 8^3 are 2.5 or more from the walls (few are near the
  // cubes), the outer shells 0.5 and 1.5 (active).
  EXPECT_GT(sleeping, 300);
  EXPECT_GT(checkedActive, 1000);
}

// A probe 0.05 spacing from a wall is pushed to about PC_RELOCATE_MIN_FRONTFACE (0.2) spacing
// from it; probes farther away stay on their grid point.
TEST(ProbeRelocation, CloseToWallPushedAwayWithinLimit) {
  test::ScopedTestTimer timer;
  const float size = 4.0f, spacing = 1.0f;
  // x = 0.05, 1.05, 2.05, 3.05; y and z = 1, 2, 3 (1 from the walls).
  const ProbeVolume volume{glm::vec3(0.05f, 1.0f, 1.0f), spacing, glm::ivec3(4, 3, 3)};
  const Scene scene = roomWithCubes(size, {});
  Field field = Field::create({volume}, FieldSettings{});
  auto tracer = tracerFor(scene);
  ASSERT_TRUE(tracer);
  runUpdates(field, *tracer, 4);

  const gpu::CascadeDesc& c = field.cascade(0);
  int pushed = 0;
  for (const ProbeRef& p : allProbes(field)) {
    const ProbeRecord& r = field.probe(p.cascade, p.slot);
    const glm::ivec3 logical = gpu::pcLogicalCoord(c, gpu::pcSlotCoord(c, p.slot));
    const glm::vec3 pos = field.probePosition(p.cascade, p.slot);
    EXPECT_NE(r.state, gpu::PC_PROBE_INSIDE);
    EXPECT_LE(glm::length(r.offset), 0.45f * spacing + 1e-4f);
    if (logical.x == 0) {
      ++pushed;
      EXPECT_EQ(r.state, gpu::PC_PROBE_ACTIVE);
      // Pushed along the wall's normal (+x): the rule moves it by (0.2 - d) along the closest
      // ray, which is within a few degrees of the normal with 256 rays, so it ends at
      // 0.2 cos(angle) >= ~0.19 from the wall. Sideways drift stays small.
      const float minFront = gpu::PC_RELOCATE_MIN_FRONTFACE;
      EXPECT_GE(pos.x, (minFront - 0.03f) * spacing) << "still too close to the wall";
      EXPECT_LE(pos.x, (minFront + 0.05f) * spacing) << "pushed farther than needed";
      EXPECT_LT(std::abs(r.offset.y) + std::abs(r.offset.z), 0.05f * spacing);
    } else {
      EXPECT_EQ(r.offset, glm::vec3(0.0f)) << "probe at x=" << pos.x << " is not near a wall";
    }
  }
  EXPECT_EQ(pushed, 9);
}

// ---- change detection and versions -----------------------------------------------------------

// A furnace box with an 8x4x4 cascade: two bricks (x 0-3 and 4-7), every probe one spacing
// from the walls so nothing relocates.
TEST(FieldVersions, UpdatesBumpChangedBricksOnly) {
  test::ScopedTestTimer timer;
  const Scene scene = furnaceBox(0.5f, 1.0f, 2.0f);
  const ProbeVolume volume{glm::vec3(0.2f), 0.2f, glm::ivec3(8, 4, 4)};
  Field field = Field::create({volume}, FieldSettings{});
  ASSERT_EQ(field.brickVersions.size(), 1u);
  ASSERT_EQ(field.brickVersions[0].size(), 2u);
  auto tracer = tracerFor(scene);
  ASSERT_TRUE(tracer);
  EXPECT_EQ(field.version, 0u);

  // First update: every probe goes from uninitialized to data; both bricks change.
  UpdateRequest all;
  all.probes = allProbes(field);
  all.rotationSeed = 1;
  UpdateStats s = updateOrFail(*tracer, field, all);
  EXPECT_EQ(s.bricksChanged, 2);
  EXPECT_EQ(field.version, 1u);
  EXPECT_EQ(field.brickVersions[0][0], 1u);
  EXPECT_EQ(field.brickVersions[0][1], 1u);

  // Second update of brick 0's probes only: the first bounce of indirect light arrives, a
  // large change; brick 1 keeps its version.
  UpdateRequest brick0;
  brick0.rotationSeed = 2;
  for (const ProbeRef& p : all.probes)
    if (p.slot / gpu::PC_PROBES_PER_BRICK == 0) brick0.probes.push_back(p);
  ASSERT_EQ(brick0.probes.size(), 64u);
  s = updateOrFail(*tracer, field, brick0);
  EXPECT_EQ(s.bricksChanged, 1);
  EXPECT_EQ(s.probesUpdated, 64);
  EXPECT_EQ(field.version, 2u);
  EXPECT_EQ(field.brickVersions[0][0], 2u);
  EXPECT_EQ(field.brickVersions[0][1], 1u);

  // A threshold above any possible change of an encoded texel: the atlases still blend, but
  // nothing counts as changed, so no version moves.
  UpdateRequest quiet = all;
  quiet.rotationSeed = 3;
  quiet.changeThreshold = 1e9f;
  const std::vector<float> before = field.irradiance.texels;
  s = updateOrFail(*tracer, field, quiet);
  EXPECT_EQ(s.bricksChanged, 0);
  EXPECT_EQ(field.version, 2u);
  EXPECT_EQ(field.brickVersions[0][0], 2u);
  EXPECT_EQ(field.brickVersions[0][1], 1u);
  EXPECT_NE(field.irradiance.texels, before) << "the update must still have blended";

  // Threshold 0 again: the fresh ray rotation changes some texel of both bricks.
  all.rotationSeed = 4;
  s = updateOrFail(*tracer, field, all);
  EXPECT_EQ(s.bricksChanged, 2);
  EXPECT_EQ(field.version, 3u);
  EXPECT_EQ(field.brickVersions[0][0], 3u);
  EXPECT_EQ(field.brickVersions[0][1], 3u);
}

// ---- scheduler -------------------------------------------------------------------------------

// 8x4x4 probes (two bricks) with states set by hand; no tracing involved.
Field schedulerField() {
  Field field =
      Field::create({ProbeVolume{glm::vec3(0.0f), 1.0f, glm::ivec3(8, 4, 4)}}, FieldSettings{});
  for (ProbeRecord& r : field.probes) r.state = gpu::PC_PROBE_ACTIVE;
  return field;
}

TEST(ProbeScheduler, SleepingAndInsideProbesAreStaggered) {
  Field field = schedulerField();
  // Brick 1 (slots 64-127): 56 sleeping probes, then 8 inside geometry.
  for (int s = 64; s < 120; ++s) field.probe(0, s).state = gpu::PC_PROBE_SLEEPING;
  for (int s = 120; s < 128; ++s) field.probe(0, s).state = gpu::PC_PROBE_INSIDE;
  SchedulerOptions options;
  options.sleepingPeriod = 8;
  options.insidePeriod = 16;
  ProbeScheduler scheduler(options);

  // Tick 1: nothing was ever updated, so everything is due.
  EXPECT_EQ(scheduler.plan(field, 1).size(), 128u);

  std::vector<std::vector<std::uint64_t>> ticksOf(128);
  for (std::uint64_t tick = 2; tick < 2 + 32; ++tick) {
    const std::vector<ProbeRef> plan = scheduler.plan(field, tick);
    int sleepingThisTick = 0, insideThisTick = 0;
    for (const ProbeRef& p : plan) {
      ticksOf[p.slot].push_back(tick);
      sleepingThisTick += field.probe(0, p.slot).state == gpu::PC_PROBE_SLEEPING;
      insideThisTick += field.probe(0, p.slot).state == gpu::PC_PROBE_INSIDE;
    }
    // Staggered: 56 consecutive sleeping slots spread as 7 per tick, never all in one tick;
    // 8 inside slots, period 16: at most one per tick.
    EXPECT_EQ(sleepingThisTick, 7) << "tick " << tick;
    EXPECT_LE(insideThisTick, 1) << "tick " << tick;
  }
  for (int s = 0; s < 128; ++s) {
    const int state = field.probe(0, s).state;
    const std::size_t expected = state == gpu::PC_PROBE_ACTIVE     ? 32
                                 : state == gpu::PC_PROBE_SLEEPING ? 4
                                                                   : 2;
    ASSERT_EQ(ticksOf[s].size(), expected) << "slot " << s << " state " << state;
    const std::uint64_t period = state == gpu::PC_PROBE_ACTIVE     ? 1
                                 : state == gpu::PC_PROBE_SLEEPING ? 8
                                                                   : 16;
    for (std::size_t i = 1; i < ticksOf[s].size(); ++i)
      EXPECT_EQ(ticksOf[s][i] - ticksOf[s][i - 1], period) << "slot " << s;
  }

  // A reset (scene cut) makes every probe due again at once.
  scheduler.resetAll();
  EXPECT_EQ(scheduler.plan(field, 40).size(), 128u);
}

// Two viewers at opposite corners: with equal weights the budget splits between them; a viewer
// of weight 4 (what its connect token allows) draws most of it to its side.
TEST(ProbeScheduler, AHeavierViewerDrawsTheBudgetToItsSide) {
  Field field = schedulerField();
  SchedulerOptions options;
  options.budget = 16;
  const glm::vec3 a(1.2f, 0.7f, 0.4f), b = field.probePosition(0, 127);
  auto nearerA = [&](const std::vector<ProbeRef>& plan) {
    int n = 0;
    for (const ProbeRef& p : plan) {
      const glm::vec3 x = field.probePosition(p.cascade, p.slot);
      n += glm::length(x - a) < glm::length(x - b) ? 1 : 0;
    }
    return n;
  };
  ProbeScheduler even(options), weighted(options);
  const int evenA = nearerA(even.plan(field, 1, {a, b}, {1.0f, 1.0f}));
  const int weightedA = nearerA(weighted.plan(field, 1, {a, b}, {4.0f, 1.0f}));
  std::printf("probes nearer the first viewer: %d of 16 at equal weights, %d at weight 4\n", evenA,
              weightedA);
  EXPECT_GT(weightedA, evenA);
  EXPECT_GE(weightedA, 12);
  // No weights: as equal weights.
  ProbeScheduler plain(options);
  EXPECT_EQ(nearerA(plain.plan(field, 1, {a, b})), evenA);
}

TEST(ProbeScheduler, BudgetServesNearestViewerFirstWithoutStarving) {
  Field field = schedulerField();
  SchedulerOptions options;
  options.budget = 16;
  ProbeScheduler scheduler(options);
  // Near one corner of the grid, so distances differ widely.
  const glm::vec3 viewer(1.2f, 0.7f, 0.4f);
  auto distance = [&](ProbeRef p) {
    return glm::length(field.probePosition(p.cascade, p.slot) - viewer);
  };

  // Tick 1: every probe is new, so priority falls with distance alone: the plan must be the 16
  // nearest probes.
  const std::vector<ProbeRef> first = scheduler.plan(field, 1, {viewer});
  ASSERT_EQ(first.size(), 16u);
  std::vector<bool> planned(128, false);
  float farthestPlanned = 0;
  for (const ProbeRef& p : first) {
    planned[p.slot] = true;
    farthestPlanned = std::max(farthestPlanned, distance(p));
  }
  for (const ProbeRef& p : allProbes(field)) {
    if (!planned[p.slot]) {
      EXPECT_GE(distance(p), farthestPlanned - 1e-5f) << "slot " << p.slot;
    }
  }

  // Probes never updated outrank any updated one, so 128 / 16 = 8 ticks update each probe
  // exactly once, nearest first.
  std::vector<int> count(128, 0);
  for (const ProbeRef& p : first) ++count[p.slot];
  float previousFarthest = farthestPlanned;
  for (std::uint64_t tick = 2; tick <= 8; ++tick) {
    const std::vector<ProbeRef> plan = scheduler.plan(field, tick, {viewer});
    EXPECT_EQ(plan.size(), 16u) << "budget per tick";
    float nearest = 1e30f, farthest = 0;
    for (const ProbeRef& p : plan) {
      ++count[p.slot];
      nearest = std::min(nearest, distance(p));
      farthest = std::max(farthest, distance(p));
    }
    EXPECT_GE(nearest, previousFarthest - 1e-5f)
        << "tick " << tick << " went back toward the viewer";
    previousFarthest = farthest;
  }
  for (int s = 0; s < 128; ++s) EXPECT_EQ(count[s], 1) << "slot " << s;

  // Afterwards staleness grows without bound, so even the farthest probe comes up again: over
  // the next 64 ticks (1024 updates for 128 probes) every probe gets several, and the nearest
  // get more than the farthest.
  std::fill(count.begin(), count.end(), 0);
  for (std::uint64_t tick = 9; tick < 9 + 64; ++tick) {
    const std::vector<ProbeRef> plan = scheduler.plan(field, tick, {viewer});
    EXPECT_LE(plan.size(), 16u);
    for (const ProbeRef& p : plan) ++count[p.slot];
  }
  int nearestSlot = 0, farthestSlot = 0;
  for (const ProbeRef& p : allProbes(field)) {
    EXPECT_GE(count[p.slot], 2) << "slot " << p.slot << " at " << distance(p) << " starves";
    if (distance(p) < distance({0, nearestSlot})) nearestSlot = p.slot;
    if (distance(p) > distance({0, farthestSlot})) farthestSlot = p.slot;
  }
  EXPECT_GT(count[nearestSlot], count[farthestSlot]);
}

// ---- determinism -----------------------------------------------------------------------------

void expectSameField(const Field& a, const Field& b, const std::string& what) {
  EXPECT_TRUE(a.irradiance.texels == b.irradiance.texels) << what << ": irradiance differs";
  EXPECT_TRUE(a.depth.texels == b.depth.texels) << what << ": depth differs";
  EXPECT_TRUE(a.occlusion.texels == b.occlusion.texels) << what << ": occlusion differs";
  ASSERT_EQ(a.probes.size(), b.probes.size());
  for (std::size_t i = 0; i < a.probes.size(); ++i) {
    EXPECT_EQ(a.probes[i].offset, b.probes[i].offset) << what << ": probe " << i;
    EXPECT_EQ(a.probes[i].state, b.probes[i].state) << what << ": probe " << i;
    EXPECT_EQ(a.probes[i].updates, b.probes[i].updates) << what << ": probe " << i;
  }
  EXPECT_EQ(a.brickVersions, b.brickVersions) << what;
  EXPECT_EQ(a.version, b.version) << what;
}

Field bakeBuiltin(const Scene& scene, int updates, std::uint32_t seed) {
  Field field = Field::create(scene.volumes, FieldSettings{});
  field.sceneHash = scene.hash;
  auto tracer = tracerFor(scene);
  if (!tracer) return field;
  BakeOptions options;
  options.updates = updates;
  options.seed = seed;
  bakeOrFail(field, *tracer, options);
  return field;
}

// The built-in room (point light, emissive sampling, two cascades, multi-bounce through the
// field): the same seed must give the same bits on 1, 2 and all threads. Each probe draws
// from its own seeded generator and the update reads the field only before writing it.
TEST(FieldDeterminism, SameSeedSameFieldOnAnyThreadCount) {
  test::ScopedTestTimer timer;
  const Scene scene = builtinScene();
  const int updates = 8;  // enough for multi-bounce reads of a partly converged field
  const Field reference = bakeBuiltin(scene, updates, 7);
  for (int threads : {1, 2}) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    const Field f = bakeBuiltin(scene, updates, 7);
    expectSameField(reference, f, std::to_string(threads) + " thread(s)");
  }
  // A different seed gives a different field: the comparison above can fail.
  const Field other = bakeBuiltin(scene, updates, 8);
  EXPECT_NE(reference.irradiance.texels, other.irradiance.texels);
}

// ---- baked files ------------------------------------------------------------------------------

// A traced field (real values in every channel, states, offsets, versions) through the baked
// file format: full precision gives back exactly what shading reads.
TEST(BakedTracedField, RoundTripSamplesIdentically) {
  test::ScopedTestTimer timer;
  const Scene scene = builtinScene();
  const Field field = bakeBuiltin(scene, 8, 3);
  ASSERT_GT(field.version, 0u);

  const fs::path dir =
      fs::temp_directory_path() / ("pc_test_field_update_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path file = dir / "builtin.probes";
  const Status written = writeBakedField(file, field);
  ASSERT_TRUE(written.ok()) << written.error().message;
  auto loaded = readBakedField(file, scene.hash);
  fs::remove_all(dir);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  const Field& back = *loaded;
  expectSameField(field, back, "file round trip");
  EXPECT_EQ(back.sceneHash, field.sceneHash);

  auto halfBytes = encodeBakedField(field, BakedWriteOptions{.halfPrecision = true});
  ASSERT_TRUE(halfBytes.ok()) << halfBytes.error().message;
  auto half = decodeBakedField(*halfBytes, scene.hash);
  ASSERT_TRUE(half.ok()) << half.error().message;

  // Shading points all over the room, with random normals and view directions, for both
  // cascades and the blend between them.
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  auto unit = [&] {
    const float z = 2 * u(rng) - 1, phi = 2 * float(kPi) * u(rng), r = std::sqrt(1 - z * z);
    return glm::vec3(r * std::cos(phi), r * std::sin(phi), z);
  };
  double worstHalf = 0;
  for (int i = 0; i < 2000; ++i) {
    const glm::vec3 P =
        scene.boundsMin + (scene.boundsMax - scene.boundsMin) * glm::vec3(u(rng), u(rng), u(rng));
    const glm::vec3 N = unit(), V = unit();
    for (int flags : {gpu::PC_SAMPLE_DEFAULT, gpu::PC_SAMPLE_NO_VISIBILITY}) {
      float ca = 0, cb = 0;
      const glm::vec4 a = sampleField(field, P, N, V, flags, &ca);
      const glm::vec4 b = sampleField(back, P, N, V, flags, &cb);
      ASSERT_EQ(a, b) << "point " << i;
      ASSERT_EQ(ca, cb);
      const glm::vec4 h = sampleField(*half, P, N, V, flags);
      const float scale = std::max(1e-3f, std::max(a.x, std::max(a.y, a.z)));
      for (int c = 0; c < 4; ++c)
        worstHalf = std::max<double>(worstHalf, std::abs(h[c] - a[c]) / scale);
    }
  }
  std::printf("half-precision baked field: worst sampled error %.2e of the sample's peak channel\n",
              worstHalf);
  // float16 keeps 11 significant bits (relative error 5e-4) of the gamma-5 encoded value, so
  // the decoded irradiance is within ~2.5e-3; 1e-2 leaves room for interpolation.
  EXPECT_LT(worstHalf, 1e-2);
}

// The Embree update's sampler at probe-ray hits gives the very floats of the shared sampling
// code, on a traced field (two cascades and the blend between them) and on the same field with
// most probes taken out, where cages without data fall back to the wider block.
TEST(FieldHitSampler, SamplesExactlyAsTheSharedCode) {
  test::ScopedTestTimer timer;
  const Scene scene = builtinScene();
  Field field = bakeBuiltin(scene, 6, 9);
  ASSERT_GT(field.version, 0u);
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::normal_distribution<float> g;
  for (bool thinned : {false, true}) {
    if (thinned) {
      for (ProbeRecord& p : field.probes) {
        if (u(rng) < 0.8f) p.state = gpu::PC_PROBE_INSIDE;
      }
    }
    const FieldHitSampler sampler(field);
    int fallbacks = 0;
    for (int i = 0; i < 3000; ++i) {
      const glm::vec3 P =
          scene.boundsMin + (scene.boundsMax - scene.boundsMin) * glm::vec3(u(rng), u(rng), u(rng));
      const glm::vec3 N = glm::normalize(glm::vec3(g(rng), g(rng), g(rng)));
      const glm::vec3 V = glm::normalize(glm::vec3(g(rng), g(rng), g(rng)));
      const glm::vec3 expected(sampleField(field, P, N, V, gpu::PC_SAMPLE_NO_OCCLUSION));
      ASSERT_EQ(sampler.irradiance(P, N, V), expected) << "point " << i << ", thinned " << thinned;
      float coverage = 1.0f;
      sampleField(field, P, N, V, gpu::PC_SAMPLE_NO_OCCLUSION | gpu::PC_SAMPLE_NO_FALLBACK,
                  &coverage);
      fallbacks += coverage < 1.0f ? 1 : 0;
    }
    // The thinned field sends points to the fallback (76 of 3000 with this seed): it is covered.
    if (thinned) {
      EXPECT_GT(fallbacks, 30);
    }
  }
}

}  // namespace
}  // namespace pc
