// probecast-server: updates a scene's probe field on the animation clock and streams it to
// clients (TCP session, UDP brick datagrams). Two threads besides main: the field thread
// (trace, blend, publish) and the network thread; main waits for SIGINT/SIGTERM (or
// --duration) and prints statistics.
#include <pthread.h>
#include <signal.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <string>
#include <thread>

#include "common/log.h"
#include "protocol/baked_file.h"
#include "protocol/stream_tuning.h"
#include "server/bake.h"
#include "server/net_field_loop.h"
#include "server/net_server.h"
#include "server/vulkan_tracer.h"
#include "tools/command_line.h"

namespace {

std::string statsLine(const pc::NetServerStats& now, const pc::NetServerStats& before,
                      double seconds, const pc::FieldLoopStats& field) {
  char line[256];
  const double rate = seconds > 0 ? double(now.bytesSent - before.bytesSent) / seconds : 0.0;
  std::snprintf(line, sizeof line,
                "clients %zu | sent %.1f kB/s | field v%llu, t=%.2f s, update %.1f ms, %d bricks "
                "changed | accepted %llu, rejected %llu",
                now.clients.size(), rate / 1e3, (unsigned long long)field.fieldVersion,
                field.animationTime, field.lastUpdateMs, field.lastBricksChanged,
                (unsigned long long)now.accepted, (unsigned long long)now.rejected);
  std::string s = line;
  for (const pc::NetClientInfo& c : now.clients) {
    std::snprintf(line, sizeof line, "\n  session %u %s (%s, %s): %.1f kB sent, %llu datagrams, %zu bricks pending",
                  c.sessionId, c.name.c_str(), c.peer.c_str(), c.udp ? "udp" : "tcp",
                  double(c.bytesSent) / 1e3, (unsigned long long)c.datagrams, c.pendingBricks);
    s += line;
  }
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"probecast server: traces the probe field and streams it to clients"};
  std::string scenePath = "builtin", sidecar, probes, backend = "auto", dumpField;
  pc::NetServerOptions net;
  pc::FieldLoopOptions loop;
  int rays = 256, warmup = 32;
  double duration = 0, statsInterval = 2.0, rateLimit = 0;
  app.add_option("--scene", scenePath, "glTF/OBJ scene, or 'builtin'");
  app.add_option("--sidecar", sidecar, "scene.json sidecar");
  app.add_option("--probes", probes, "start from this baked field (else a short warm-up bake)");
  app.add_option("--backend", backend, "tracer: auto, embree or vulkan");
  pc::TracerOptions tracerOptions;
  app.add_option(
         "--shadow-roulette", tracerOptions.shadowRouletteShare,
         "share of a hit's punctual light below which a light's shadow ray is drawn at random, "
         "weighted to keep the expected light (0: every shadow ray; fewer rays with many lights)")
      ->check(CLI::Range(0.0f, 1.0f))
      ->capture_default_str();
  std::size_t gpuShadowMiB = 0;
  app.add_option(
         "--gpu-shadow-memory", gpuShadowMiB,
         "Vulkan backend: the most device memory, in MiB, for the shadow rays of one update "
         "(48 bytes per probe ray, light and emissive sample); beyond it shading runs in "
         "rounds, with the same field (0: a quarter of the largest device-local heap, at "
         "most 8 GiB)")
      ->check(CLI::Range(std::size_t(0), std::size_t(1) << 30))
      ->capture_default_str();
  bool noFallback = false;
  app.add_flag("--no-fallback", noFallback,
               "where the GPU tracer fails (device lost, out of memory), keep serving the last "
               "field without updates instead of going on with Embree on the CPU");
  int gpuFailSubmission = 0;
  app.add_option("--gpu-fail-submission", gpuFailSubmission,
                 "failure drill: the GPU tracer's N-th submission fails as a lost device would "
                 "(0: never)")
      ->check(CLI::Range(0, 1 << 30));
  app.add_option("--rate", loop.rate, "field updates per second");
  app.add_option("--rays", rays, "rays per probe per update (without --probes)")
      ->check(CLI::Range(pc::kMinRaysPerProbe, pc::kMaxRaysPerProbe));
  app.add_option("--warmup", warmup, "warm-up updates without --probes")
      ->check(CLI::Range(0, 100000000));
  app.add_option("--budget", loop.scheduler.budget, "most probes per update (0: all due)");
  app.add_option("--time", loop.startTime, "animation time of the first update")
      ->check(pc::kFinite);
  app.add_option("--freeze-at", loop.freezeAt,
                 "animation time where the clock and the field stop (the field is then exact)");
  app.add_option("--dump-field", dumpField, "at the freeze, write the exact field here (.probes)");
  app.add_option("--bind", net.bindAddress, "address to listen on");
  app.add_option("--port", net.port, "TCP port (0: any free one)");
  app.add_option("--token", net.token, "shared secret clients must present (else $PROBECAST_TOKEN)");
  app.add_flag("--tcp-only", net.tcpOnly, "send datagrams over TCP to every client");
  app.add_option("--rate-limit", rateLimit, "bytes per second per client (0: default)");
  pc::StreamTuning tuning;
  app.add_option("--stream-threshold", tuning.threshold,
                 "perceptual threshold T of the stream: changes of the gamma-encoded irradiance "
                 "below T are held back (0: every version exactly; docs/BENCHMARKS.md has the "
                 "bandwidth and PSNR for each T)")
      ->check(CLI::Range(0.0, 0.5));
  app.add_option("--duration", duration, "exit after this many seconds (0: run until a signal)");
  app.add_option("--stats-interval", statsInterval, "seconds between statistics lines");
  int metricsPort = 0;
  std::string logFormat = "text", logLevel = "info";
  app.add_option("--metrics-port", metricsPort,
                 "serve Prometheus metrics at http://BIND:PORT/metrics (0: off)")
      ->check(CLI::Range(0, 65535));
  app.add_option("--metrics-bind", net.metricsBindAddress,
                 "address the metrics endpoint listens on (default: --bind's)");
  app.add_option("--log-format", logFormat, "log lines: text, or json (one object per line)");
  app.add_option("--log-level", logLevel, "least severe level logged: debug, info, warn, error");
  app.add_option("--max-clients", net.maxClients, "clients past the handshake; more get a Reject");
  app.add_option("--max-pending", net.maxPendingConnections,
                 "connections awaiting their Hello; more are closed when accepted");
  app.add_option("--max-message-bytes", net.maxMessageBytes,
                 "largest message a client may send (0: derived from the field's brick count)");
  app.add_option("--max-messages-per-second", net.maxMessagesPerSecond,
                 "messages a client may send per second before it is disconnected as a flood");
  app.add_option("--max-write-queue", net.maxWriteQueueBytes,
                 "bytes queued to a client before it counts as not reading");
  if (auto code = pc::parseCommandLine(app, argc, argv)) return *code;
  const auto format = pc::parseLogFormat(logFormat);
  const auto level = pc::parseLogLevel(logLevel);
  if (!format) return pc::logError("--log-format: expected text or json, got '" + logFormat + "'"), 1;
  if (!level) {
    return pc::logError("--log-level: expected debug, info, warn or error, got '" + logLevel + "'"), 1;
  }
  pc::setLogFormat(*format);
  pc::setLogLevel(*level);
  if (metricsPort != 0) net.metricsPort = std::uint16_t(metricsPort);

  if (net.token.empty()) {
    if (const char* env = std::getenv("PROBECAST_TOKEN")) net.token = env;
  }
  if (net.token.empty()) {
    pc::logError("no auth token: pass --token or set PROBECAST_TOKEN");
    return 1;
  }
  if (loop.rate <= 0 || loop.rate > 240) return pc::logError("--rate: expected 0 < rate <= 240"), 1;
  if (rateLimit > 0) net.sender.bytesPerSecond = rateLimit;
  pc::PublisherOptions publisherOptions;
  pc::applyStreamTuning(tuning, publisherOptions, net.sender);
  loop.dumpField = dumpField;

  // Signals go to the thread that waits for them (main), never to the worker threads: block
  // them before any thread starts, and let sigtimedwait take them.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  pc::Result<pc::Scene> scene = scenePath == "builtin" ? pc::Result<pc::Scene>(pc::builtinScene())
                                                       : pc::loadScene(scenePath, sidecar);
  if (!scene) return pc::logError(scene.error().message), 1;
  for (const std::string& w : scene->warnings) pc::logWarn(w);

  pc::VulkanTracerOptions vulkanOptions;
  vulkanOptions.shadowMemoryBudget = gpuShadowMiB << 20;
  vulkanOptions.failSubmission = gpuFailSubmission;
  auto tracer = pc::makeTracer(*scene, backend, tracerOptions, &vulkanOptions);
  if (!tracer) return pc::logError("tracer: " + tracer.error().message), 1;
  pc::logInfo("tracer: " + (*tracer)->name());
  // A GPU that fails hands the updates to Embree (FieldLoopOptions::fallback).
  const bool onCpu = (*tracer)->name().rfind("embree", 0) == 0;
  if (!onCpu && !noFallback)
    loop.fallback = [&scene, tracerOptions] { return pc::makeEmbreeTracer(*scene, tracerOptions); };

  // Before the main loop, a signal found between warm-up updates ends the process: a large
  // scene's warm-up on the CPU can take minutes, and SIGTERM must not wait for it.
  int interruptedBy = 0;
  auto pendingSignal = [&signals] {
    timespec now{0, 0};
    const int sig = sigtimedwait(&signals, nullptr, &now);
    return sig == SIGINT || sig == SIGTERM ? sig : 0;
  };
  auto signalName = [](int sig) { return sig == SIGINT ? "SIGINT" : "SIGTERM"; };
  if (const int sig = pendingSignal()) {
    pc::logInfo(std::string("shutting down (") + signalName(sig) + ") before the field exists");
    return 0;
  }

  pc::Field field;
  if (!probes.empty()) {
    auto baked = pc::readBakedField(probes, scene->hash);
    if (!baked) return pc::logError(baked.error().message), 1;
    field = std::move(baked).value();
  } else {
    // A fresh field, warmed up with a short bake; stopped by a signal (interruptedBy).
    auto warmUp = [&](pc::Tracer& t) -> pc::Status {
      pc::FieldSettings settings;
      settings.raysPerProbe = rays;
      field = pc::Field::create(
          scene->volumes.empty() ? pc::defaultVolumes(*scene) : scene->volumes, settings);
      field.sceneHash = scene->hash;
      pc::BakeOptions bake;
      bake.updates = warmup;
      const double began = pc::steadySeconds();
      double logged = began;
      bake.progress = [&](int done, int total) {
        if ((interruptedBy = pendingSignal()) != 0) return false;
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
      pc::logInfo("warm-up: " + std::to_string(warmup) + " updates of " +
                  std::to_string(field.desc.probeCount) + " probes on " + t.name());
      if (pc::Status s = t.setState(pc::evaluateScene(*scene, loop.startTime)); !s) return s;
      auto baked = pc::bakeField(field, t, bake);
      if (!baked) return baked.error();
      return pc::Status::success();
    };
    pc::Status warm = warmUp(**tracer);
    if (!warm && interruptedBy == 0) {
      // No client yet: the warm-up starts over on the fallback, from a fresh field.
      pc::logError("warm-up bake failed: " + warm.error().message);
      if (!loop.fallback) return 1;
      auto cpu = loop.fallback();
      if (!cpu) return pc::logError("fallback tracer: " + cpu.error().message), 1;
      pc::logWarn("the warm-up and the field updates go on with the " + (*cpu)->name() +
                  " tracer");
      tracer = std::move(cpu);
      loop.fallback = nullptr;
      warm = warmUp(**tracer);
      if (!warm && interruptedBy == 0)
        return pc::logError("warm-up bake failed: " + warm.error().message), 1;
    }
    if (interruptedBy != 0) {
      pc::logInfo(std::string("shutting down (") + signalName(interruptedBy) +
                  ") during the warm-up");
      return 0;
    }
  }
  pc::logInfo("field: " + std::to_string(field.desc.probeCount) + " probe slots, " +
              std::to_string(field.desc.cascadeCount) + " cascades, version " +
              std::to_string(field.version));

  pc::FieldHub hub(field, publisherOptions);
  auto server = pc::NetServer::create(hub, net);
  if (!server) return pc::logError(server.error().message), 1;
  // The first publish happens before any client can connect, so every Welcome carries a field.
  (void)hub.publish(field, pc::sceneStateMessage(pc::evaluateScene(*scene, loop.startTime)),
                    pc::steadySeconds());
  (*server)->start();
  pc::logInfo("listening on " + net.bindAddress + ":" + std::to_string((*server)->port()) +
              " (TCP), datagrams from UDP port " + std::to_string((*server)->udpPort()));
  if ((*server)->metricsPort() != 0) {
    pc::logInfo("metrics at http://" +
                (net.metricsBindAddress.empty() ? net.bindAddress : net.metricsBindAddress) + ":" +
                std::to_string((*server)->metricsPort()) + "/metrics");
  }
  // A line a script can wait for before starting clients.
  std::printf("ready port %u\n", unsigned((*server)->port()));
  std::fflush(stdout);

  pc::FieldLoop fieldLoop(*scene, **tracer, field, hub, loop);
  (*server)->setExtraMetrics(
      [&fieldLoop](pc::MetricsText& m) { pc::appendFieldLoopMetrics(m, fieldLoop.stats()); });
  std::atomic<bool> stop{false};
  std::thread fieldThread([&] {
    pthread_setname_np(pthread_self(), "pc-field");
    fieldLoop.run(stop, pc::steadySeconds);
  });

  const double start = pc::steadySeconds();
  double lastStats = start;
  pc::NetServerStats before = (*server)->stats();
  while (true) {
    timespec wait{0, 200'000'000};
    const int sig = sigtimedwait(&signals, nullptr, &wait);
    if (sig == SIGINT || sig == SIGTERM) {
      pc::logInfo(std::string("shutting down (") + signalName(sig) + ")");
      break;
    }
    const double now = pc::steadySeconds();
    if (duration > 0 && now - start >= duration) {
      pc::logInfo("shutting down (--duration reached)");
      break;
    }
    if (statsInterval > 0 && now - lastStats >= statsInterval) {
      pc::NetServerStats s = (*server)->stats();
      pc::logInfo(statsLine(s, before, now - lastStats, fieldLoop.stats()));
      before = s;
      lastStats = now;
    }
  }
  stop = true;
  fieldThread.join();
  (*server)->stop();
  const pc::NetServerStats s = (*server)->stats();
  std::printf("server: %llu clients served, %llu rejected, %.1f kB sent\n",
              (unsigned long long)s.accepted, (unsigned long long)s.rejected,
              double(s.bytesSent) / 1e3);
  return 0;
}
