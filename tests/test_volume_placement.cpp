// Probe volumes placed from geometry (common/volume_placement.h): the free-space scale of rooms
// whose answer is known (a closed cube of side L: the median distance from a point inside to
// the nearest wall is (1 - 2^(-1/3)) L / 2 = 0.103 L), that it follows the scene's scale, that
// the inside of a solid block and the air around it are not counted, and the spacing warning.
#include <gtest/gtest.h>

#include "common/volume_placement.h"
#include "test_meshes.h"

namespace {

using pc::Scene;

// A scene of axis-aligned boxes; `inward` boxes are rooms, the others solid blocks.
Scene boxes(std::initializer_list<std::pair<std::pair<glm::vec3, glm::vec3>, bool>> list) {
  Scene s;
  s.name = "boxes";
  s.materials.push_back(pc::Material{.name = "white"});
  s.boundsMin = glm::vec3(INFINITY);
  s.boundsMax = glm::vec3(-INFINITY);
  for (const auto& [box, inward] : list) {
    s.meshes.push_back(pc::testmesh::boxMesh(box.first, box.second, inward));
    s.instances.push_back(pc::Instance{.name = "box", .mesh = int(s.meshes.size()) - 1});
    s.boundsMin = glm::min(s.boundsMin, box.first);
    s.boundsMax = glm::max(s.boundsMax, box.second);
  }
  return s;
}

constexpr float kCubeMedian = 0.10315f;  // (1 - 2^(-1/3)) / 2

TEST(VolumePlacement, ClosedRoomsFreeSpaceIsTheCubesMedianDistance) {
  for (float side : {2.0f, 30.0f}) {
    const Scene room = boxes({{{glm::vec3(0.0f), glm::vec3(side)}, true}});
    const pc::GeometryScale g = pc::measureGeometry(room);
    ASSERT_TRUE(g.valid) << side;
    // Voxels quantize the distance by about one voxel (side / 256).
    EXPECT_NEAR(g.freeSpace, kCubeMedian * side, 0.08f * kCubeMedian * side) << side;
    EXPECT_NEAR(g.edgeLength, side * (2.0f + std::sqrt(2.0f)) / 3.0f, 1e-3f * side);
    // The enclosed space is the room.
    EXPECT_NEAR(g.levelMin.x, 0.0f, 0.02f * side);
    EXPECT_NEAR(g.levelMax.y, side, 0.02f * side);
    // 1.2 x 0.103 L: about 8 probes across the room, in one cascade.
    const pc::VolumePlan plan = pc::autoVolumes(room);
    ASSERT_EQ(plan.volumes.size(), 1u) << side;
    EXPECT_GT(plan.volumes[0].spacing, side / 9.0f);
    EXPECT_LT(plan.volumes[0].spacing, side / 7.0f);
    EXPECT_GE(plan.volumes[0].counts.x, 7);
    EXPECT_LE(plan.volumes[0].counts.x, 9);
  }
}

TEST(VolumePlacement, SolidBlocksInsideAndAirOutsideAreNotFreeSpace) {
  // A solid block (outward faces) alone: its inside shows only backs, its outside has no walls.
  const Scene block = boxes({{{glm::vec3(0.0f), glm::vec3(4.0f)}, false}});
  EXPECT_FALSE(pc::measureGeometry(block).valid);
  // The block in a room: the free space is the room's minus the block, so it shrinks, and the
  // block's inside (which would give distances up to 2) is left out. The room of side 10 alone
  // measures 1.03.
  const Scene room = boxes({{{glm::vec3(0.0f), glm::vec3(10.0f)}, true},
                            {{glm::vec3(3.0f, 0.0f, 3.0f), glm::vec3(7.0f, 4.0f, 7.0f)}, false}});
  const pc::GeometryScale g = pc::measureGeometry(room);
  ASSERT_TRUE(g.valid);
  EXPECT_LT(g.freeSpace, 1.0f);
  EXPECT_GT(g.freeSpace, 0.6f);
}

TEST(VolumePlacement, SmallLevelInALargeFileGetsAFineAndACoarseCascade) {
  // A 4 m room on a 400 m ground slab: the fine cascade fits the room, a coarse one the slab.
  const Scene s =
      boxes({{{glm::vec3(0.0f), glm::vec3(4.0f)}, true},
             {{glm::vec3(-200.0f, -1.0f, -200.0f), glm::vec3(200.0f, -0.5f, 200.0f)}, false}});
  const pc::VolumePlan plan = pc::autoVolumes(s);
  ASSERT_TRUE(plan.scale.valid);
  ASSERT_EQ(plan.volumes.size(), 2u);
  EXPECT_NEAR(plan.scale.freeSpace, kCubeMedian * 4.0f, 0.1f * kCubeMedian * 4.0f);
  EXPECT_LT(plan.volumes[0].spacing, 1.0f);
  EXPECT_GT(plan.volumes[1].spacing, plan.volumes[0].spacing);
  const pc::ProbeVolume& coarse = plan.volumes[1];
  EXPECT_LE(coarse.origin.x, -150.0f);  // reaches over the slab
  EXPECT_LE(plan.probes, 16384);
}

TEST(VolumePlacement, ProbeBudgetWidensTheSpacing) {
  const Scene room = boxes({{{glm::vec3(0.0f), glm::vec3(10.0f, 2.0f, 10.0f)}, true}});
  const pc::VolumePlan wide = pc::autoVolumes(room, 64);
  EXPECT_LE(wide.probes, 64);
  EXPECT_GT(wide.volumes[0].spacing, wide.wantedSpacing);
  const pc::VolumePlan open = pc::autoVolumes(room);
  EXPECT_FLOAT_EQ(open.volumes[0].spacing, open.wantedSpacing);
}

TEST(VolumePlacement, EmptyScenesFallBackToTheBoundsGrid) {
  Scene s;
  s.boundsMax = glm::vec3(4.0f);
  const pc::VolumePlan plan = pc::autoVolumes(s);
  EXPECT_FALSE(plan.scale.valid);
  const std::vector<pc::ProbeVolume> bounds = pc::defaultVolumes(s);
  ASSERT_EQ(plan.volumes.size(), bounds.size());
  EXPECT_FLOAT_EQ(plan.volumes[0].spacing, bounds[0].spacing);
  EXPECT_NE(pc::describePlan(s, plan).find("no enclosed space"), std::string::npos);
}

TEST(VolumePlacement, CoarseSpacingIsNamedWithTheSuggestedOne) {
  Scene room = boxes({{{glm::vec3(0.0f), glm::vec3(4.0f)}, true}});
  room.name = "small-room";
  const pc::GeometryScale g = pc::measureGeometry(room);
  const float wanted = pc::suggestedSpacing(g);
  pc::ProbeVolume v;
  v.spacing = 3.0f * wanted;
  const auto advice = pc::spacingAdvice(room, {v}, g);
  ASSERT_TRUE(advice.has_value());
  EXPECT_NE(advice->find("small-room"), std::string::npos) << *advice;
  char spacing[32], suggested[32];
  std::snprintf(spacing, sizeof spacing, "spacing %.3g", v.spacing);
  std::snprintf(suggested, sizeof suggested, "suggested spacing %.3g", wanted);
  EXPECT_NE(advice->find(spacing), std::string::npos) << *advice;
  EXPECT_NE(advice->find(suggested), std::string::npos) << *advice;
  v.spacing = 1.5f * wanted;
  EXPECT_FALSE(pc::spacingAdvice(room, {v}, g).has_value());
  // The hand-written Cornell box spacing (0.25 in a 2 m room) is not coarse.
  Scene cornell = boxes({{{glm::vec3(-1.0f, 0.0f, -1.0f), glm::vec3(1.0f, 2.0f, 1.0f)}, true}});
  v.spacing = 0.25f;
  EXPECT_FALSE(pc::spacingAdvice(cornell, {v}, pc::measureGeometry(cornell)).has_value());
}

}  // namespace
