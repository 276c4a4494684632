// rest: what a still scene costs. An in-process server (Embree, the field thread and the network
// thread as probecast-server runs them, TLS on loopback) and N viewer clients. The scene's own
// animation is taken out; a light circles for --moving seconds (one runtime edit per field
// update), then stops for --still seconds, then one edit changes it again.
//   rest_gpu_fraction: tracing time per second over the last half of the still phase, over the
//     same in the last half of the moving phase (Embree here: CPU time of the update).
//   rest_bytes_fraction: bytes per second per client received, the same two windows.
//   rest_settle_s: from the stop until the tracing time per second (over 1 s) falls below 5% of
//     the moving phase's and stays there.
//   rest_wake_updates: updates from the one that traces the waking edit's state until one
//     traces at least 90% of the probes an update traced while moving (1: that one itself).
#include <algorithm>
#include <atomic>
#include <cmath>
#include <memory>
#include <thread>

#include "bench.h"
#include "client/field_mirror.h"
#include "client/net_client.h"
#include "loopback_server.h"

namespace pc::bench {

namespace {

struct RestSetup {
  std::string scene = "builtin", sidecar;
  int clients = 4;
  double moving = 6.0, still = 8.0;  // s
  double rate = 10;                  // field updates per second
  int rays = 64, bakeUpdates = 16;
  int period = RestOptions{}.period;
};

// One sample of the server's figures, taken every few milliseconds.
struct Sample {
  double at;             // s since the run started
  double updateSeconds;  // FieldLoopStats::updateSeconds
  std::uint64_t ticks, editVersion;
  int probesUpdated;
  std::size_t resting;
  std::uint64_t bytes;  // received by all viewers
};

int runRest(const RestSetup& o) {
  auto loaded = loadBenchScene(o.scene, o.sidecar);
  if (!loaded) return std::fprintf(stderr, "rest: %s\n", loaded.error().message.c_str()), 1;
  Scene scene = std::move(loaded).value();
  // Still unless edited: every light and instance off its animation.
  for (Light& l : scene.lights) l.animation = -1;
  for (auto& i : scene.instances) i.animation = -1;
  LoopbackServerOptions serverOptions;
  serverOptions.rays = o.rays;
  serverOptions.bakeUpdates = o.bakeUpdates;
  serverOptions.clients = o.clients;
  serverOptions.loop.rate = o.rate;
  serverOptions.loop.rest.period = o.period;
  auto started = LoopbackServer::start(scene, serverOptions);
  if (!started) return std::fprintf(stderr, "rest: %s\n", started.error().message.c_str()), 1;
  LoopbackServer& server = **started;
  SceneEditor& editor = server.editor();
  FieldLoop& loop = server.loop();
  std::vector<std::unique_ptr<client::FieldMirror>> mirrors;
  std::vector<std::unique_ptr<client::NetClient>> viewers;
  for (int i = 0; i < o.clients; ++i) {
    mirrors.push_back(std::make_unique<client::FieldMirror>());
    viewers.push_back(std::make_unique<client::NetClient>(
        *mirrors.back(), server.clientOptions("viewer-" + std::to_string(i), TokenRole::Viewer)));
    viewers.back()->start();
  }
  const auto sleep = [](double s) {
    std::this_thread::sleep_for(std::chrono::duration<double>(s));
  };
  const double start = steadySeconds();
  const auto allSynced = [&] {
    for (const auto& v : viewers)
      if (!v->stats().synced) return false;
    return true;
  };
  while (!allSynced() && steadySeconds() - start < 60) sleep(0.05);
  const bool synced = allSynced();
  std::printf("rest: %d viewers %s after %.1f s\n", o.clients, synced ? "synced" : "NOT all synced",
              steadySeconds() - start);

  // The light that moves: the scene's first, else one added.
  std::uint32_t light = 0;
  const glm::vec3 center = 0.5f * (scene.boundsMin + scene.boundsMax);
  const glm::vec3 half = 0.5f * (scene.boundsMax - scene.boundsMin);
  const auto lightAt = [&](double t, EditOp op) {
    SceneEdit e;
    e.op = op;
    e.target = light;
    e.fields = kEditPosition | kEditIntensity;
    const float a = float(t) * 0.8f;
    e.position = center + half * glm::vec3(0.5f * std::cos(a), 0.4f, 0.5f * std::sin(a));
    e.intensity = 3.0f;
    return e;
  };
  if (scene.lights.empty()) {
    auto added = editor.submit(lightAt(0, EditOp::AddLight));
    if (!added) return std::fprintf(stderr, "rest: %s\n", added.error().message.c_str()), 1;
    light = added->target;
  }

  std::vector<Sample> samples;
  const auto sample = [&] {
    const FieldLoopStats s = loop.stats();
    std::uint64_t bytes = 0;
    for (const auto& v : viewers) {
      const client::NetClientStats c = v->stats();
      bytes += c.udpBytes + c.tcpBytes;
    }
    samples.push_back({steadySeconds() - start, s.updateSeconds, s.ticks, s.editVersion,
                       s.lastUpdate.probesUpdated, s.restingProbes, bytes});
  };
  // Moving: one edit per field update.
  const double moveStart = steadySeconds() - start;
  std::uint64_t editVersion = 0;
  for (double next = moveStart; steadySeconds() - start < moveStart + o.moving;) {
    const double now = steadySeconds() - start;
    if (now >= next) {
      auto moved = editor.submit(lightAt(now, EditOp::SetLight));
      if (moved) editVersion = moved->version;
      next += 1.0 / o.rate;
    }
    sample();
    sleep(0.005);
  }
  const double stopAt = steadySeconds() - start;
  while (steadySeconds() - start < stopAt + o.still) {
    sample();
    sleep(0.005);
  }
  // Wake: one change of the light, then a second for the field to answer.
  const double wakeAt = steadySeconds() - start;
  auto woken = editor.submit(lightAt(wakeAt + 5.0, EditOp::SetLight));
  const std::uint64_t wakeVersion = woken ? woken->version : editVersion + 1;
  while (steadySeconds() - start < wakeAt + 1.5) {
    sample();
    sleep(0.005);
  }
  server.stop();
  for (auto& v : viewers) v->stop();

  // Rates over a window [from, to] of the run.
  const auto at = [&](double t) {
    return *std::min_element(samples.begin(), samples.end(), [&](const Sample& a, const Sample& b) {
      return std::abs(a.at - t) < std::abs(b.at - t);
    });
  };
  const auto rates = [&](double from, double to) {
    const Sample a = at(from), b = at(to);
    const double dt = std::max(1e-9, b.at - a.at);
    return std::pair{(b.updateSeconds - a.updateSeconds) / dt,
                     double(b.bytes - a.bytes) / dt / double(std::max(1, o.clients))};
  };
  const auto [movingTrace, movingBytes] = rates(stopAt - o.moving / 2, stopAt);
  const auto [stillTrace, stillBytes] = rates(stopAt + o.still / 2, wakeAt);
  double settle = -1;
  for (double t = stopAt; t + 1.0 <= wakeAt; t += 0.05) {
    bool below = true;
    for (double u = t; u + 1.0 <= wakeAt && below; u += 0.05)
      below = rates(u, u + 1.0).first < 0.05 * movingTrace;
    if (below) {
      settle = t + 1.0 - stopAt;
      break;
    }
  }
  // Probes per update while moving, and the updates after the wake.
  double movingProbes = 0;
  int movingN = 0;
  for (const Sample& s : samples)
    if (s.at > stopAt - o.moving / 2 && s.at < stopAt) movingProbes += s.probesUpdated, ++movingN;
  movingProbes /= std::max(1, movingN);
  int wakeUpdates = -1;
  std::uint64_t firstTick = 0;
  for (const Sample& s : samples) {
    if (s.at < wakeAt || s.editVersion < wakeVersion) continue;
    if (firstTick == 0) firstTick = s.ticks;
    if (s.probesUpdated >= 0.9 * movingProbes) {
      wakeUpdates = int(s.ticks - firstTick) + 1;
      break;
    }
  }
  std::printf(
      "rest: %s; %s, %d viewers, field at %.0f updates/s, %d rays, rest period %d\n"
      "  moving: tracing %.1f ms/s, %.1f kB/s per client, %.0f probes per update\n"
      "  still:  tracing %.1f ms/s, %.2f kB/s per client (second half of %.0f s)\n",
      machineDescription().c_str(), o.scene.c_str(), o.clients, o.rate, o.rays, o.period,
      movingTrace * 1e3, movingBytes / 1e3, movingProbes, stillTrace * 1e3, stillBytes / 1e3,
      o.still);
  std::printf("  after the stop, s:     ");
  for (int t = 0; t <= int(o.still); ++t) std::printf(" %6d", t);
  std::printf("\n  probes at rest:        ");
  for (int t = 0; t <= int(o.still); ++t) std::printf(" %6zu", at(stopAt + t).resting);
  std::printf("\n  probes per update:     ");
  for (int t = 0; t <= int(o.still); ++t) std::printf(" %6d", at(stopAt + t).probesUpdated);
  std::printf("\n");
  figure("rest_gpu_fraction", stillTrace / std::max(1e-12, movingTrace), "ratio");
  figure("rest_bytes_fraction", stillBytes / std::max(1e-12, movingBytes), "ratio");
  figure("rest_settle_s", settle, "s");
  figure("rest_wake_updates", wakeUpdates, "count");
  return synced && wakeUpdates > 0 ? 0 : 1;
}

}  // namespace

Benchmark addRest(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "rest", "a still scene: tracing and streaming at rest against moving, settling and waking");
  static RestSetup o;
  cmd->add_option("--scene", o.scene, "glTF/OBJ scene, or 'builtin'");
  cmd->add_option("--sidecar", o.sidecar, "scene.json sidecar");
  addSceneLoadOptions(*cmd, sceneLoadOptions());
  cmd->add_option("--clients", o.clients, "viewer clients, each with its own session")
      ->check(CLI::Range(1, 200));
  cmd->add_option("--moving", o.moving, "seconds the light moves")->check(CLI::Range(1.0, 600.0));
  cmd->add_option("--still", o.still, "seconds it then stays still")->check(CLI::Range(2.0, 600.0));
  cmd->add_option("--rate", o.rate, "field updates per second")->check(CLI::Range(1.0, 240.0));
  cmd->add_option("--rays", o.rays, "rays per probe per update")->check(CLI::Range(8, 4096));
  cmd->add_option("--bake-updates", o.bakeUpdates, "updates of the field before serving")
      ->check(CLI::Range(1, 1000));
  cmd->add_option("--rest-period", o.period, "ticks between updates of a resting probe")
      ->check(CLI::Range(1, 100000));
  return {cmd, [] { return runRest(o); }};
}

}  // namespace pc::bench
