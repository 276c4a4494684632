// Unit tests of the shared probe math: octahedral mapping, borders, ray directions, probe and
// brick indexing, atlas addressing.
#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "common/field.h"
#include "shaders/interop/probe_update.h"

using namespace pc::gpu;

TEST(OctahedralMapping, RoundTripsEveryDirection) {
  float worst = 0.0f;
  for (int i = 0; i < 20000; ++i) {
    vec3 d = pcFibonacciDirection(i, 20000);
    vec3 back = pcOctDecode(pcOctEncode(d));
    worst = std::max(worst, length(back - d));
  }
  EXPECT_LT(worst, 1e-5f);
  // Axes and the fold seam.
  for (vec3 d : {vec3(1, 0, 0), vec3(0, -1, 0), vec3(0, 0, -1), normalize(vec3(1, 1, -1e-4f))}) {
    EXPECT_LT(length(pcOctDecode(pcOctEncode(d)) - d), 1e-5f);
  }
}

TEST(OctahedralMapping, EncodeCoversTheSquare) {
  for (int i = 0; i < 1000; ++i) {
    vec2 uv = pcOctEncode(pcFibonacciDirection(i, 1000));
    EXPECT_LE(std::abs(uv.x), 1.0f + 1e-6f);
    EXPECT_LE(std::abs(uv.y), 1.0f + 1e-6f);
  }
}

TEST(OctahedralMapping, TexelCoordinateOfTexelDirectionIsItsCentre) {
  const int n = 8;
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      vec2 tc = pcTileCoord(pcTexelDirection(x, y, n), n);
      EXPECT_NEAR(tc.x, x + 1.5f, 1e-4f);
      EXPECT_NEAR(tc.y, y + 1.5f, 1e-4f);
    }
}

// A border texel must hold the value of the interior texel whose direction is closest to
// where the border texel's centre would map across the octahedral fold.
TEST(OctahedralMapping, BorderSourcesAreNeighboursAcrossTheFold) {
  const int n = 8;
  for (int by = 0; by < n + 2; ++by)
    for (int bx = 0; bx < n + 2; ++bx) {
      bool border = bx == 0 || by == 0 || bx == n + 1 || by == n + 1;
      if (!border) continue;
      ivec2 src = pcBorderSource(bx, by, n);
      ASSERT_GE(src.x, 0);
      ASSERT_LT(src.x, n);
      ASSERT_GE(src.y, 0);
      ASSERT_LT(src.y, n);
      // The nearest interior texel to the border texel, measured on the sphere through the
      // adjacent interior texel, must be the source: check the source is within 1.5 texel
      // angles of the adjacent interior texel.
      int ax = std::clamp(bx - 1, 0, n - 1), ay = std::clamp(by - 1, 0, n - 1);
      vec3 adjacent = pcTexelDirection(ax, ay, n);
      vec3 source = pcTexelDirection(src.x, src.y, n);
      float texelAngle = 3.14159265f / n;  // about one texel's angular size
      EXPECT_LT(std::acos(std::clamp(dot(adjacent, source), -1.0f, 1.0f)), 1.5f * texelAngle)
          << "border " << bx << "," << by;
    }
}

TEST(FibonacciDirections, AreUnitAndUniform) {
  const int n = 256;
  vec3 mean(0.0f);
  // Uniform on the sphere: every cap of solid angle w holds about n*w/(4pi) points.
  for (int i = 0; i < n; ++i) {
    vec3 d = pcFibonacciDirection(i, n);
    EXPECT_NEAR(length(d), 1.0f, 1e-5f);
    mean += d;
  }
  EXPECT_LT(length(mean / float(n)), 0.01f);
  const float capCos = 0.8f;  // cap solid angle 2pi(1-0.8) -> expected n*0.1 = 25.6 points
  for (int t = 0; t < 200; ++t) {
    vec3 axis = pcFibonacciDirection(t, 200);
    int inside = 0;
    for (int i = 0; i < n; ++i) inside += dot(pcFibonacciDirection(i, n), axis) > capCos;
    EXPECT_NEAR(inside, 25.6, 6.0) << "cap " << t;
  }
  // Nearest-neighbour spacing is even: no two directions much closer than the mean spacing.
  float minAngle = 10.0f;
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j < n; ++j)
      minAngle = std::min(
          minAngle,
          std::acos(std::min(1.0f, dot(pcFibonacciDirection(i, n), pcFibonacciDirection(j, n)))));
  float meanSpacing = std::sqrt(4.0f * 3.14159265f / n);
  EXPECT_GT(minAngle, 0.5f * meanSpacing);
}

TEST(FibonacciDirections, RandomRotationIsOrthonormalAndChanges) {
  mat3 a = pcRandomRotation(1u), b = pcRandomRotation(2u);
  mat3 i = a * transpose(a);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(i[c][r], r == c ? 1.0f : 0.0f, 1e-5f);
  EXPECT_NEAR(determinant(a), 1.0f, 1e-5f);
  EXPECT_GT(length(a * vec3(0, 0, 1) - b * vec3(0, 0, 1)), 1e-3f);
  // Rotated sets stay uniform: the mean of many rotated axes is near zero.
  vec3 mean(0.0f);
  for (uint s = 0; s < 2000; ++s) mean += pcRandomRotation(s) * vec3(0, 0, 1);
  EXPECT_LT(length(mean / 2000.0f), 0.05f);
}

TEST(ProbeIndexing, SlotsAreABijectionBrickByBrick) {
  CascadeDesc c{};
  c.counts = ivec3(9, 5, 6);  // not multiples of the brick size
  std::set<int> slots;
  for (int z = 0; z < c.counts.z; ++z)
    for (int y = 0; y < c.counts.y; ++y)
      for (int x = 0; x < c.counts.x; ++x) {
        ivec3 p(x, y, z);
        int s = pcProbeSlot(c, p);
        EXPECT_TRUE(slots.insert(s).second);
        EXPECT_EQ(pcSlotCoord(c, s), p);
        EXPECT_TRUE(pcSlotValid(c, s));
        EXPECT_EQ(s / PC_PROBES_PER_BRICK, pcBrickIndex(c, p));
        EXPECT_EQ(pcBrickCoord(c, pcBrickIndex(c, p)), p / PC_BRICK_SIZE);
      }
  EXPECT_EQ(pcBrickCounts(c), ivec3(3, 2, 2));
  EXPECT_EQ(pcSlotCount(c), 12 * PC_PROBES_PER_BRICK);
  int valid = 0;
  for (int s = 0; s < pcSlotCount(c); ++s) valid += pcSlotValid(c, s);
  EXPECT_EQ(valid, 9 * 5 * 6);
}

TEST(ProbeIndexing, ToroidalScrollWraps) {
  CascadeDesc c{};
  c.counts = ivec3(4, 4, 4);
  c.scroll = ivec3(1, 3, 1);
  for (int x = 0; x < 4; ++x) {
    ivec3 l(x, 0, 3);
    ivec3 p = pcPhysicalCoord(c, l);
    EXPECT_EQ(p, ivec3((x + 1) % 4, 3, 0));
    EXPECT_EQ(pcLogicalCoord(c, p), l);
  }
}

TEST(FieldLayout, AtlasTilesDoNotOverlapAcrossCascades) {
  std::vector<pc::ProbeVolume> volumes = {{vec3(0.0f), 0.5f, ivec3(6, 5, 7)},
                                          {vec3(-1.0f), 1.0f, ivec3(8, 8, 8)}};
  pc::Field f = pc::Field::create(volumes, {});
  ASSERT_EQ(f.cascadeCount(), 2);
  std::set<std::pair<int, int>> origins;
  for (int k = 0; k < 2; ++k)
    for (int s = 0; s < pcSlotCount(f.cascade(k)); ++s) {
      ivec2 o = pcAtlasTileOrigin(f.cascade(k), s, PC_DEPTH_TEXELS + 2);
      EXPECT_TRUE(origins.insert({o.x, o.y}).second);
      EXPECT_LE(o.x + PC_DEPTH_TEXELS + 2, f.depth.width);
      EXPECT_LE(o.y + PC_DEPTH_TEXELS + 2, f.depth.height);
    }
  EXPECT_EQ(f.probeCount(), 6 * 5 * 7 + 512);
}

// A field whose every texel holds the same irradiance samples to that irradiance anywhere,
// whatever the weights: the sampling is a normalized average (no energy gain or loss).
TEST(FieldSampling, UniformFieldSamplesToItsValue) {
  std::vector<pc::ProbeVolume> volumes = {{vec3(0.0f), 1.0f, ivec3(4, 4, 4)}};
  pc::Field f = pc::Field::create(volumes, {});
  const vec3 E(2.0f, 1.0f, 0.5f);
  vec3 enc = pcEncodeIrradiance(E);
  for (std::size_t i = 0; i < f.irradiance.texels.size(); i += 3)
    f.irradiance.texels[i] = enc.x, f.irradiance.texels[i + 1] = enc.y,
    f.irradiance.texels[i + 2] = enc.z;
  for (std::size_t i = 0; i < f.depth.texels.size(); i += 2)
    f.depth.texels[i] = 0.5f, f.depth.texels[i + 1] = 0.3f;
  for (auto& p : f.probes) p.state = PC_PROBE_ACTIVE;
  for (int i = 0; i < 100; ++i) {
    vec3 P =
        vec3(0.3f) + 2.4f * vec3(pcHashToFloat(pcHash(3 * i)), pcHashToFloat(pcHash(3 * i + 1)),
                                 pcHashToFloat(pcHash(3 * i + 2)));
    vec3 N = pcFibonacciDirection(i, 100);
    float coverage = 0;
    vec4 s = pc::sampleField(f, P, N, N, PC_SAMPLE_DEFAULT, &coverage);
    EXPECT_NEAR(coverage, 1.0f, 1e-6f);
    EXPECT_NEAR(s.x, E.x, 1e-3f * E.x);
    EXPECT_NEAR(s.y, E.y, 1e-3f * E.y);
    EXPECT_NEAR(s.z, E.z, 1e-3f * E.z);
  }
}

TEST(FieldSampling, ProbesInsideGeometryAreIgnored) {
  std::vector<pc::ProbeVolume> volumes = {{vec3(0.0f), 1.0f, ivec3(2, 2, 2)}};
  pc::Field f = pc::Field::create(volumes, {});
  float coverage = -1;
  pc::sampleField(f, vec3(0.5f), vec3(0, 1, 0), vec3(0, 1, 0), PC_SAMPLE_DEFAULT, &coverage);
  EXPECT_EQ(coverage, 0.0f);  // nothing initialized yet
  for (auto& p : f.probes) p.state = PC_PROBE_INSIDE;
  pc::sampleField(f, vec3(0.5f), vec3(0, 1, 0), vec3(0, 1, 0), PC_SAMPLE_DEFAULT, &coverage);
  EXPECT_EQ(coverage, 0.0f);
}

TEST(ProbeClassification, InsideHasHysteresis) {
  // Between the two thresholds a probe keeps its state: ray noise around one threshold no
  // longer flips it (and resets its history) at every update.
  EXPECT_FALSE(pcProbeInside(0.2f, PC_PROBE_ACTIVE));
  EXPECT_TRUE(pcProbeInside(0.2f, PC_PROBE_INSIDE));
  EXPECT_TRUE(pcProbeInside(0.3f, PC_PROBE_ACTIVE));
  EXPECT_FALSE(pcProbeInside(0.05f, PC_PROBE_INSIDE));
  EXPECT_FALSE(pcProbeInside(0.2f, PC_PROBE_SLEEPING));
}

TEST(ProbeClassification, InsideProbeStepsOutOnlyWithinReach) {
  const float minFront = 0.2f, maxOffset = 0.45f;
  // A backface 0.1 away: the step (0.1 + 0.1) fits, the probe moves through it.
  vec3 moved =
      pcRelocate(vec3(0.0f), true, 0.1f, vec3(1, 0, 0), 1e30f, vec3(0.0f), minFront, maxOffset);
  EXPECT_NEAR(moved.x, 0.2f, 1e-6f);
  // From an offset of 0.3 the same step would end at 0.5, past the reach: it stays put rather
  // than being clamped back inside.
  moved = pcRelocate(vec3(0.3f, 0, 0), true, 0.1f, vec3(1, 0, 0), 1e30f, vec3(0.0f), minFront,
                     maxOffset);
  EXPECT_EQ(moved, vec3(0.3f, 0, 0));
  // Outside and too close to a wall: it backs away, clamped to the reach.
  moved = pcRelocate(vec3(0.4f, 0, 0), false, 1e30f, vec3(0.0f), 0.05f, vec3(-1, 0, 0), minFront,
                     maxOffset);
  EXPECT_NEAR(glm::length(moved), maxOffset, 1e-5f);
}
