// Probes at rest (server/probe_rest.h): a probe whose blended irradiance still converges keeps
// being updated, one whose changes are only noise rests, any change of the scene wakes them all,
// and the scheduler then updates a resting probe once a rest period, a brick at a time.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <set>

#include "server/probe_rest.h"
#include "server/probe_scheduler.h"
#include "test_protocol_support.h"

namespace {

using namespace pc;

void setProbeIrradiance(Field& f, int k, int slot, float value) {
  constexpr int n = gpu::PC_IRRADIANCE_TEXELS;
  const glm::ivec2 o = gpu::pcAtlasTileOrigin(f.cascade(k), slot, n + 2) + glm::ivec2(1);
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      float* t = f.irradiance.at(o.x + x, o.y + y);
      t[0] = t[1] = t[2] = value;
    }
}

std::size_t probeIndex(const Field& f, ProbeRef r) {
  return std::size_t(f.cascade(r.cascade).firstProbe) + std::size_t(r.slot);
}

// One blended update of every probe: x <- h x + (1 - h) sample, the sample the target plus
// relative noise, as a tracer's blend does.
void blendAll(Field& f, std::vector<float>& x, float target, float noise, std::mt19937& rng,
              ProbeRest& rest, const std::vector<ProbeRef>& probes) {
  std::normal_distribution<float> n(0.0f, noise);
  for (std::size_t i = 0; i < probes.size(); ++i) {
    x[i] = 0.97f * x[i] + 0.03f * target * (1.0f + n(rng));
    setProbeIrradiance(f, probes[i].cascade, probes[i].slot, x[i]);
  }
  rest.observe(f, probes);
}

std::vector<ProbeRef> everyProbe(const Field& f) {
  std::vector<ProbeRef> out;
  for (int k = 0; k < f.cascadeCount(); ++k)
    for (int s = 0; s < gpu::pcSlotCount(f.cascade(k)); ++s)
      if (gpu::pcSlotValid(f.cascade(k), s)) out.push_back({k, s});
  return out;
}

TEST(ProbeRest, ConvergingProbesStayAwakeNoisyConvergedOnesRestAChangeWakesAll) {
  Field f = test::makeSyntheticLayout();
  const std::vector<ProbeRef> probes = everyProbe(f);
  ProbeRest rest;
  std::mt19937 rng(3);
  // From 0.2 toward 1.0 at a hysteresis of 0.97: for the first 40 updates each probe is still
  // at least 30% below its target, and every change points the same way.
  std::vector<float> x(probes.size(), 0.2f);
  for (int u = 0; u < 40; ++u) {
    blendAll(f, x, 1.0f, 0.05f, rng, rest, probes);
    EXPECT_EQ(rest.restingProbes(), 0u) << "update " << u;
  }
  // Converged (x starts at the target): the changes are noise, and nearly every probe rests
  // once its window is measured.
  std::fill(x.begin(), x.end(), 1.0f);
  rest.wakeAll();
  for (int u = 0; u < 60; ++u) blendAll(f, x, 1.0f, 0.05f, rng, rest, probes);
  EXPECT_GE(rest.restingProbes(), probes.size() * 9 / 10);
  // A change of the scene wakes every probe at once.
  rest.wakeAll();
  EXPECT_EQ(rest.restingProbes(), 0u);
  for (const ProbeRef& p : probes) EXPECT_FALSE(rest.resting(probeIndex(f, p)));
  // A dark probe whose irradiance does not move at all rests too.
  std::fill(x.begin(), x.end(), 0.0f);
  blendAll(f, x, 0.0f, 0.0f, rng, rest, probes);
  rest.wakeAll();
  for (int u = 0; u < 20; ++u) blendAll(f, x, 0.0f, 0.0f, rng, rest, probes);
  EXPECT_EQ(rest.restingProbes(), probes.size());
}

TEST(ProbeRest, TheSchedulerUpdatesARestingProbeOncePerPeriodABrickAtATime) {
  Field f = test::makeSyntheticLayout();
  const std::vector<ProbeRef> probes = everyProbe(f);
  for (const ProbeRef& p : probes) f.probe(p.cascade, p.slot).state = gpu::PC_PROBE_ACTIVE;
  RestOptions o;
  o.period = 16;
  ProbeRest rest(o);
  std::vector<float> x(probes.size(), 0.0f);
  std::mt19937 rng(1);
  for (int u = 0; u < 20; ++u) blendAll(f, x, 0.0f, 0.0f, rng, rest, probes);
  ASSERT_EQ(rest.restingProbes(), probes.size());
  ProbeScheduler scheduler;
  // The first plan takes every probe (never updated); then each resting probe once in each
  // period of 16 ticks, and the probes of a brick always together.
  EXPECT_EQ(scheduler.plan(f, 1, {}, {}, &rest).size(), probes.size());
  std::map<std::size_t, int> updates;
  std::size_t planned = 0;
  for (std::uint64_t tick = 2; tick < 2 + 16 * 4; ++tick) {
    const std::vector<ProbeRef> plan = scheduler.plan(f, tick, {}, {}, &rest);
    planned += plan.size();
    std::set<std::pair<int, int>> bricks;
    for (const ProbeRef& p : plan) {
      ++updates[probeIndex(f, p)];
      bricks.insert({p.cascade, p.slot / gpu::PC_PROBES_PER_BRICK});
    }
    // Whole bricks: every valid probe of each brick planned.
    std::size_t inBricks = 0;
    for (const auto& [k, b] : bricks)
      for (int s = b * gpu::PC_PROBES_PER_BRICK; s < (b + 1) * gpu::PC_PROBES_PER_BRICK; ++s)
        inBricks += gpu::pcSlotValid(f.cascade(k), s) ? 1 : 0;
    EXPECT_EQ(plan.size(), inBricks) << "tick " << tick;
  }
  for (const ProbeRef& p : probes) EXPECT_EQ(updates[probeIndex(f, p)], 4);
  EXPECT_EQ(planned, 4 * probes.size());
  // Awake again: every probe every tick.
  rest.wakeAll();
  EXPECT_EQ(scheduler.plan(f, 100, {}, {}, &rest).size(), probes.size());
}

}  // namespace
