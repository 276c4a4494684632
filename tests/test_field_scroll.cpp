// Cascades that follow the viewers (common/field_scroll.h): what a move keeps and what starts
// over, where the viewers put the cascade, the layout stamps bricks carry and how a client's
// copy moves with the server's over a stream that skips places and loses datagrams.
#include <gtest/gtest.h>

#include <random>

#include "common/field_scroll.h"
#include "protocol/brick_codec.h"
#include "protocol/stream_simulation.h"
#include "test_protocol_support.h"

namespace pc {
namespace {

using gpu::CascadeDesc;

Field movingLayout() {
  Field f = test::makeSyntheticLayout();
  for (int k = 0; k < f.cascadeCount(); ++k) f.desc.cascades[k].follows = 1;
  return f;
}

// The grid point (in spacings from the first origin) each valid slot of cascade k stands for.
std::vector<glm::ivec3> gridPoints(const Field& f, int k, glm::vec3 firstOrigin) {
  const CascadeDesc& c = f.cascade(k);
  std::vector<glm::ivec3> points(std::size_t(gpu::pcSlotCount(c)), glm::ivec3(-9999));
  for (int s = 0; s < gpu::pcSlotCount(c); ++s) {
    if (!gpu::pcSlotValid(c, s)) continue;
    points[std::size_t(s)] = originShift(firstOrigin, c.origin, c.spacing) +
                             gpu::pcLogicalCoord(c, gpu::pcSlotCoord(c, s));
  }
  return points;
}

TEST(FieldScroll, AMoveKeepsTheProbesThatStayAndResetsTheSlabThatCameIn) {
  Field f = movingLayout();
  std::mt19937 rng(3);
  test::evolveField(f, rng, 1.0f, 0.5f);
  const int k = 0;
  const glm::vec3 first = f.cascade(k).origin;
  const std::vector<glm::ivec3> before = gridPoints(f, k, first);
  const Field old = f;
  const glm::ivec3 shift(2, 0, -1);
  const std::vector<int> reset = scrollCascade(f, k, shift);
  const std::vector<glm::ivec3> after = gridPoints(f, k, first);
  const CascadeDesc& c = f.cascade(k);
  EXPECT_EQ(c.origin, first + glm::vec3(shift) * c.spacing);
  // 8x6x8: two x-slabs (2*6*8) and one z-slab (1*6*8), sharing 2*6*1 probes.
  EXPECT_EQ(reset.size(), std::size_t(96 + 48 - 12));
  std::vector<bool> wasReset(before.size(), false);
  for (int s : reset) wasReset[std::size_t(s)] = true;
  for (int s = 0; s < gpu::pcSlotCount(c); ++s) {
    if (!gpu::pcSlotValid(c, s)) continue;
    const glm::ivec3 g = after[std::size_t(s)];
    const glm::ivec3 rel = g - originShift(first, c.origin, c.spacing);
    ASSERT_TRUE(rel.x >= 0 && rel.y >= 0 && rel.z >= 0 && rel.x < 8 && rel.y < 6 && rel.z < 8);
    // A slot keeps its data exactly when it still stands for the same grid point.
    const bool same = g == before[std::size_t(s)];
    EXPECT_EQ(wasReset[std::size_t(s)], !same) << "slot " << s;
    if (same) {
      EXPECT_EQ(f.probe(k, s).state, old.probe(k, s).state);
      EXPECT_EQ(f.probe(k, s).offset, old.probe(k, s).offset);
      // Same world position, relocation included.
      EXPECT_NEAR(glm::length(f.probePosition(k, s) - old.probePosition(k, s)), 0.0f, 1e-5f);
    } else {
      EXPECT_EQ(f.probe(k, s).state, gpu::PC_PROBE_UNINITIALIZED);
      EXPECT_EQ(f.probe(k, s).offset, glm::vec3(0.0f));
      EXPECT_EQ(f.probe(k, s).updates, 0u);
    }
  }
  // The other cascade did not move; versions are left to the next update.
  EXPECT_EQ(f.cascade(1).origin, old.cascade(1).origin);
  EXPECT_EQ(f.brickVersions, old.brickVersions);
  // A move past the cascade's size starts every probe over.
  EXPECT_EQ(scrollCascade(f, k, glm::ivec3(0, 0, 20)).size(), std::size_t(8 * 6 * 8));
}

TEST(FieldScroll, TheCascadeMovesOnlyOnceTheCentreIsASpacingOff) {
  const Field f = movingLayout();
  const CascadeDesc& c = f.cascade(0);  // 8x6x8 at spacing 0.5 from (-2, 0, -2)
  const glm::vec3 middle = c.origin + glm::vec3(c.counts - 1) * (0.5f * c.spacing);
  EXPECT_EQ(followShift(c, middle), glm::ivec3(0));
  EXPECT_EQ(followShift(c, middle + glm::vec3(0.49f, -0.49f, 0.2f)), glm::ivec3(0));
  EXPECT_EQ(followShift(c, middle + glm::vec3(0.51f, 0.0f, -1.26f)), glm::ivec3(1, 0, -2));
  Field moved = f;
  scrollCascade(moved, 0, followShift(c, middle + glm::vec3(10.3f, 0, 0)));
  const CascadeDesc& m = moved.cascade(0);
  const glm::vec3 newMiddle = m.origin + glm::vec3(m.counts - 1) * (0.5f * m.spacing);
  EXPECT_LT(std::abs(newMiddle.x - (middle.x + 10.3f)), m.spacing);
}

TEST(FieldScroll, StampsShowExactlyTheSlotsThatStandForTheSameGridPoint) {
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> step(-5, 5);
  Field f = movingLayout();
  const glm::vec3 first = f.cascade(1).origin;
  for (int trial = 0; trial < 40; ++trial) {
    const CascadeDesc stamp = f.cascade(1);
    const std::vector<glm::ivec3> before = gridPoints(f, 1, first);
    scrollCascade(f, 1, glm::ivec3(step(rng), step(rng), step(rng)));
    const std::vector<glm::ivec3> after = gridPoints(f, 1, first);
    const CascadeDesc& c = f.cascade(1);
    for (int s = 0; s < gpu::pcSlotCount(c); ++s) {
      if (!gpu::pcSlotValid(c, s)) continue;
      EXPECT_EQ(slotMatchesStamp(c, stamp.origin, gpu::pcSlotCoord(c, s)),
                after[std::size_t(s)] == before[std::size_t(s)])
          << "trial " << trial << " slot " << s;
    }
  }
}

TEST(FieldScroll, BricksCarryTheirStampThroughTheCodecAndApplyMasked) {
  Field server = movingLayout();
  std::mt19937 rng(9);
  test::evolveField(server, rng, 1.0f, 0.1f);
  const QuantizedBrick before = quantizeBrick(server, 0, 0);
  ASSERT_TRUE(before.origin.has_value());
  EXPECT_EQ(*before.origin, server.cascade(0).origin);
  // Self-contained and residual payloads keep the stamp.
  scrollCascade(server, 0, glm::ivec3(1, 0, 0));
  test::evolveField(server, rng, 1.0f, 0.2f);
  const QuantizedBrick after = quantizeBrick(server, 0, 0);
  EXPECT_NE(*after.origin, *before.origin);
  for (const QuantizedBrick* base : {static_cast<const QuantizedBrick*>(nullptr), &before}) {
    auto decoded = decodeBrick(encodeBrick(after, base), base);
    ASSERT_TRUE(decoded.ok()) << decoded.error().message;
    EXPECT_EQ(*decoded, after);
  }
  // A stamp change is never held back as a small change.
  QuantizedBrick moved = before;
  moved.origin = *before.origin + glm::vec3(0.5f, 0, 0);
  EXPECT_TRUE(brickChange(before, moved).states);
  // Unstamped bricks (cascades that never move) decode as before.
  QuantizedBrick plain = before;
  plain.origin.reset();
  auto decodedPlain = decodeBrick(encodeBrick(plain, nullptr), nullptr);
  ASSERT_TRUE(decodedPlain.ok());
  EXPECT_FALSE(decodedPlain->origin.has_value());
  // A truncated or non-finite stamp is refused by name.
  std::vector<std::uint8_t> bytes = encodeBrick(after, nullptr);
  auto truncated = decodeBrick(std::span(bytes).first(10), nullptr);
  ASSERT_FALSE(truncated.ok());
  EXPECT_NE(truncated.error().message.find("layout stamp"), std::string::npos);
  bytes[4] = bytes[5] = 0x00;
  bytes[6] = 0xC0;
  bytes[7] = 0x7F;  // float32 quiet NaN (0x7FC00000), little-endian
  auto nan = decodeBrick(bytes, nullptr);
  ASSERT_FALSE(nan.ok());
  EXPECT_NE(nan.error().message.find("not finite"), std::string::npos);

  // The old brick applied to a copy in the new place shows only the slots still in place.
  Field client = server;
  applyBrick(client, 0, 0, before);
  const CascadeDesc& c = server.cascade(0);
  int hidden = 0;
  for (int s = 0; s < gpu::PC_PROBES_PER_BRICK; ++s) {
    if (!gpu::pcSlotValid(c, s)) continue;
    const bool here = slotMatchesStamp(c, *before.origin, gpu::pcSlotCoord(c, s));
    hidden += !here;
    if (!here) {
      EXPECT_EQ(client.probe(0, s).state, gpu::PC_PROBE_UNINITIALIZED);
    } else {
      EXPECT_NE(client.probe(0, s).state, gpu::PC_PROBE_UNINITIALIZED);
    }
  }
  EXPECT_EQ(hidden, 16);  // brick 0 holds x 0..3: the x = 0 column (4x4 probes) scrolled out
}

// The server's cascades move every few updates while the field changes; the client hears the
// places only with the scene states (some of which a lossy link delays past several moves) and
// ends with exactly the server's field, in the server's places.
TEST(FieldScroll, AStreamedCopyMovesWithTheServersCascades) {
  Field server = movingLayout();
  StreamSimulationOptions o;
  o.seed = 21;
  o.warmupSeconds = 0.5;
  o.faultSeconds = 3.0;
  o.faults.loss = 0.1;
  o.faults.reorder = 0.1;
  o.settleLimitSeconds = 5.0;
  std::mt19937 rng(21);
  int updates = 0, moves = 0;
  const glm::ivec3 steps[] = {{1, 0, 0}, {1, 0, 1}, {0, 0, 1}, {-1, 1, 0}, {2, 0, 0}};
  FieldAdvance advance = [&](Field& f, double t) {
    if (++updates % 3 == 0) {
      // Every third update the viewers moved: both cascades follow (the coarse one less often),
      // and the tracer re-traces the probes that came in, as the field thread does.
      const glm::ivec3 step = steps[std::size_t(moves++) % 5];
      std::vector<std::pair<int, std::vector<int>>> reset;
      reset.emplace_back(0, scrollCascade(f, 0, step));
      if (moves % 2 == 0) reset.emplace_back(1, scrollCascade(f, 1, step));
      const std::uint64_t next = f.version + 1;
      for (auto& [k, slots] : reset) {
        for (int s : slots) {
          const int b = s / gpu::PC_PROBES_PER_BRICK;
          test::paintBrick(f, k, b, float(t));
          f.brickVersions[k][b] = next;
        }
      }
      f.version = next;
    }
    test::evolveField(f, rng, 0.2f, float(t));
  };
  auto r = runStreamSimulation(server, advance, o);
  ASSERT_GT(moves, 8);
  ASSERT_TRUE(r.converged);
  EXPECT_EQ(r.receiverErrors, r.receiver.rejectedDatagrams);  // only the link's damage refused
  EXPECT_EQ(r.receiver.decodeErrors, 0u);
  for (int k = 0; k < server.cascadeCount(); ++k) {
    EXPECT_EQ(r.mirror.cascade(k).origin, server.cascade(k).origin);
    EXPECT_EQ(r.mirror.cascade(k).scroll, server.cascade(k).scroll);
  }
  EXPECT_EQ(test::differingBricks(r.mirror, test::quantizedCopy(server)), 0);
}

}  // namespace
}  // namespace pc
