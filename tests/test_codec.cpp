// The brick codec: quantization within the bounds PROTOCOL.md states, residual and
// self-contained payloads decode to the same brick, and hostile payloads are rejected
// without crashing.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "protocol/brick_codec.h"
#include "test_protocol_support.h"

namespace {

using namespace pc;
using namespace pc::gpu;

TEST(BrickCodec, IrradianceCodeWithinBound) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> logE(-20.0f, 15.9f);
  for (int i = 0; i < 200000; ++i) {
    const float e = std::exp2(logE(rng));
    const float d = dequantizeIrradiance(quantizeIrradiance(e));
    const float err = std::abs(d - e);
    ASSERT_LE(err, std::max(kIrradianceRelativeBound * e, kIrradianceAbsoluteBound))
        << "e = " << e << " decoded " << d;
  }
  EXPECT_EQ(quantizeIrradiance(0.0f), 0);
  EXPECT_EQ(quantizeIrradiance(-1.0f), 0);
  EXPECT_EQ(quantizeIrradiance(std::nanf("")), 0);
  EXPECT_EQ(dequantizeIrradiance(quantizeIrradiance(1.0f)), 1.0f);
  // Codes are monotonic in the value, so residuals between close values are small.
  EXPECT_LT(quantizeIrradiance(0.5f), quantizeIrradiance(0.51f));
}

TEST(BrickCodec, RoundTripWithinStatedBounds) {
  Field server = test::makeSyntheticLayout();
  std::mt19937 rng(1);
  test::evolveField(server, rng, 1.0f, 0.0f);
  Field mirror = test::quantizedCopy(server);
  for (int k = 0; k < server.cascadeCount(); ++k) {
    const CascadeDesc& c = server.cascade(k);
    const float D = c.maxRayDistance;
    for (int slot = 0; slot < pcSlotCount(c); ++slot) {
      if (!pcSlotValid(c, slot)) continue;
      auto each = [&](const Atlas& a, const Atlas& b, int n, auto&& check) {
        const glm::ivec2 o = pcAtlasTileOrigin(c, slot, n + 2);
        for (int y = 0; y < n + 2; ++y)  // borders included: they follow the interiors
          for (int x = 0; x < n + 2; ++x) check(a.at(o.x + x, o.y + y), b.at(o.x + x, o.y + y));
      };
      each(server.irradiance, mirror.irradiance, PC_IRRADIANCE_TEXELS,
           [&](const float* a, const float* b) {
             for (int ch = 0; ch < 3; ++ch)
               ASSERT_LE(std::abs(a[ch] - b[ch]), kIrradianceRelativeBound * a[ch] + 1e-7f);
           });
      each(server.depth, mirror.depth, PC_DEPTH_TEXELS, [&](const float* a, const float* b) {
        const float bound = kDepthBound * D * 1.001f;
        ASSERT_LE(std::abs(a[0] - b[0]), bound);
        const float sa = std::sqrt(std::max(a[1] - a[0] * a[0], 0.0f));
        const float sb = std::sqrt(std::max(b[1] - b[0] * b[0], 0.0f));
        // float rounding of mean^2 + sigma^2 adds a little on top of the code's bound
        ASSERT_LE(std::abs(sa - sb), bound + 1e-3f * sa + 1e-5f * D);
        ASSERT_LE(std::abs(a[1] - b[1]), 4.0f * D * bound + 1e-6f * D * D);
      });
      each(server.occlusion, mirror.occlusion, PC_OCCLUSION_TEXELS,
           [&](const float* a, const float* b) {
             ASSERT_LE(std::abs(a[0] - b[0]), kOcclusionBound + 1e-6f);
           });
      const ProbeRecord& pa = server.probe(k, slot);
      const ProbeRecord& pb = mirror.probe(k, slot);
      for (int i = 0; i < 3; ++i)
        ASSERT_LE(std::abs(pa.offset[i] - pb.offset[i]), kOffsetBound * c.spacing * 1.001f);
      ASSERT_EQ(pa.state, pb.state);
    }
  }
}

TEST(BrickCodec, EncodeDecodeSelfContainedAndResidualAgree) {
  Field f = test::makeSyntheticLayout();
  std::mt19937 rng(2);
  test::evolveField(f, rng, 1.0f, 0.0f);
  const QuantizedBrick v1 = quantizeBrick(f, 0, 3);
  test::paintBrick(f, 0, 3, 0.05f);  // a small change, as between two updates
  const QuantizedBrick v2 = quantizeBrick(f, 0, 3);
  ASSERT_NE(v1, v2);

  const auto self = encodeBrick(v2, nullptr);
  const auto residual = encodeBrick(v2, &v1);
  auto a = decodeBrick(self, nullptr);
  auto b = decodeBrick(residual, &v1);
  ASSERT_TRUE(a.ok()) << a.error().message;
  ASSERT_TRUE(b.ok()) << b.error().message;
  EXPECT_EQ(*a, v2);
  EXPECT_EQ(*b, v2);

  // The wrong kind of base is refused, not misapplied.
  EXPECT_FALSE(decodeBrick(residual, nullptr).ok());
  EXPECT_FALSE(decodeBrick(self, &v1).ok());

  const double raw = double(brick_layout::kCodes) * 2.0;
  std::printf("brick: %zu bytes self-contained, %zu residual (raw quantized %.0f, float %.0f)\n",
              self.size(), residual.size(), raw, 64.0 * (64 * 3 + 256 * 2 + 64 + 4) * 4.0);
  EXPECT_LT(self.size(), raw / 2);
}

TEST(BrickCodec, ChangeMeasure) {
  Field f = test::makeSyntheticLayout();
  std::mt19937 rng(4);
  test::evolveField(f, rng, 1.0f, 0.0f);
  const QuantizedBrick a = quantizeBrick(f, 0, 0);
  EXPECT_EQ(brickChange(a, a).irradiance, 0.0f);
  test::paintBrick(f, 0, 0, 0.5f);
  const BrickChange c = brickChange(a, quantizeBrick(f, 0, 0));
  EXPECT_GT(c.irradiance, 0.01f);
  EXPECT_LT(c.irradiance, 0.5f);
}

TEST(BrickCodec, HostilePayloadsAreRejected) {
  Field f = test::makeSyntheticLayout();
  std::mt19937 rng(5);
  test::evolveField(f, rng, 1.0f, 0.0f);
  const QuantizedBrick base = quantizeBrick(f, 1, 0);
  test::paintBrick(f, 1, 0, 0.2f);
  const QuantizedBrick next = quantizeBrick(f, 1, 0);
  const auto self = encodeBrick(next, nullptr);
  const auto residual = encodeBrick(next, &base);

  auto check = [&](const std::vector<std::uint8_t>& bytes, const QuantizedBrick* b) {
    auto r = decodeBrick(bytes, b);
    if (r.ok()) {
      // Anything accepted is a complete brick of in-range codes, safe to apply.
      ASSERT_EQ(r->codes.size(), brick_layout::kCodes);
      Field scratch = test::makeSyntheticLayout();
      applyBrick(scratch, 1, 0, *r);
    } else {
      ASSERT_FALSE(r.error().message.empty());
    }
  };
  // Random bytes, with and without a plausible header.
  for (int i = 0; i < 300; ++i) {
    std::vector<std::uint8_t> junk(rng() % 3000);
    for (auto& x : junk) x = std::uint8_t(rng());
    if (i % 2 && junk.size() >= 4) std::copy(self.begin(), self.begin() + 4, junk.begin());
    check(junk, nullptr);
    check(junk, &base);
  }
  // Every truncation.
  for (std::size_t n = 0; n < self.size(); n += 7) {
    std::vector<std::uint8_t> cut(self.begin(), self.begin() + std::ptrdiff_t(n));
    EXPECT_FALSE(decodeBrick(cut, nullptr).ok()) << n;
  }
  // Bit flips: zstd's checksum and the header checks catch them.
  int accepted = 0;
  for (int i = 0; i < 400; ++i) {
    auto bytes = (i % 2) ? residual : self;
    bytes[rng() % bytes.size()] ^= std::uint8_t(1u << (rng() % 8));
    const QuantizedBrick* b = (i % 2) ? &base : nullptr;
    auto r = decodeBrick(bytes, b);
    if (r.ok()) ++accepted;
    check(bytes, b);
  }
  std::printf("bit flips accepted: %d of 400 (a flip in zstd's unchecked bits can decode)\n",
              accepted);
  // Trailing bytes.
  auto longer = self;
  longer.push_back(0);
  EXPECT_FALSE(decodeBrick(longer, nullptr).ok());
  // A base of the wrong size.
  QuantizedBrick small;
  small.codes.resize(10);
  EXPECT_FALSE(decodeBrick(residual, &small).ok());
}

TEST(BrickCodec, DeadZoneHoldsSmallChangesWithinItsTolerance) {
  Field f = test::makeSyntheticLayout();
  std::mt19937 rng(6);
  test::evolveField(f, rng, 1.0f, 0.0f);
  const QuantizedBrick previous = quantizeBrick(f, 0, 1);
  test::paintBrick(f, 0, 1, 0.02f);  // small moves everywhere
  const QuantizedBrick exact = quantizeBrick(f, 0, 1);
  DeadZone dz;
  dz.irradiance = 0.01f;
  dz.depth = 0.02f;
  dz.occlusion = 0.02f;
  QuantizedBrick held = exact;
  const std::size_t kept = holdSmallChanges(held, previous, dz);
  EXPECT_GT(kept, 0u);
  using namespace brick_layout;
  constexpr std::size_t kDepthPlane = std::size_t(kSlots) * kDepthTexels;
  for (std::size_t i = 0; i < kCodes; ++i) {
    // Every code is either the fresh one or the previous one within the tolerance.
    if (held.codes[i] == exact.codes[i]) continue;
    ASSERT_EQ(held.codes[i], previous.codes[i]) << i;
    if (i < kDepth) {
      ASSERT_LE(
          std::abs(dequantizeIrradiance(held.codes[i]) - dequantizeIrradiance(exact.codes[i])),
          dz.irradiance);
    } else if (i < kOcclusion) {
      const std::size_t mean = kDepth + (i - kDepth) % kDepthPlane;
      ASSERT_LE(std::abs(int(held.codes[i]) - int(exact.codes[i])),
                dz.depth * float(exact.codes[mean]));
    } else {
      ASSERT_LT(i, kOffset) << "offsets and states are never held";
      ASSERT_LE(std::abs(int(held.codes[i]) - int(exact.codes[i])), int(dz.occlusion * 255.0f));
    }
  }
  // A large change passes; no tolerance changes nothing.
  test::paintBrick(f, 0, 1, 2.0f);
  QuantizedBrick moved = quantizeBrick(f, 0, 1);
  const QuantizedBrick movedExact = moved;
  holdSmallChanges(moved, previous, dz);
  EXPECT_NE(moved, previous);
  QuantizedBrick untouched = movedExact;
  EXPECT_EQ(holdSmallChanges(untouched, previous, DeadZone{}), 0u);
  EXPECT_EQ(untouched, movedExact);
}

TEST(BrickCodec, DeadZoneHoldsOffsetsOfProbesThatAreNotSampled) {
  Field f = test::makeSyntheticLayout();
  std::mt19937 rng(7);
  test::evolveField(f, rng, 1.0f, 0.0f);
  const int brick = 1;
  const int inside = brick * gpu::PC_PROBES_PER_BRICK + 3;
  const int active = brick * gpu::PC_PROBES_PER_BRICK + 4;
  f.probe(0, inside).state = gpu::PC_PROBE_INSIDE;
  f.probe(0, active).state = gpu::PC_PROBE_ACTIVE;
  const QuantizedBrick previous = quantizeBrick(f, 0, brick);
  // Both wander by 30% of the spacing, far past a 5% dead zone.
  const float spacing = f.cascade(0).spacing;
  f.probe(0, inside).offset += glm::vec3(0.3f * spacing, 0.0f, 0.0f);
  f.probe(0, active).offset += glm::vec3(0.3f * spacing, 0.0f, 0.0f);
  QuantizedBrick q = quantizeBrick(f, 0, brick);
  DeadZone dz;
  dz.offset = 0.05f;
  holdSmallChanges(q, previous, dz);
  using namespace brick_layout;
  EXPECT_EQ(q.codes[kOffset + 3], previous.codes[kOffset + 3]) << "inside: never read, held";
  EXPECT_NE(q.codes[kOffset + 4], previous.codes[kOffset + 4]) << "active: a real move passes";
  // The change measure sees the active probe's move as a fraction of the spacing.
  const BrickChange c = brickChange(q, previous);
  EXPECT_NEAR(c.offset, 0.3f, 0.01f);
  EXPECT_FALSE(c.states);
}

}  // namespace
