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
#include "protocol/brick_precision.h"
#include "protocol/stream_tuning.h"
#include "server/bake.h"
#include "server/net_field_loop.h"
#include "server/net_server.h"
#include "server/vulkan_tracer.h"
#include "tools/command_line.h"

namespace {

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

// A bearer token from a file: its first line, without surrounding white space.
pc::Result<std::string> readTokenFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) return pc::Error{"cannot read " + path};
  std::string token;
  std::getline(in, token);
  const auto space = [](unsigned char c) { return std::isspace(c) != 0; };
  while (!token.empty() && space(token.back())) token.pop_back();
  const auto first = std::find_if_not(token.begin(), token.end(), space);
  token.erase(token.begin(), first);
  if (token.empty()) return pc::Error{path + " holds no token"};
  return token;
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

struct ServerSetup {
  std::string scenePath = "builtin", sidecar, probes, backend = "auto", dumpField;
  pc::SceneLoadOptions sceneLoad;
  pc::NetServerOptions net;
  pc::FieldLoopOptions loop;
  pc::TracerOptions tracerOptions;
  pc::StreamTuning tuning;
  pc::PublisherOptions publisherOptions;  // from `tuning`
  std::size_t gpuShadowMiB = 0;
  bool noFallback = false;
  int gpuFailSubmission = 0;
  int rays = 256, warmup = 32;
  double duration = 0, statsInterval = 2.0, rateLimit = 0;
  int metricsPort = 0;
  std::vector<std::string> tokenKeyFiles;
  std::string sceneName;
  std::string metricsTokenFile;
  std::string logFormat = "text", logLevel = "info";
};

void addTracerOptions(CLI::App& app, ServerSetup& s) {
  app.add_option("--scene", s.scenePath, "glTF/OBJ scene, or 'builtin'");
  app.add_option("--sidecar", s.sidecar, "scene.json sidecar");
  pc::addSceneLoadOptions(app, s.sceneLoad);
  app.add_option("--probes", s.probes, "start from this baked field (else a short warm-up bake)");
  app.add_option("--backend", s.backend, "tracer: auto, embree or vulkan");
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
  app.add_option("--time", s.loop.startTime, "animation time of the first update")
      ->check(pc::kFinite);
  app.add_option("--freeze-at", s.loop.freezeAt,
                 "animation time where the clock and the field stop (the field is then exact)");
  app.add_option("--dump-field", s.dumpField,
                 "at the freeze, write the exact field here (.probes)");
}

void addStreamOptions(CLI::App& app, ServerSetup& s) {
  app.add_option("--bind", s.net.bindAddress, "address to listen on");
  app.add_option("--port", s.net.port, "TCP port (0: any free one)");
  app.add_option("--token-key", s.tokenKeyFiles,
                 "verify key file of a connect token issuer (probecast-token keygen); "
                 "repeat it while keys rotate (else $PROBECAST_TOKEN_KEY_FILE)");
  app.add_option("--revoked", s.net.revocationFile,
                 "revocation list: token ids refused (read again when it changes)");
  app.add_option("--scene-name", s.sceneName,
                 "the scene name connect tokens must name (default: 'builtin', or the scene "
                 "file's folder name when the file is called scene.*, else its stem)");
  app.add_flag("--tcp-only", s.net.tcpOnly, "send datagrams over TCP to every client");
  app.add_option("--tls-cert", s.net.tls.certificateFile,
                 "TLS certificate chain (PEM) of the session port");
  app.add_option("--tls-key", s.net.tls.keyFile, "its private key (PEM)");
  app.add_flag("--dev-self-signed", s.net.tls.devSelfSigned,
               "make a self-signed certificate at start (development, tests); its fingerprint "
               "is printed for clients to pin");
  app.add_option("--dev-cert-out", s.net.tls.devCertificateOut,
                 "write the --dev-self-signed certificate here (PEM), for clients' --ca-file");
  app.add_flag("--no-tls{false}", s.net.tls.enabled,
               "plain TCP and unsealed datagrams (measuring TLS's cost, a trusted loopback); "
               "clients must say --no-tls too");
  app.add_option("--rate-limit", s.rateLimit, "bytes per second per client (0: default)");
  app.add_option("--stream-threshold", s.tuning.threshold,
                 "perceptual threshold T of the stream: changes of the gamma-encoded irradiance "
                 "below T are held back (0: every version exactly; docs/BENCHMARKS.md has the "
                 "bandwidth and PSNR for each T)")
      ->check(CLI::Range(0.0, 0.5));
  app.add_option("--max-precision", s.net.sender.maxPrecision,
                 "coarsest precision level a short link is sent (0: the codec's own always; "
                 "PROTOCOL.md, Precision levels)")
      ->check(CLI::Range(0, pc::kMaxPrecision));
}

// How long the process runs and what it reports.
void addReportOptions(CLI::App& app, ServerSetup& s) {
  app.add_option("--duration", s.duration, "exit after this many seconds (0: run until a signal)");
  app.add_option("--stats-interval", s.statsInterval, "seconds between statistics lines");
  app.add_option("--metrics-port", s.metricsPort,
                 "serve Prometheus metrics at http://BIND:PORT/metrics (0: off)")
      ->check(CLI::Range(0, 65535));
  app.add_option("--metrics-bind", s.net.metricsBindAddress,
                 "address the metrics endpoint listens on (default: 127.0.0.1)");
  app.add_option("--metrics-token-file", s.metricsTokenFile,
                 "file holding a bearer token every scrape must present (else 401)");
  app.add_option("--log-format", s.logFormat, "log lines: text, or json (one object per line)");
  app.add_option("--log-level", s.logLevel, "least severe level logged: debug, info, warn, error");
}

// What clients may do before they are turned away.
void addLimitOptions(CLI::App& app, ServerSetup& s) {
  pc::NetServerOptions& net = s.net;
  app.add_option("--max-clients", net.maxClients, "clients past the handshake; more get a Reject");
  app.add_option("--max-pending", net.maxPendingConnections,
                 "connections awaiting their Hello; more are closed when accepted");
  app.add_option("--max-message-bytes", net.maxMessageBytes,
                 "largest message a client may send (0: derived from the field's brick count)");
  app.add_option("--max-messages-per-second", net.maxMessagesPerSecond,
                 "messages a client may send per second before it is disconnected as a flood");
  app.add_option("--max-write-queue", net.maxWriteQueueBytes,
                 "bytes queued to a client before it counts as not reading");
  app.add_option("--max-pending-per-address", net.maxPendingPerAddress,
                 "connections awaiting their Hello from one address (IPv6: /64) (0: no cap)");
  app.add_option("--max-sessions-per-address", net.maxSessionsPerAddress,
                 "sessions from one address (IPv6: /64) (0: no cap)");
  app.add_option("--handshakes-per-second-per-address", net.handshakesPerSecondPerAddress,
                 "connections one address may open per second, burst of two seconds' worth "
                 "(0: no cap)");
  app.add_option("--max-sessions-per-client", net.maxSessionsPerClient,
                 "sessions one client name may hold; more get a Reject (0: no cap)");
}

// What the options imply beyond their values (logging, the token, the stream's tuning), after
// checks CLI11 cannot make; false (with the error logged) where they do not hold.
bool applyOptions(ServerSetup& s) {
  const auto format = pc::parseLogFormat(s.logFormat);
  const auto level = pc::parseLogLevel(s.logLevel);
  if (!format) {
    pc::logError("--log-format: expected text or json, got '" + s.logFormat + "'");
    return false;
  }
  if (!level) {
    pc::logError("--log-level: expected debug, info, warn or error, got '" + s.logLevel + "'");
    return false;
  }
  pc::setLogFormat(*format);
  pc::setLogLevel(*level);
  if (s.metricsPort != 0) s.net.metricsPort = std::uint16_t(s.metricsPort);
  if (!s.metricsTokenFile.empty()) {
    auto token = readTokenFile(s.metricsTokenFile);
    if (!token) {
      pc::logError("--metrics-token-file: " + token.error().message);
      return false;
    }
    s.net.metricsToken = std::move(token).value();
  }

  if (s.tokenKeyFiles.empty()) {
    if (const char* env = std::getenv("PROBECAST_TOKEN_KEY_FILE")) s.tokenKeyFiles.push_back(env);
  }
  if (s.tokenKeyFiles.empty()) {
    pc::logError(
        "no token verify key: pass --token-key FILE or set PROBECAST_TOKEN_KEY_FILE "
        "(probecast-token keygen makes one)");
    return false;
  }
  for (const std::string& file : s.tokenKeyFiles) {
    auto key = pc::loadVerifyKey(file);
    if (!key) {
      pc::logError("--token-key: " + key.error().message);
      return false;
    }
    s.net.tokenKeys.push_back(*key);
  }
  s.net.sceneName = !s.sceneName.empty() ? s.sceneName : sceneNameOf(s.scenePath);
  if (s.loop.rate <= 0 || s.loop.rate > 240) {
    pc::logError("--rate: expected 0 < rate <= 240");
    return false;
  }
  if (s.rateLimit > 0) s.net.sender.bytesPerSecond = s.rateLimit;
  pc::applyStreamTuning(s.tuning, s.publisherOptions, s.net.sender);
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
  if (auto code = pc::parseCommandLine(app, argc, argv)) return *code;
  if (!applyOptions(s)) return 1;
  return std::nullopt;
}

// SIGINT and SIGTERM go to the thread that waits for them (main), never to the worker
// threads: blocked before any thread starts (which inherit the mask), taken by sigtimedwait.
class Signals {
 public:
  Signals() {
    sigemptyset(&set_);
    sigaddset(&set_, SIGINT);
    sigaddset(&set_, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &set_, nullptr);
  }
  // The signal that arrived within `wait` (none: 0).
  int wait(timespec wait) const {
    const int sig = sigtimedwait(&set_, nullptr, &wait);
    return sig == SIGINT || sig == SIGTERM ? sig : 0;
  }
  int pending() const { return wait(timespec{0, 0}); }
  static const char* name(int sig) { return sig == SIGINT ? "SIGINT" : "SIGTERM"; }

 private:
  sigset_t set_;
};

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
      for (const std::string& line : statsLines(stats, before, now - lastStats, fieldLoop.stats()))
        pc::logInfo(line);
      before = stats;
      lastStats = now;
    }
  }
}

// Streams `field` to clients while the field thread updates it, until a signal or --duration.
int serve(const pc::Scene& scene, pc::Tracer& tracer, pc::Field& field, const ServerSetup& s,
          const Signals& signals) {
  pc::FieldHub hub(field, s.publisherOptions);
  auto server = pc::NetServer::create(hub, s.net);
  if (!server) return pc::logError(server.error().message), 1;
  // The first publish happens before any client can connect, so every Welcome carries a field.
  (void)hub.publish(field, pc::sceneStateMessage(pc::evaluateScene(scene, s.loop.startTime)),
                    pc::steadySeconds());
  (*server)->start();
  pc::logInfo("listening on " + s.net.bindAddress + ":" + std::to_string((*server)->port()) +
              " (TCP), datagrams from UDP port " + std::to_string((*server)->udpPort()));
  if ((*server)->metricsPort() != 0) {
    const std::string bind =
        s.net.metricsBindAddress.empty() ? "127.0.0.1" : s.net.metricsBindAddress;
    pc::logInfo("metrics at http://" + bind + ":" + std::to_string((*server)->metricsPort()) +
                "/metrics");
  }
  // Lines a script can wait for before starting clients: the certificate to pin, then ready.
  if (!(*server)->tlsFingerprint().empty()) {
    pc::logInfo("TLS certificate " + (*server)->tlsFingerprint());
    std::printf("tls-fingerprint %s\n", (*server)->tlsFingerprint().c_str());
  } else {
    pc::logWarn("TLS is off (--no-tls): sessions and datagrams travel in clear");
  }
  std::printf("ready port %u\n", unsigned((*server)->port()));
  std::fflush(stdout);

  pc::FieldLoop fieldLoop(scene, tracer, field, hub, s.loop);
  (*server)->setExtraMetrics(
      [&fieldLoop](pc::MetricsText& m) { pc::appendFieldLoopMetrics(m, fieldLoop.stats()); });
  std::atomic<bool> stop{false};
  std::thread fieldThread([&] {
    pthread_setname_np(pthread_self(), "pc-field");
    fieldLoop.run(stop, pc::steadySeconds);
  });
  waitForTheEnd(**server, fieldLoop, s, signals);
  stop = true;
  fieldThread.join();
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
