// stream: what the streaming protocol costs on the wire for one client, and what the client
// sees. The server traces the scene's probe field with Embree while its lights move (the
// scene's animation), at --rate updates per simulated second, and publishes every update; one
// StreamSender + StreamReceiver pair per threshold streams it over an in-memory link. All the
// pairs see the same field updates, so the rows of the table differ only in the threshold.
//
// Per threshold T (change of gamma-encoded irradiance e), the rules the server streams with
// (applyStreamTuning, protocol/stream_tuning.h): the publisher's dead zone holds codes that
// moved by <= T (depth by <= --depth-tolerance of its mean, occlusion by <= 0.02, offsets by
// <= 5% of the spacing, active <-> sleeping flips), and the sender holds back brick versions
// whose mean irradiance change over the brick is below T (and no texel moved by 8 T) until the
// change accumulates or the refresh interval ends. The client joins at the start (an empty
// mirror); the bandwidth is measured after it holds every brick once, over --seconds of simulated
// time: every datagram's bytes plus the session messages going back (acks, repair requests),
// each with its IPv4 + UDP (28) or IPv4 + TCP (40) header bytes. At the end the CPU probe-lit
// image of camera 0 is rendered from the client's mirror and from the server's exact field
// (same camera, time, samples and direct light; only the field differs) and compared.
#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "bench.h"
#include "bench_common.h"
#include "cpu/path_tracer.h"
#include "cpu/probe_lit_render.h"
#include "protocol/baked_file.h"
#include "protocol/brick_codec.h"
#include "protocol/datagram.h"
#include "protocol/fault_link.h"
#include "protocol/field_publisher.h"
#include "protocol/stream_receiver.h"
#include "protocol/stream_sender.h"
#include "protocol/stream_tuning.h"
#include "server/bake.h"
#include "server/probe_scheduler.h"
#include "server/tracer.h"

namespace pc::bench {

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

constexpr double kUdpIpHeaderBytes = 28;    // IPv4 (20) + UDP (8)
constexpr double kTcpIpHeaderBytes = 40;    // IPv4 (20) + TCP (20), one segment per message
constexpr double kRawBytesPerProbe = 1288;  // RTXGI's atlas formats, borders included

struct StreamSetup {
  std::string scene = std::string(PC_SCENES_DIR) + "/sauer-pandora/pandora.obj";
  std::string sidecar;
  double seconds = 3.0;    // measured, after the join
  double joinLimit = 8.0;  // simulated seconds the initial transfer may take
  double rate = 30.0;      // field updates per simulated second
  int rays = 64;
  int budget = 4000;  // probes traced per update (the scheduler's budget); 0: all
  int bakeUpdates = 32;
  std::vector<double> thresholds = {0.004, 0.002, 0.008, 0.016};
  float depthTolerance = StreamTuning{}.depthTolerance;
  float occlusionTolerance = StreamTuning{}.occlusionTolerance;
  double loss = 0;
  double refresh = 2.0;  // s: the sender's refresh interval
  double rateLimit = 0;  // Mbit/s of the sender's token bucket; 0: unconstrained
  int maxQualityLevel = SenderOptions{}.maxQualityLevel;
  int maxPrecision = SenderOptions{}.maxPrecision;
  int width = 320, height = 180;
  int aa = 2;
  bool breakdown = false;
  std::string cacheDir = "build/stream-cache";
  float shadowRoulette = pc::TracerOptions{}.shadowRouletteShare;
  std::string outDir;
};

// One client and everything between it and the publisher, for one threshold.
struct Client {
  double threshold = 0;
  std::unique_ptr<FieldPublisher> publisher;
  std::unique_ptr<StreamSender> sender;
  std::unique_ptr<StreamReceiver> receiver;
  std::unique_ptr<FaultLink> link;
  ReliableLink control;
  double joinedAt = -1;  // simulated time it first held every brick
  // Bytes with header estimates: datagrams (down) and session messages (up).
  double downBytes = 0, upBytes = 0, datagrams = 0, messages = 0;
  double measuredDown = 0, measuredUp = 0;
  SenderStats senderAtStart;
  // The sender's held-field measures every 0.25 s of the measured window, and its level then.
  std::vector<double> heldPsnrs, heldAges, levels;
  // With --breakdown, over the measured window: payload bytes by section (each section coded
  // alone, the others equal to the base or zero) and codes changed against the base.
  std::array<double, 4> sectionBytes{}, sectionChanged{};
  double payloadBytes = 0, sampledUpdates = 0;
};

// Sections of a brick's codes, for --breakdown.
constexpr std::array<const char*, 4> kSectionNames = {"irradiance", "depth", "occlusion",
                                                      "records"};
constexpr std::array<std::size_t, 5> kSectionStarts = {
    brick_layout::kIrradiance, brick_layout::kDepth, brick_layout::kOcclusion,
    brick_layout::kOffset, brick_layout::kCodes};

// What each section of the updates in `datagram` costs: every update whose first fragment is
// here is re-encoded once per section with only that section's codes as sent.
void addBreakdown(Client& c, const std::vector<std::uint8_t>& datagram) {
  auto d = decodeDatagram(datagram);
  if (!d) return;
  for (const Fragment& f : d->fragments) {
    if (f.index != 0) continue;
    const UpdateHeader& h = f.update;
    auto q = c.publisher->find(h.cascade, int(h.brick), h.version);
    auto base = h.baseVersion ? c.publisher->find(h.cascade, int(h.brick), h.baseVersion) : nullptr;
    if (!q || (h.baseVersion && !base)) continue;
    c.payloadBytes += h.totalSize;
    c.sampledUpdates += 1;
    for (std::size_t s = 0; s < 4; ++s) {
      QuantizedBrick only;
      only.codes = base ? base->codes : std::vector<std::uint16_t>(brick_layout::kCodes, 0);
      for (std::size_t i = kSectionStarts[s]; i < kSectionStarts[s + 1]; ++i) {
        only.codes[i] = q->codes[i];
        c.sectionChanged[s] += base && base->codes[i] != q->codes[i];
      }
      c.sectionBytes[s] += double(encodeBrick(only, base.get()).size());
    }
  }
}

// The p-th quantile of `v` (0 when empty).
double quantile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, std::size_t(p * double(v.size())))];
}

bool holdsEveryBrick(const Field& server, const StreamReceiver& r) {
  for (int k = 0; k < server.cascadeCount(); ++k)
    for (std::size_t b = 0; b < server.brickVersions[k].size(); ++b)
      if (r.brickVersion(k, int(b)) == 0) return false;
  return true;
}

// The converged starting field, cached on disk: baking 15k probes takes minutes on few cores.
Result<Field> startingField(const Scene& scene, Tracer& tracer, const StreamSetup& s) {
  char name[128];
  std::snprintf(name, sizeof name, "%016llx-%drays-%dupdates.probes",
                (unsigned long long)scene.hash, s.rays, s.bakeUpdates);
  const fs::path cached = s.cacheDir.empty() ? fs::path() : fs::path(s.cacheDir) / name;
  if (!cached.empty() && fs::exists(cached)) {
    if (auto f = readBakedField(cached, scene.hash)) return f;
  }
  FieldSettings settings;
  settings.raysPerProbe = s.rays;
  Field field =
      Field::create(scene.volumes.empty() ? defaultVolumes(scene) : scene.volumes, settings);
  field.sceneHash = scene.hash;
  if (Status st = tracer.setState(evaluateScene(scene, 0.0)); !st) return st.error();
  BakeOptions bake;
  bake.updates = s.bakeUpdates;
  Progress progress("bake " + sceneSlug(scene), std::uint64_t(bake.updates));
  bake.progress = [&](int, int) {
    progress.advance();
    return true;
  };
  if (auto baked = bakeField(field, tracer, bake); !baked) return baked.error();
  if (!cached.empty()) {
    std::error_code ec;
    fs::create_directories(cached.parent_path(), ec);
    if (Status w = writeBakedField(cached, field); !w)
      std::fprintf(stderr, "stream: not cached: %s\n", w.error().message.c_str());
  }
  return field;
}

}  // namespace

Benchmark addStream(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "stream", "bandwidth per client and client-vs-server image PSNR on an animated scene");
  static StreamSetup s;
  cmd->add_option("--scene", s.scene, "scene file, or 'builtin'");
  cmd->add_option("--sidecar", s.sidecar, "scene.json sidecar");
  addSceneLoadOptions(*cmd, sceneLoadOptions());
  cmd->add_option("--seconds", s.seconds, "simulated seconds measured after the client joined");
  cmd->add_option("--join-limit", s.joinLimit, "simulated seconds allowed for the join");
  cmd->add_option("--rate", s.rate, "field updates per simulated second");
  cmd->add_option("--rays", s.rays, "rays per probe per update");
  cmd->add_option("--shadow-roulette", s.shadowRoulette,
                  "share of a hit's punctual light below which shadow rays are drawn at random (0: "
                  "all traced)")
      ->capture_default_str();
  cmd->add_option("--budget", s.budget, "probes traced per update (0: every probe)");
  cmd->add_option("--bake-updates", s.bakeUpdates, "updates of the starting field's bake");
  cmd->add_option(
      "--threshold", s.thresholds,
      "irradiance thresholds (mean |delta e| over a brick), one client each; the first gives the "
      "FIGURE lines");
  cmd->add_option("--depth-tolerance", s.depthTolerance,
                  "dead zone of depth, as a fraction of the texel's mean distance");
  cmd->add_option("--occlusion-tolerance", s.occlusionTolerance, "dead zone of occlusion");
  cmd->add_option("--loss", s.loss, "datagram loss rate of the link (0: lossless)");
  cmd->add_option("--refresh", s.refresh,
                  "seconds after which a brick with any newer version is sent anyway");
  cmd->add_option("--rate-limit", s.rateLimit,
                  "sender rate limit in Mbit/s (0: unconstrained, so the table shows demand)");
  cmd->add_option("--max-quality-level", s.maxQualityLevel,
                  "highest level of the sender's quality ladder (0: full quality always)")
      ->capture_default_str();
  cmd->add_option("--max-precision", s.maxPrecision,
                  "coarsest precision level the ladder sends (0: the codec's own)")
      ->capture_default_str();
  cmd->add_option("--width", s.width, "probe-lit image width");
  cmd->add_option("--height", s.height, "probe-lit image height");
  cmd->add_option("--aa", s.aa, "primary samples per pixel of the probe-lit images");
  cmd->add_flag("--breakdown", s.breakdown,
                "print what the sent updates cost by section and why they were sent (slower)");
  cmd->add_option("--cache", s.cacheDir, "folder for the baked starting field ('' to disable)");
  cmd->add_option("--out", s.outDir, "write the images here");
  return {
      cmd, [] {
        auto scene = loadBenchScene(s.scene, s.sidecar);
        if (!scene) {
          std::fprintf(stderr, "stream: %s\n", scene.error().message.c_str());
          return 1;
        }
        TracerOptions options;
        options.shadowRouletteShare = s.shadowRoulette;
        auto tracer = makeEmbreeTracer(*scene, options);
        if (!tracer) {
          std::fprintf(stderr, "stream: %s\n", tracer.error().message.c_str());
          return 1;
        }
        auto start = startingField(*scene, **tracer, s);
        if (!start) {
          std::fprintf(stderr, "stream: %s\n", start.error().message.c_str());
          return 1;
        }
        Field server = std::move(start).value();
        int bricks = 0;
        for (int k = 0; k < server.cascadeCount(); ++k)
          bricks += gpu::pcBrickCount(server.cascade(k));
        const int probes = server.probeCount();
        bool animated = false;
        for (const Light& l : scene->lights) animated |= l.animation >= 0;

        std::vector<Client> clients(s.thresholds.size());
        for (std::size_t i = 0; i < clients.size(); ++i) {
          Client& c = clients[i];
          c.threshold = s.thresholds[i];
          PublisherOptions po;
          SenderOptions so;
          StreamTuning tuning;
          tuning.threshold = float(c.threshold);
          tuning.depthTolerance = s.depthTolerance;
          tuning.occlusionTolerance = s.occlusionTolerance;
          applyStreamTuning(tuning, po, so);
          c.publisher = std::make_unique<FieldPublisher>(server, po);
          (void)c.publisher->publish(server, 0.0);
          so.refreshInterval = s.refresh;
          so.maxQualityLevel = s.maxQualityLevel;
          so.maxPrecision = s.maxPrecision;
          so.bytesPerSecond = s.rateLimit > 0 ? s.rateLimit * 1e6 / 8.0 : 1e12;
          so.burstBytes = s.rateLimit > 0 ? so.burstBytes : 1e12;
          const std::uint32_t session = 0x57e4'0000u + std::uint32_t(i);
          c.sender = std::make_unique<StreamSender>(*c.publisher, session, so);
          auto info = decodeMessage(encodeMessage(c.publisher->sessionInfo()));
          auto r = StreamReceiver::create(std::get<SessionInfoMsg>(info.value()), session);
          if (!r) {
            std::fprintf(stderr, "stream: %s\n", r.error().message.c_str());
            return 1;
          }
          c.receiver = std::make_unique<StreamReceiver>(std::move(r.value()));
          c.link = std::make_unique<FaultLink>(1000 + i);
          FaultProfile profile;
          profile.delay = 0.01;
          profile.loss = s.loss;
          c.link->setProfile(profile);
          c.control.setDelay(0.01);
          if (!scene->cameras.empty()) {
            ViewerPoseMsg pose;
            pose.position = scene->cameras[0].position;
            c.control.send(encodeMessage(pose), 0.0);
          }
        }

        // Simulated time: network events every 5 ms, field updates at the rate.
        const double step = 0.005, tick = 1.0 / s.rate;
        ProbeScheduler scheduler(SchedulerOptions{8, 16, s.budget});
        std::vector<glm::vec3> viewers;
        if (!scene->cameras.empty()) viewers.push_back(scene->cameras[0].position);
        double nextTick = 0.0, traceSeconds = 0.0, measureStart = -1, end = -1, nextSample = -1;
        std::uint64_t ticks = 0, probeUpdates = 0, brickChanges = 0;
        std::uint32_t rotation = 9000;
        std::printf("stream: %s, %d probes in %d bricks, %d rays, %.0f updates/s, %s\n",
                    sceneSlug(*scene).c_str(), probes, bricks, s.rays, s.rate,
                    s.budget > 0 ? (std::to_string(s.budget) + " probes per update").c_str()
                                 : "every probe every update");
        std::fflush(stdout);
        for (long i = 0;; ++i) {
          const double t = double(i) * step;
          if (end >= 0 && t > end) break;
          if (t >= nextTick) {
            nextTick += tick;
            const auto t0 = Clock::now();
            if (Status st = (*tracer)->setState(evaluateScene(*scene, t)); !st) {
              std::fprintf(stderr, "stream: %s\n", st.error().message.c_str());
              return 1;
            }
            UpdateRequest req;
            req.rotationSeed = rotation++;
            req.probes = scheduler.plan(server, ticks + 1, viewers);
            auto updated = (*tracer)->update(server, req);
            if (!updated) {
              std::fprintf(stderr, "stream: %s\n", updated.error().message.c_str());
              return 1;
            }
            const UpdateStats& us = *updated;
            traceSeconds += std::chrono::duration<double>(Clock::now() - t0).count();
            probeUpdates += std::uint64_t(us.probesUpdated);
            brickChanges += std::uint64_t(us.bricksChanged);
            ++ticks;
            for (Client& c : clients) {
              (void)c.publisher->publish(server, t);
              // The SceneState a server sends with every update: the receiver's version bound.
              if (c.receiver) c.receiver->announceFieldVersion(server.version);
            }
          }
          bool allJoined = true;
          for (Client& c : clients) {
            for (auto& d : c.sender->poll(t)) {
              const double bytes = double(d.size()) + kUdpIpHeaderBytes;
              c.downBytes += bytes;
              c.datagrams += 1;
              if (measureStart >= 0) c.measuredDown += bytes;
              if (measureStart >= 0 && s.breakdown) addBreakdown(c, d);
              c.link->send(std::move(d), t);
            }
            for (auto& d : c.link->receive(t)) (void)c.receiver->onDatagram(d, t);
            for (auto& m : c.receiver->poll(t)) {
              const double bytes = double(m.size()) + kTcpIpHeaderBytes;
              c.upBytes += bytes;
              c.messages += 1;
              if (measureStart >= 0) c.measuredUp += bytes;
              c.control.send(std::move(m), t);
            }
            for (auto& m : c.control.receive(t)) (void)c.sender->onMessage(m, t);
            if (c.joinedAt < 0 && holdsEveryBrick(server, *c.receiver)) c.joinedAt = t;
            allJoined &= c.joinedAt >= 0;
          }
          // Measure once every client holds the whole field (or the join limit passed).
          if (measureStart < 0 && (allJoined || t >= s.joinLimit)) {
            measureStart = t;
            end = t + s.seconds;
            nextSample = t;
            for (Client& c : clients) c.senderAtStart = c.sender->stats();
          }
          if (nextSample >= 0 && t >= nextSample) {
            nextSample += 0.25;
            for (Client& c : clients) {
              const HeldFieldReport held = c.sender->heldField(t);
              c.heldPsnrs.push_back(held.psnrDb);
              c.heldAges.push_back(held.oldestChangeSeconds);
              c.levels.push_back(c.sender->qualityLevel());
            }
          }
        }
        const double measured = end - measureStart;

        // Images: the same camera, animation time and samples; only the field differs.
        auto camera = sceneCamera(*scene, 0);
        if (!camera) {
          std::fprintf(stderr, "stream: %s\n", camera.error().message.c_str());
          return 1;
        }
        ProbeLitOptions lit;
        lit.width = s.width;
        lit.height = s.height;
        lit.primarySamples = s.aa;
        lit.explicitCamera = *camera;
        lit.time = end;
        auto exact = renderProbeLit(*scene, server, lit);
        if (!exact) {
          std::fprintf(stderr, "stream: %s\n", exact.error().message.c_str());
          return 1;
        }
        const Image8 exact8 = tonemap(*exact, scene->exposure);
        if (!s.outDir.empty()) {
          fs::create_directories(s.outDir);
          writePng(fs::path(s.outDir) / "server_field.png", exact8);
        }

        const double raw = kRawBytesPerProbe * double(probes) * s.rate * 8.0 / 1e6;
        std::printf("machine: %s\n", machineDescription().c_str());
        std::printf(
            "simulated: %.2f s in all (%llu field updates, %.1f s of tracing), join then "
            "%.2f s measured; light animation: %s; link loss %.0f%%; rate limit %s\n",
            end, (unsigned long long)ticks, traceSeconds, measured,
            animated ? "yes" : "none (static lights)", s.loss * 100,
            s.rateLimit > 0 ? (std::to_string(s.rateLimit) + " Mbit/s").c_str() : "none");
        std::printf(
            "probe updates per second %.0f (%.1f per probe), brick versions per update "
            "%.1f of %d\n",
            double(probeUpdates) / end, double(probeUpdates) / end / probes,
            double(brickChanges) / double(std::max<std::uint64_t>(ticks, 1)), bricks);
        std::printf("raw baseline: %d probes x 1288 B x %.0f/s = %.1f Mbit/s\n\n", probes, s.rate,
                    raw);
        std::printf("%9s %8s %9s %10s %9s %8s %8s %9s %9s %8s %9s\n", "threshold", "join_s",
                    "join_MB", "Mbit/s", "down", "up", "ratio", "updates/s", "residual", "held%",
                    "PSNR_dB");
        double figMbit = 0, figRatio = 0, figPsnr = 0;
        for (std::size_t i = 0; i < clients.size(); ++i) {
          Client& c = clients[i];
          auto image = renderProbeLit(*scene, c.receiver->field(), lit);
          if (!image) {
            std::fprintf(stderr, "stream: %s\n", image.error().message.c_str());
            return 1;
          }
          const Image8 client8 = tonemap(*image, scene->exposure);
          const double psnr = psnr8(client8, exact8);
          if (!s.outDir.empty()) {
            char name[64];
            std::snprintf(name, sizeof name, "client_t%.4f.png", c.threshold);
            writePng(fs::path(s.outDir) / name, client8);
          }
          const double down = c.measuredDown * 8.0 / measured / 1e6;
          const double up = c.measuredUp * 8.0 / measured / 1e6;
          const double mbit = down + up;
          const SenderStats& st = c.sender->stats();
          const double updates = double(st.updates - c.senderAtStart.updates);
          const double residual = double(st.residualUpdates - c.senderAtStart.residualUpdates);
          const double held = 100.0 * double(c.publisher->heldCodes()) /
                              double(std::max<std::uint64_t>(c.publisher->quantizedCodes(), 1));
          const double joinMb = (c.downBytes + c.upBytes - c.measuredDown - c.measuredUp) / 1e6;
          std::printf("%9.4f %8.2f %9.2f %10.3f %9.3f %8.3f %8.0f %9.1f %8.0f%% %7.1f%% %9.2f%s\n",
                      c.threshold, c.joinedAt, joinMb, mbit, down, up, raw / mbit,
                      updates / measured, updates > 0 ? 100.0 * residual / updates : 0.0, held,
                      psnr, c.joinedAt < 0 ? "  (did not join)" : "");
          if (i == 0) {
            figMbit = mbit;
            figRatio = raw / mbit;
            figPsnr = psnr;
          }
        }
        std::printf(
            "\nheld field (the sender's measure every 0.25 s of the window, against the current "
            "field):\n%9s %9s %9s %9s %9s %9s %9s\n",
            "threshold", "psnr_p5", "psnr_p50", "age_p95_s", "age_max_s", "level", "coarse%");
        for (const Client& c : clients) {
          double level = 0;
          for (double l : c.levels) level += l / double(std::max<std::size_t>(c.levels.size(), 1));
          const SenderStats& st = c.sender->stats();
          const double updates = double(st.updates - c.senderAtStart.updates);
          const double coarse = double(st.coarseUpdates - c.senderAtStart.coarseUpdates);
          std::printf("%9.4f %9.2f %9.2f %9.2f %9.2f %9.2f %8.0f%%\n", c.threshold,
                      quantile(c.heldPsnrs, 0.05), quantile(c.heldPsnrs, 0.5),
                      quantile(c.heldAges, 0.95), quantile(c.heldAges, 1.0), level,
                      updates > 0 ? 100.0 * coarse / updates : 0.0);
        }
        if (s.breakdown) {
          std::printf("\nwhy updates were sent (measured window, per second):\n");
          std::printf("%9s %7s %7s %7s %7s %7s %7s %7s %7s %7s %7s %7s %7s %7s\n", "threshold",
                      "first", "irr_max", "irr_mean", "depth", "occl", "offset", "state", "settled",
                      "refresh", "repair", "timeout", "aged", "refine");
          for (const Client& c : clients) {
            const auto& a = c.sender->stats().reasons;
            const auto& b = c.senderAtStart.reasons;
            auto rate = [&](std::uint64_t x, std::uint64_t y) { return double(x - y) / measured; };
            std::printf(
                "%9.4f %7.1f %7.1f %7.1f %7.1f %7.1f %7.1f %7.1f %7.1f %7.1f %7.1f %7.1f %7.1f "
                "%7.1f\n",
                c.threshold, rate(a.first, b.first), rate(a.irradiance, b.irradiance),
                rate(a.irradianceMean, b.irradianceMean), rate(a.depth, b.depth),
                rate(a.occlusion, b.occlusion), rate(a.offset, b.offset), rate(a.state, b.state),
                rate(a.settled, b.settled), rate(a.refresh, b.refresh), rate(a.repair, b.repair),
                rate(a.timeout, b.timeout), rate(c.sender->stats().aged, c.senderAtStart.aged),
                rate(a.refine, b.refine));
          }
          std::printf(
              "\nbytes per update by section (each coded alone) and codes changed "
              "against the base:\n");
          for (const Client& c : clients) {
            const double n = std::max(c.sampledUpdates, 1.0);
            std::printf("%9.4f payload %.0f B:", c.threshold, c.payloadBytes / n);
            for (std::size_t k = 0; k < 4; ++k)
              std::printf("  %s %.0f B (%.0f changed)", kSectionNames[k], c.sectionBytes[k] / n,
                          c.sectionChanged[k] / n);
            std::printf("\n");
          }
        }
        std::printf(
            "\nMbit/s: measured window, datagrams + acks with IP/UDP/TCP headers; down/up "
            "split; ratio: raw baseline / Mbit/s; held%%: codes the dead zone kept\n");
        figure("mbit_per_client", figMbit, "Mbit/s");
        figure("raw_ratio", figRatio, "x");
        figure("psnr_client_vs_server_field", figPsnr, "dB");
        figure("held_psnr_db_p5", quantile(clients.front().heldPsnrs, 0.05), "dB");
        figure("oldest_change_s_p95", quantile(clients.front().heldAges, 0.95), "s");
        return 0;
      }};
}

}  // namespace pc::bench
