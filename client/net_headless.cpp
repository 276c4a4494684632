// Headless frame loop of the network mode. The loop never waits for the network: each frame
// reads the synced clock and whatever the mirror holds (the baked field, then the stream), and
// the renderer uploads the bricks that changed since the last frame.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <thread>

#include "camera.h"
#include "client_series.h"
#include "client_setup.h"
#include "common/image.h"
#include "common/log.h"
#include "net_app.h"
#include "renderer.h"

namespace pc::client {

namespace {

Status writeViews(const ClientConfig& config, const Renderer::Readback& images,
                  const std::string& stem, bool exr) {
  for (std::size_t v = 0; v < images.display.size(); ++v) {
    const char* eye = config.stereo ? (v == 0 ? "_left" : "_right") : "";
    const std::filesystem::path base = std::filesystem::path(config.outDir) / (stem + eye);
    Status png = writePng(base.string() + ".png", images.display[v]);
    if (!png) return png;
    if (exr) {
      Status e = writeExr(base.string() + ".exr", images.linear[v]);
      if (!e) return e;
    }
  }
  return Status::success();
}

Result<std::unique_ptr<Renderer>> makeRenderer(const vk::Context& ctx, const Scene& scene,
                                               FieldMirror& mirror, const ClientConfig& config) {
  RendererOptions ro;
  ro.width = config.width;
  ro.height = config.height;
  ro.views = config.stereo ? 2 : 1;
  ro.msaa = config.msaa;
  ro.rasterizer = config.rasterizer;
  ro.textureMipmaps = config.textureMipmaps;
  ro.shadows = config.shadows;
  ro.sampleFlags = config.sampleFlags;
  ro.aoRadius = config.aoRadius;
  ro.foveaRadius = config.foveaRadius;
  return Renderer::create(ctx, scene, mirror, ro);
}

}  // namespace

int runNetHeadless(const ClientConfig& config, const NetRunConfig& run) {
  auto scene = loadClientScene(config);
  if (!scene) return logError(scene.error().message), 1;
  auto camera = clientCamera(*scene, config);
  if (!camera) return logError(camera.error().message), 1;
  FieldMirror mirror;
  // A fallback that cannot be read is bad input, as without --connect: exit 1, nothing drawn.
  if (!config.probes.empty() && !loadFallbackField(*scene, config, mirror)) return 1;  // logged

  NetClient client(mirror, run.net);
  client.setViewer(camera->position, glm::quatLookAt(glm::normalize(camera->forward), camera->up));
  client.start();
  // Start-up only (no frame is waited for): without a baked field the renderer would be made
  // for no layout and rebuilt as soon as the server's arrives; a moment's wait saves that.
  const double t0 = secondsNow();
  while (!mirror.present() && secondsNow() - t0 < run.startupWait)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));

  auto ctx = createClientContext(config, {});
  if (!ctx) return logError(ctx.error().message), 2;
  logInfo("Vulkan device: " + (*ctx)->deviceName());
  std::uint64_t generation = client.layoutGeneration();
  auto renderer = makeRenderer(**ctx, *scene, mirror, config);
  if (!renderer) return logError("renderer: " + renderer.error().message), 1;
  std::error_code ec;
  std::filesystem::create_directories(config.outDir, ec);

  const double start = secondsNow();
  auto series = ClientSeries::create(run.series, start);
  if (!series) return logError("--series: " + series.error().message), 1;
  int frame = 0, framesDisconnected = 0, rebuilds = 0;
  double stalenessSum = 0, stalenessMax = 0;
  int stalenessFrames = 0;
  bool everConnected = false;
  double lastTime = config.startTime;
  auto frameInput = [&](double time) {
    FrameInput input;
    input.probeView = config.probeView;
    input.time = time;
    input.edited = client.editedScene();
    if (config.stereo) {
      input.cameras[0] = offsetCamera(*camera, -0.5f * config.ipd);
      input.cameras[1] = offsetCamera(*camera, 0.5f * config.ipd);
    } else {
      input.cameras[0] = *camera;
    }
    return input;
  };

  auto writeSummary = [&](const NetClientStats& s, double seconds, double lastFrameTime,
                          bool final) {
    if (run.summary.empty()) return;
    const std::uint64_t bytes = s.tcpBytes + s.udpBytes;
    nlohmann::json j;
    j["frames"] = frame;
    j["seconds"] = seconds;
    j["fps"] = frame / std::max(seconds, 1e-9);
    j["stereo"] = config.stereo;
    j["bytes_received"] = bytes;
    j["bytes_per_second"] = bytes / std::max(seconds, 1e-9);
    j["udp_bytes"] = s.udpBytes;
    j["tcp_bytes"] = s.tcpBytes;
    j["udp_datagrams"] = s.udpDatagrams;
    j["tcp_datagrams"] = s.tcpDatagrams;
    j["bad_datagrams"] = s.badDatagrams;
    j["bricks_applied"] = s.bricksApplied;
    j["bricks_held"] = s.bricksHeld;
    j["bricks_total"] = s.bricksTotal;
    j["connected"] = s.connected;
    j["synced"] = s.synced;
    j["sessions"] = s.sessions;
    j["connect_attempts"] = s.connectAttempts;
    j["rejects"] = s.rejects;
    j["server_field_version"] = s.serverFieldVersion;
    j["last_resync_seconds"] = s.lastResyncSeconds;
    j["frames_while_disconnected"] = framesDisconnected;
    j["renderer_rebuilds"] = rebuilds;
    j["staleness_mean_seconds"] = stalenessFrames ? stalenessSum / stalenessFrames : 0.0;
    j["staleness_max_seconds"] = stalenessMax;
    const ClientSeriesTotals t = (*series)->totals();
    j["latency_samples"] = t.latencySamples;
    j["latency_p50_ms"] = t.latencyP50Ms;
    j["latency_p95_ms"] = t.latencyP95Ms;
    j["latency_max_ms"] = t.latencyMaxMs;
    j["version_lag_mean"] = t.versionLagMean;
    j["version_lag_max"] = t.versionLagMax;
    j["frame_ms_mean"] = t.frameMsMean;
    j["frame_ms_p95"] = t.frameMsP95;
    j["frame_ms_max"] = t.frameMsMax;
    j["final"] = final;
    j["last_frame_time"] = lastFrameTime;
    j["last_frame_prefix"] = config.prefix + "_last";
    j["receiver"] = {{"applied", s.receiver.applied},
                     {"applied_residual", s.receiver.appliedResidual},
                     {"stale", s.receiver.stale},
                     {"missing_base", s.receiver.missingBase},
                     {"rejected_datagrams", s.receiver.rejectedDatagrams},
                     {"decode_errors", s.receiver.decodeErrors},
                     {"repair_bricks", s.receiver.repairBricks},
                     {"gap_reports", s.receiver.gapReports}};
    // Written beside and renamed into place: a reader polling the file never sees half of it.
    const std::string tmp = run.summary + ".tmp";
    {
      std::ofstream out(tmp);
      out << j.dump(2) << "\n";
      if (!out) return logError("cannot write " + tmp);
    }
    std::error_code renameError;
    std::filesystem::rename(tmp, run.summary, renameError);
  };
  double lastSummaryAt = secondsNow();
  for (;; ++frame) {
    const double now = secondsNow();
    if (run.duration > 0 ? now - start >= run.duration : frame >= std::max(1, config.frames)) break;
    if (client.layoutGeneration() != generation) {
      // The server's layout differs from the one the renderer was made for (rare: only when no
      // or another scene's baked field was given): rebuild it around the mirror.
      generation = client.layoutGeneration();
      (*renderer).reset();
      renderer = makeRenderer(**ctx, *scene, mirror, config);
      if (!renderer) return logError("renderer: " + renderer.error().message), 1;
      ++rebuilds;
    }
    // The server's clock when synced (direct light then matches its indirect light), else the
    // local one.
    lastTime = client.animationTime().value_or(config.startTime + (now - start));
    auto images = (*renderer)->renderOffscreen(frameInput(lastTime));
    if (!images)
      return logError("frame " + std::to_string(frame) + ": " + images.error().message), 1;

    const NetClientStats s = client.stats();
    everConnected = everConnected || s.connected;
    if (everConnected && !s.connected) ++framesDisconnected;
    const FieldAge age = mirror.age(secondsNow());
    if (s.connected && age.present) {
      stalenessSum += age.newestSeconds;
      stalenessMax = std::max(stalenessMax, age.newestSeconds);
      ++stalenessFrames;
    }
    if (Status row = (*series)->frame(secondsNow(), s, age, client.takeLatencySamples()); !row)
      return logError("--series: " + row.error().message), 1;
    if (now - lastSummaryAt >= 0.25) {
      // A live summary: tests and scripts watch the client's progress through it.
      lastSummaryAt = now;
      writeSummary(s, now - start, lastTime, false);
    }
    if (run.saveEvery > 0 && frame % run.saveEvery == 0) {
      char stem[64];
      std::snprintf(stem, sizeof stem, "%s_%04d", config.prefix.c_str(), frame);
      Status w = writeViews(config, *images, stem, false);
      if (!w) logError(w.error().message);
    }
    if (run.maxFps > 0) {
      const double next = now + 1.0 / run.maxFps;
      while (secondsNow() < next) std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
  }
  const double seconds = secondsNow() - start;

  // The last frame, at the clock's time now, for comparisons against the server's field.
  // Pending bricks go up in a few frames' budgets first, so it shows all the mirror holds.
  int flushes = 0;
  while (mirror.age(secondsNow()).pendingBricks > 0 && flushes++ < 64) {
    auto flush = (*renderer)->renderOffscreen(frameInput(lastTime));
    if (!flush) return logError("last frame: " + flush.error().message), 1;
  }
  const double lastFrameTime = client.animationTime().value_or(lastTime);
  auto last = (*renderer)->renderOffscreen(frameInput(lastFrameTime));
  if (!last) return logError("last frame: " + last.error().message), 1;
  Status w = writeViews(config, *last, config.prefix + "_last", config.writeExr);
  if (!w) logError(w.error().message);

  const NetClientStats s = client.stats();
  client.stop();
  (*renderer).reset();

  const std::uint64_t bytes = s.tcpBytes + s.udpBytes;
  char line[256];
  std::snprintf(
      line, sizeof line,
      "%d frames in %.1f s (%.1f fps), %.1f kB/s received, %llu sessions, server field v%llu, "
      "%d of %d bricks held, resync %.3f s",
      frame, seconds, frame / std::max(seconds, 1e-9), bytes / std::max(seconds, 1e-9) / 1e3,
      (unsigned long long)s.sessions, (unsigned long long)s.serverFieldVersion, s.bricksHeld,
      s.bricksTotal, s.lastResyncSeconds);
  logInfo(line);

  writeSummary(s, seconds, lastFrameTime, true);
  if ((*ctx)->validationErrorCount() > 0) {
    logError("validation errors: " + std::to_string((*ctx)->validationErrorCount()));
    return 3;
  }
  // Rendered, but never let in: a wrong token or a full server is the user's to fix, and a
  // script must not read the run as a success.
  if (s.sessions == 0 && s.rejects > 0) {
    logError("the server rejected all " + std::to_string(s.rejects) +
             " connection attempts: " + s.lastError);
    return 4;
  }
  return 0;
}

}  // namespace pc::client
