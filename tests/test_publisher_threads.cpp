// The publisher and the change cache read by several senders' threads at once (the server
// polls datagram sessions in parallel under FieldHub's shared lock): what each thread gets is
// what one thread alone gets, and the coarsened copies the publisher keeps stay within their
// cap.
#include <gtest/gtest.h>

#include <random>
#include <thread>
#include <vector>

#include "protocol/brick_codec.h"
#include "protocol/brick_precision.h"
#include "protocol/field_publisher.h"
#include "protocol/stream_sender.h"
#include "test_protocol_support.h"

namespace {

using namespace pc;

struct Request {
  int cascade, brick;
  std::uint64_t version, base;
  int precision, basePrecision;
};

// A publisher with a few versions of every brick, and every (version, base, level) an encode
// may be asked for.
struct Published {
  Field field = test::makeSyntheticLayout();
  std::unique_ptr<FieldPublisher> publisher;
  std::vector<Request> requests;

  explicit Published(PublisherOptions options = {}) {
    publisher = std::make_unique<FieldPublisher>(field, options);
    std::mt19937 rng(5);
    for (int u = 0; u < 4; ++u) {
      test::evolveField(field, rng, 1.0f, 0.3f * float(u));
      EXPECT_TRUE(publisher->publish(field, double(u)).ok());
    }
    for (int k = 0; k < field.cascadeCount(); ++k) {
      for (int b = 0; b < publisher->brickCount(k); ++b) {
        const std::uint64_t v = publisher->current(k, b).version;
        for (std::uint64_t base = 0; base < v; ++base)
          for (int p = 0; p <= kMaxPrecision; ++p)
            requests.push_back({k, b, v, base, p, base == 0 ? 0 : (p + 1) % (kMaxPrecision + 1)});
      }
    }
  }
};

TEST(PublisherThreads, ConcurrentEncodesEqualOneThreadsAndDecodeToTheCoarseVersion) {
  Published serial, parallel;
  ASSERT_EQ(serial.requests.size(), parallel.requests.size());
  ASSERT_GT(serial.requests.size(), 100u);
  std::vector<std::vector<std::uint8_t>> expected;
  for (const Request& r : serial.requests) {
    auto u = serial.publisher->encoded(r.cascade, r.brick, r.version, r.base, r.precision,
                                       r.basePrecision);
    ASSERT_TRUE(u);
    expected.push_back(u->payload);
  }
  // Eight threads ask for every update, each in its own order, so that most are asked for by
  // several threads at once.
  constexpr int kThreads = 8;
  std::vector<std::vector<std::uint8_t>> got(parallel.requests.size());
  std::vector<int> mismatches(kThreads, 0);
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&, t] {
      std::vector<std::size_t> order(parallel.requests.size());
      for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
      std::shuffle(order.begin(), order.end(), std::mt19937(std::uint32_t(t)));
      for (std::size_t i : order) {
        const Request& r = parallel.requests[i];
        auto u = parallel.publisher->encoded(r.cascade, r.brick, r.version, r.base, r.precision,
                                             r.basePrecision);
        if (!u || u->payload != expected[i]) ++mismatches[std::size_t(t)];
      }
    });
  }
  for (std::thread& t : threads) t.join();
  for (int t = 0; t < kThreads; ++t) EXPECT_EQ(mismatches[std::size_t(t)], 0) << "thread " << t;
  // Each update was encoded once or a few times (threads racing on a miss), never lost.
  EXPECT_GE(parallel.publisher->encodes(), parallel.requests.size());
  EXPECT_LE(parallel.publisher->encodes(), kThreads * parallel.requests.size());
  // What a coarse update decodes to is the version coarsened, on top of the coarse base.
  for (const Request& r : parallel.requests) {
    if (r.base == 0) continue;
    auto u = parallel.publisher->encoded(r.cascade, r.brick, r.version, r.base, r.precision,
                                         r.basePrecision);
    auto base = parallel.publisher->find(r.cascade, r.brick, r.base, r.basePrecision);
    auto want = parallel.publisher->find(r.cascade, r.brick, r.version, r.precision);
    ASSERT_TRUE(u && base && want);
    auto decoded = decodeBrick(u->payload, base.get());
    ASSERT_TRUE(decoded.ok()) << decoded.error().message;
    EXPECT_EQ(*decoded, *want);
  }
}

TEST(PublisherThreads, CoarseCopiesStayWithinTheirCapAndStayCorrect) {
  PublisherOptions o;
  const std::size_t brickBytes = brick_layout::kCodes * sizeof(std::uint16_t);
  o.maxCoarseBytes = 3 * brickBytes;
  Published p(o);
  for (const Request& r : p.requests) {
    auto coarse = p.publisher->find(r.cascade, r.brick, r.version, r.precision);
    ASSERT_TRUE(coarse);
    EXPECT_EQ(*coarse,
              coarsenBrick(*p.publisher->find(r.cascade, r.brick, r.version), r.precision));
    EXPECT_LE(p.publisher->coarseBytes(), o.maxCoarseBytes);
  }
  EXPECT_GT(p.publisher->coarseBytes(), 0u);
  // Kept copies are shared: the same level asked for again is the same object.
  const Request& r = p.requests.back();
  ASSERT_GT(r.precision, 0);
  EXPECT_EQ(p.publisher->find(r.cascade, r.brick, r.version, r.precision),
            p.publisher->find(r.cascade, r.brick, r.version, r.precision));
}

TEST(PublisherThreads, SharedChangeCacheGivesEveryThreadTheSameChanges) {
  Published p;
  BrickChangeCache shared;
  std::vector<std::optional<BrickChange>> expected;
  for (const Request& r : p.requests) {
    if (r.base == 0) continue;
    auto cur = p.publisher->find(r.cascade, r.brick, r.version);
    auto old = p.publisher->find(r.cascade, r.brick, r.base, r.basePrecision);
    expected.push_back(brickChange(*cur, *old));
  }
  constexpr int kThreads = 6;
  std::vector<int> mismatches(kThreads, 0);
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&, t] {
      std::size_t i = 0;
      for (const Request& r : p.requests) {
        if (r.base == 0) continue;
        auto c = shared.get(*p.publisher, r.cascade, r.brick, r.version, r.base, r.basePrecision);
        if (!c || !expected[i] || c->irradiance != expected[i]->irradiance ||
            c->irradianceMeanSquare != expected[i]->irradianceMeanSquare ||
            c->depth != expected[i]->depth || c->occlusion != expected[i]->occlusion)
          ++mismatches[std::size_t(t)];
        ++i;
      }
    });
  }
  for (std::thread& t : threads) t.join();
  for (int t = 0; t < kThreads; ++t) EXPECT_EQ(mismatches[std::size_t(t)], 0) << "thread " << t;
}

}  // namespace
