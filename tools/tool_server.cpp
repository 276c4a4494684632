// probecast-server: updates a scene's probe field on the animation clock and streams it to
// clients (TCP session, UDP brick datagrams). Two threads besides main: the field thread
// (trace, blend, publish) and the network thread; main waits for SIGINT/SIGTERM (or
// --duration) and prints statistics.
#include <pthread.h>
#include <signal.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "common/log.h"
#include "common/volume_placement.h"
#include "protocol/baked_file.h"
#include "protocol/stream_tuning.h"
#include "relay/field_export.h"
#include "server/bake.h"
#include "server/net_field_loop.h"
#include "server/net_server.h"
#include "server/vulkan_tracer.h"
#include "tools/command_line.h"
#include "tools/serve_options.h"

namespace {

using pc::addLimitOptions;
using pc::addReportOptions;
using pc::addStreamOptions;
using pc::Signals;

// The statistics: one line for the server, then one per client (a log line never spans lines).
std::vector<std::string> statsLines(const pc::NetServerStats& now, const pc::NetServerStats& before,
                                    double seconds, const pc::FieldLoopStats& field) {
  char line[256];
  const double rate = seconds > 0 ? double(now.bytesSent - before.bytesSent) / seconds : 0.0;
  std::snprintf(line, sizeof line,
                "clients %zu | sent %.1f kB/s | field v%llu, t=%.2f s, update %.1f ms, %d bricks "
                "changed | accepted %llu, rejected %llu",
                now.clients.size(), rate / 1e3, (unsigned long long)field.fieldVersion,
                field.animationTime, field.lastUpdateMs, field.lastBricksChanged,
                (unsigned long long)now.accepted, (unsigned long long)now.rejected);
  std::vector<std::string> lines{line};
  for (const pc::NetClientInfo& c : now.clients) {
    // The name is the client's own text: quoted, so it cannot pose as another line.
    std::snprintf(line, sizeof line,
                  "  session %u %s (%s, %s): %.1f kB sent, %llu datagrams, %zu bricks pending",
                  c.sessionId, pc::quoteUntrusted(c.name, 64).c_str(), c.peer.c_str(),
                  c.udp ? "udp" : "tcp", double(c.bytesSent) / 1e3, (unsigned long long)c.datagrams,
                  c.pendingBricks);
    lines.emplace_back(line);
  }
  return lines;
}

// The statistics: in a JSON log one "statistics" record with named fields and one "client
// statistics" record per client; in a text log the same lines as ever.
void logStatistics(const pc::NetServerStats& now, const pc::NetServerStats& before, double seconds,
                   const pc::FieldLoopStats& field) {
  const std::vector<std::string> lines = statsLines(now, before, seconds, field);
  std::vector<pc::LogField> fields = pc::statisticsFields(now, before, seconds);
  pc::appendFieldLoopFields(fields, field);
  pc::logRecord(pc::LogLevel::Info, "statistics", fields, lines.front());
  for (std::size_t i = 0; i < now.clients.size(); ++i) {
    pc::logRecord(pc::LogLevel::Info, "client statistics",
                  pc::clientStatisticsFields(now.clients[i]), lines[i + 1]);
  }
}

// The command line's settings, and what follows from them once parsed.
// The name connect tokens give a scene: "builtin", the folder of a file called scene.* (the
// layout of scene collections: <name>/scene.gltf), else the file's stem.
std::string sceneNameOf(const std::string& scenePath) {
  if (scenePath == "builtin") return scenePath;
  const std::filesystem::path path(scenePath);
  if (path.stem() == "scene" && path.has_parent_path())
    return path.parent_path().filename().string();
  return path.stem().string();
}

struct ServerSetup : pc::ServeSetup {
  std::string scenePath = "builtin", sidecar, probes, backend = "auto", dumpField;
  pc::SceneLoadOptions sceneLoad;
  pc::FieldLoopOptions loop;
  pc::TracerOptions tracerOptions;
  std::size_t gpuShadowMiB = 0;
  bool noFallback = false;
  bool followViewers = false;
  int gpuFailSubmission = 0;
  int rays = 256, warmup = 32;
  // Field distribution to relays (relay/): off while nats.urls is empty.
  pc::relay::NatsOptions nats{.urls = ""};
  pc::relay::BucketOptions bucket;
};

void addTracerOptions(CLI::App& app, ServerSetup& s) {
  app.add_option("--scene", s.scenePath, "glTF/OBJ scene, or 'builtin'");
  app.add_option("--sidecar", s.sidecar, "scene.json sidecar");
  pc::addSceneLoadOptions(app, s.sceneLoad);
  app.add_option("--probes", s.probes, "start from this baked field (else a short warm-up bake)");
  app.add_option(
      "--backend", s.backend,
      "tracer: auto, embree, vulkan (ray tracing) or sdf (distance field in Vulkan compute)");
  app.add_option(
         "--shadow-roulette", s.tracerOptions.shadowRouletteShare,
         "share of a hit's punctual light below which a light's shadow ray is drawn at random, "
         "weighted to keep the expected light (0: every shadow ray; fewer rays with many lights)")
      ->check(CLI::Range(0.0f, 1.0f))
      ->capture_default_str();
  app.add_option(
         "--gpu-shadow-memory", s.gpuShadowMiB,
         "Vulkan backend: the most device memory, in MiB, for the shadow rays of one update "
         "(48 bytes per probe ray, light and emissive sample); beyond it shading runs in "
         "rounds, with the same field (0: a quarter of the largest device-local heap, at "
         "most 8 GiB)")
      ->check(CLI::Range(std::size_t(0), std::size_t(1) << 30))
      ->capture_default_str();
  app.add_flag("--no-fallback", s.noFallback,
               "where the GPU tracer fails (device lost, out of memory), keep serving the last "
               "field without updates instead of going on with Embree on the CPU");
  app.add_option("--gpu-fail-submission", s.gpuFailSubmission,
                 "failure drill: the GPU tracer's N-th submission fails as a lost device would "
                 "(0: never)")
      ->check(CLI::Range(0, 1 << 30));
}

void addFieldOptions(CLI::App& app, ServerSetup& s) {
  app.add_option("--rate", s.loop.rate, "field updates per second");
  app.add_option("--rays", s.rays, "rays per probe per update (without --probes)")
      ->check(CLI::Range(pc::kMinRaysPerProbe, pc::kMaxRaysPerProbe));
  app.add_option("--warmup", s.warmup, "warm-up updates without --probes")
      ->check(CLI::Range(0, 100000000));
  app.add_option("--budget", s.loop.scheduler.budget, "most probes per update (0: all due)");
  app.add_flag("--no-rest{false}", s.loop.rest.enabled,
               "update every probe every tick, also in a still scene (by default a probe that "
               "stopped changing rests: updated every --rest-period ticks)");
  app.add_option("--rest-period", s.loop.rest.period, "ticks between updates of a resting probe")
      ->check(CLI::Range(1, 100000));
  app.add_flag("--follow-viewers", s.followViewers,
               "every cascade follows the viewers: it moves by whole spacings to keep them near "
               "its middle, re-tracing only the probes that scroll in (a volume's \"follow\" in "
               "the sidecar does it per cascade); clients need protocol version 9");
  app.add_option("--time", s.loop.startTime, "animation time of the first update")
      ->check(pc::kFinite);
  app.add_option("--freeze-at", s.loop.freezeAt,
                 "animation time where the clock and the field stop (the field is then exact)");
  app.add_option("--dump-field", s.dumpField,
                 "at the freeze, write the exact field here (.probes)");
}

// What the options imply beyond their values (logging, the token, the stream's tuning), after
// checks CLI11 cannot make; false (with the error logged) where they do not hold.
bool applyOptions(ServerSetup& s) {
  if (!pc::applyServeOptions(s)) return false;
  s.net.sceneName = !s.sceneName.empty() ? s.sceneName : sceneNameOf(s.scenePath);
  if (s.loop.rate <= 0 || s.loop.rate > 240) {
    pc::logError("--rate: expected 0 < rate <= 240");
    return false;
  }
  s.loop.dumpField = s.dumpField;
  return true;
}

// The parsed and checked command line, or the process's exit code (--help: 0; bad input: 1).
std::optional<int> parseOptions(int argc, char** argv, ServerSetup& s) {
  CLI::App app{"probecast server: traces the probe field and streams it to clients"};
  addTracerOptions(app, s);
  addFieldOptions(app, s);
  addStreamOptions(app, s);
  addReportOptions(app, s);
  addLimitOptions(app, s);
  pc::addNatsOptions(app, s.nats, s.bucket.name);
  app.add_option("--nats-replicas", s.bucket.replicas,
                 "copies of the bucket across a JetStream cluster's nodes, where it is created")
      ->check(CLI::Range(1, 5));
  app.add_flag("--nats-memory", s.bucket.memoryStorage,
               "keep the bucket in the NATS servers' memory, not on disk, where it is created");
  if (auto code = pc::parseCommandLine(app, argc, argv)) return *code;
  if (!applyOptions(s)) return 1;
  return std::nullopt;
}

// The tracer the options ask for; where it runs on a GPU, the loop's fallback (Embree) takes
// over the updates if the GPU fails (FieldLoopOptions::fallback).
pc::Result<std::unique_ptr<pc::Tracer>> makeServerTracer(const pc::Scene& scene, ServerSetup& s) {
  pc::VulkanTracerOptions vulkanOptions;
  vulkanOptions.shadowMemoryBudget = s.gpuShadowMiB << 20;
  vulkanOptions.failSubmission = s.gpuFailSubmission;
  auto tracer = pc::makeTracer(scene, s.backend, s.tracerOptions, &vulkanOptions);
  if (!tracer) return pc::Error{"tracer: " + tracer.error().message};
  pc::logInfo("tracer: " + (*tracer)->name());
  const bool onCpu = (*tracer)->name().rfind("embree", 0) == 0;
  if (!onCpu && !s.noFallback) {
    s.loop.fallback = [&scene, options = s.tracerOptions] {
      return pc::makeEmbreeTracer(scene, options);
    };
  }
  return tracer;
}

// A fresh field, warmed up with a short bake on `tracer`. A signal between the updates stops
// the bake and is left in `interruptedBy`: a large scene's warm-up on the CPU can take
// minutes, and SIGTERM must not wait for it.
pc::Status warmUp(pc::Field& field, pc::Tracer& tracer, const pc::Scene& scene,
                  const ServerSetup& s, const Signals& signals, int& interruptedBy) {
  pc::FieldSettings settings;
  settings.raysPerProbe = s.rays;
  field = pc::Field::create(pc::sceneVolumes(scene), settings);
  field.sceneHash = scene.hash;
  pc::BakeOptions bake;
  bake.updates = s.warmup;
  const double began = pc::steadySeconds();
  double logged = began;
  bake.progress = [&](int done, int total) {
    if ((interruptedBy = signals.pending()) != 0) return false;
    const double now = pc::steadySeconds();
    if (now - logged >= 5.0 && done < total) {  // a slow warm-up says how far it is
      char line[128];
      std::snprintf(line, sizeof line, "warm-up: %d of %d updates, %.1f s", done, total,
                    now - began);
      pc::logInfo(line);
      logged = now;
    }
    return true;
  };
  pc::logInfo("warm-up: " + std::to_string(s.warmup) + " updates of " +
              std::to_string(field.desc.probeCount) + " probes on " + tracer.name());
  if (pc::Status moved = tracer.setState(pc::evaluateScene(scene, s.loop.startTime)); !moved)
    return moved;
  auto baked = pc::bakeField(field, tracer, bake);
  if (!baked) return baked.error();
  return pc::Status::success();
}

// The field the server starts from: the baked file of --probes, or a warm-up bake, which
// starts over on the fallback tracer (then `tracer`) where the first one fails: no client is
// there yet. The process's exit code where it should stop instead (a signal: 0).
std::optional<int> startingField(pc::Field& field, std::unique_ptr<pc::Tracer>& tracer,
                                 const pc::Scene& scene, ServerSetup& s, const Signals& signals) {
  if (!s.probes.empty()) {
    auto baked = pc::readBakedField(s.probes, scene.hash);
    if (!baked) return pc::logError(baked.error().message), 1;
    field = std::move(baked).value();
    return std::nullopt;
  }
  int interruptedBy = 0;
  pc::Status warm = warmUp(field, *tracer, scene, s, signals, interruptedBy);
  if (!warm && interruptedBy == 0) {
    pc::logError("warm-up bake failed: " + warm.error().message);
    if (!s.loop.fallback) return 1;
    auto cpu = s.loop.fallback();
    if (!cpu) return pc::logError("fallback tracer: " + cpu.error().message), 1;
    pc::logWarn("the warm-up and the field updates go on with the " + (*cpu)->name() + " tracer");
    tracer = std::move(cpu).value();
    s.loop.fallback = nullptr;
    warm = warmUp(field, *tracer, scene, s, signals, interruptedBy);
    if (!warm && interruptedBy == 0)
      return pc::logError("warm-up bake failed: " + warm.error().message), 1;
  }
  if (interruptedBy != 0) {
    pc::logInfo(std::string("shutting down (") + Signals::name(interruptedBy) +
                ") during the warm-up");
    return 0;
  }
  return std::nullopt;
}

// Main's wait until a signal or --duration, a statistics line every --stats-interval.
void waitForTheEnd(const pc::NetServer& server, const pc::FieldLoop& fieldLoop,
                   const ServerSetup& s, const Signals& signals) {
  const double start = pc::steadySeconds();
  double lastStats = start;
  pc::NetServerStats before = server.stats();
  while (true) {
    if (const int sig = signals.wait(timespec{0, 200'000'000})) {
      pc::logInfo(std::string("shutting down (") + Signals::name(sig) + ")");
      return;
    }
    const double now = pc::steadySeconds();
    if (s.duration > 0 && now - start >= s.duration) {
      pc::logInfo("shutting down (--duration reached)");
      return;
    }
    if (s.statsInterval > 0 && now - lastStats >= s.statsInterval) {
      pc::NetServerStats stats = server.stats();
      logStatistics(stats, before, now - lastStats, fieldLoop.stats());
      before = stats;
      lastStats = now;
    }
  }
}

// Streams `field` to clients while the field thread updates it, until a signal or --duration.
int serve(const pc::Scene& scene, pc::Tracer& tracer, pc::Field& field, const ServerSetup& s,
          const Signals& signals) {
  if (s.followViewers) {
    for (int k = 0; k < field.cascadeCount(); ++k) field.desc.cascades[k].follows = 1;
  }
  pc::FieldHub hub(field, s.publisherOptions);
  // Runtime edits from sessions with editor tokens: the network thread submits them, the
  // field thread traces and publishes the scene with them.
  pc::SceneEditor editor(scene);
  pc::NetServerOptions net = s.net;
  net.edits = [&editor](const pc::SceneEdit& edit) { return editor.submit(edit); };
  pc::FieldLoopOptions loop = s.loop;
  loop.editor = &editor;
  auto server = pc::NetServer::create(hub, net);
  if (!server) return pc::logError(server.error().message), 1;
  // The first publish happens before any client can connect, so every Welcome carries a field.
  (void)hub.publish(field, pc::sceneStateMessage(pc::evaluateScene(scene, s.loop.startTime)),
                    pc::steadySeconds());
  // Relays follow the field through NATS: the exporter puts every brick version into the
  // bucket once, from the first publish on.
  std::unique_ptr<pc::relay::FieldExporter> exporter;
  if (!s.nats.urls.empty()) {
    pc::relay::ExportOptions exportOptions;
    exportOptions.nats = s.nats;
    if (exportOptions.nats.name.empty()) exportOptions.nats.name = "probecast-server";
    exportOptions.bucket = s.bucket;
    exportOptions.sceneName = s.net.sceneName;
    auto created = pc::relay::FieldExporter::create(hub, exportOptions);
    if (!created) return pc::logError("--nats: " + created.error().message), 1;
    exporter = std::move(created).value();
    exporter->start();
    pc::logInfo("field export to NATS " + s.nats.urls + ", bucket " + s.bucket.name);
  }
  (*server)->start();
  pc::logInfo("listening on " + s.net.bindAddress + ":" + std::to_string((*server)->port()) +
              " (TCP), datagrams from UDP port " + std::to_string((*server)->udpPort()));
  pc::announceServing(s.net, (*server)->port(), (*server)->metricsPort(),
                      (*server)->tlsFingerprint());

  pc::FieldLoop fieldLoop(scene, tracer, field, hub, loop);
  (*server)->setExtraMetrics([&fieldLoop, &exporter](pc::MetricsText& m) {
    pc::appendFieldLoopMetrics(m, fieldLoop.stats());
    if (exporter) pc::relay::appendExportMetrics(m, exporter->stats());
  });
  std::atomic<bool> stop{false};
  std::thread fieldThread([&] {
    pthread_setname_np(pthread_self(), "pc-field");
    fieldLoop.run(stop, pc::steadySeconds);
  });
  waitForTheEnd(**server, fieldLoop, s, signals);
  stop = true;
  fieldThread.join();
  if (exporter) exporter->stop();
  (*server)->stop();
  const pc::NetServerStats stats = (*server)->stats();
  std::printf("server: %llu clients served, %llu rejected, %.1f kB sent\n",
              (unsigned long long)stats.accepted, (unsigned long long)stats.rejected,
              double(stats.bytesSent) / 1e3);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  ServerSetup setup;
  if (auto code = parseOptions(argc, argv, setup)) return *code;
  const Signals signals;

  pc::Result<pc::Scene> scene =
      setup.scenePath == "builtin" ? pc::Result<pc::Scene>(pc::builtinScene())
                                   : pc::loadScene(setup.scenePath, setup.sidecar, setup.sceneLoad);
  if (!scene) return pc::logError(scene.error().message), 1;
  pc::logInfo(pc::sidecarReport(*scene));
  for (const std::string& w : scene->warnings) pc::logWarn(w);

  auto tracer = makeServerTracer(*scene, setup);
  if (!tracer) return pc::logError(tracer.error().message), 1;
  if (const int sig = signals.pending()) {
    pc::logInfo(std::string("shutting down (") + Signals::name(sig) + ") before the field exists");
    return 0;
  }
  pc::Field field;
  if (auto code = startingField(field, *tracer, *scene, setup, signals)) return *code;
  pc::logInfo("field: " + std::to_string(field.desc.probeCount) + " probe slots, " +
              std::to_string(field.desc.cascadeCount) + " cascades, version " +
              std::to_string(field.version));
  return serve(*scene, **tracer, field, setup, signals);
}
