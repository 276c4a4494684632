// edits: runtime edits seen by every viewer. An in-process server (Embree, the field thread and
// the network thread as probecast-server runs them, TLS on loopback), N viewer clients and one
// editor, each a NetClient with its own session; the editor moves and recolours a light M times.
//   edit_to_photon: from the editor's send to the moment the last of the N viewers' sessions
//     took the scene state that includes the edit (NetClient::takeEditArrivals), per edit.
//   edit_settle_s: from the send until one viewer's field around the edit (irradiance sampled
//     at points near the light, six normals each) stays within 40 dB PSNR of where it settles
//     (its value just before the next edit).
#include <algorithm>
#include <atomic>
#include <cmath>
#include <memory>
#include <random>
#include <thread>

#include "bench.h"
#include "client/field_mirror.h"
#include "client/net_client.h"
#include "loopback_server.h"

namespace pc::bench {

namespace {

struct EditsSetup {
  std::string scene = "builtin", sidecar;
  int clients = 10, edits = 20;
  double interval = 2.0;  // s between edits: the field settles in between
  double rate = 15;       // field updates per second
  int rays = 64, bakeUpdates = 16, budget = 0;
  double settleDb = 40.0;
};

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const double rank = p * double(v.size() - 1);
  const std::size_t lo = std::size_t(std::floor(rank)), hi = std::size_t(std::ceil(rank));
  return v[lo] + (v[hi] - v[lo]) * (rank - double(lo));
}

// Irradiance of `field` at points around `center`: a 4x4x4 grid 0.8 units across, clamped
// inside the scene's bounds, each seen along the six axes.
std::vector<glm::vec3> sampleAround(const Field& field, const Scene& scene, glm::vec3 center) {
  std::vector<glm::vec3> out;
  const glm::vec3 lo = scene.boundsMin + 0.05f, hi = scene.boundsMax - 0.05f;
  const glm::vec3 axes[6] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  for (int x = 0; x < 4; ++x)
    for (int y = 0; y < 4; ++y)
      for (int z = 0; z < 4; ++z) {
        const glm::vec3 p = glm::clamp(center + (glm::vec3(x, y, z) / 3.0f - 0.5f) * 0.8f, lo, hi);
        for (const glm::vec3& n : axes) out.push_back(glm::vec3(sampleField(field, p, n, n, 0)));
      }
  return out;
}

// PSNR of `a` against `reference`, the peak being the reference's brightest channel.
double psnr(const std::vector<glm::vec3>& a, const std::vector<glm::vec3>& reference) {
  double peak = 0, sum = 0;
  for (const glm::vec3& r : reference) peak = std::max<double>(peak, std::max({r.x, r.y, r.z}));
  for (std::size_t i = 0; i < a.size() && i < reference.size(); ++i) {
    const glm::vec3 d = a[i] - reference[i];
    sum += double(glm::dot(d, d)) / 3.0;
  }
  const double mse = sum / double(std::max<std::size_t>(1, reference.size()));
  if (mse <= 0) return 200.0;
  return 10.0 * std::log10(peak * peak / mse);
}

int runEdits(const EditsSetup& o) {
  auto loaded = loadBenchScene(o.scene, o.sidecar);
  if (!loaded) return std::fprintf(stderr, "edits: %s\n", loaded.error().message.c_str()), 1;
  const Scene scene = std::move(loaded).value();
  LoopbackServerOptions serverOptions;
  serverOptions.rays = o.rays;
  serverOptions.bakeUpdates = o.bakeUpdates;
  serverOptions.clients = o.clients;
  serverOptions.loop.rate = o.rate;
  serverOptions.loop.scheduler.budget = o.budget;
  auto started = LoopbackServer::start(scene, serverOptions);
  if (!started) return std::fprintf(stderr, "edits: %s\n", started.error().message.c_str()), 1;
  LoopbackServer& server = **started;
  const auto clientOptions = [&](const std::string& name, TokenRole role) {
    return server.clientOptions(name, role);
  };
  std::vector<std::unique_ptr<client::FieldMirror>> mirrors;
  std::vector<std::unique_ptr<client::NetClient>> viewers;
  for (int i = 0; i < o.clients; ++i) {
    mirrors.push_back(std::make_unique<client::FieldMirror>());
    viewers.push_back(std::make_unique<client::NetClient>(
        *mirrors.back(), clientOptions("viewer-" + std::to_string(i), TokenRole::Viewer)));
    viewers.back()->start();
  }
  client::FieldMirror editorMirror;
  client::NetClient editorClient(editorMirror, clientOptions("editor", TokenRole::Editor));
  editorClient.start();
  const auto sleep = [](double s) {
    std::this_thread::sleep_for(std::chrono::duration<double>(s));
  };
  const double joinStart = client::netClockSeconds();
  const auto allSynced = [&] {
    if (!editorClient.stats().connected) return false;
    for (const auto& v : viewers)
      if (!v->stats().synced) return false;
    return true;
  };
  while (!allSynced() && client::netClockSeconds() - joinStart < 60) sleep(0.05);
  const bool synced = allSynced();
  std::printf("edits: %d viewers and an editor %s after %.1f s\n", o.clients,
              synced ? "synced" : "NOT all synced", client::netClockSeconds() - joinStart);

  // The light moved: the scene's first, else one the first edit adds.
  std::uint32_t light = 0;
  std::mt19937 random(7);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  const glm::vec3 lo = scene.boundsMin, span = scene.boundsMax - scene.boundsMin;
  std::vector<double> photon, settle;
  int refused = 0, unsettled = 0;
  std::uint32_t id = 0;
  for (int e = 0; e < o.edits; ++e) {
    SceneEdit edit;
    edit.op = scene.lights.empty() && e == 0 ? EditOp::AddLight : EditOp::SetLight;
    edit.target = light;
    edit.fields = kEditPosition | kEditIntensity | kEditColor;
    edit.position = lo + span * glm::vec3(0.2f + 0.6f * unit(random), 0.55f + 0.3f * unit(random),
                                          0.2f + 0.6f * unit(random));
    edit.intensity = 1.5f + 3.0f * unit(random);
    edit.color = glm::vec3(0.6f + 0.4f * unit(random), 0.6f + 0.4f * unit(random), 1.0f);
    for (const auto& v : viewers) (void)v->takeEditArrivals();
    const double sent = client::netClockSeconds();
    editorClient.sendEdit(EditMsg{++id, edit});
    std::optional<EditResultMsg> result;
    std::vector<double> arrived(viewers.size(), -1.0);
    std::vector<std::vector<glm::vec3>> samples;
    std::vector<double> sampleTimes;
    while (client::netClockSeconds() - sent < o.interval) {
      for (EditResultMsg& r : editorClient.takeEditResults())
        if (r.editId == id) result = std::move(r);
      if (result && result->accepted) {
        for (std::size_t i = 0; i < viewers.size(); ++i) {
          for (const client::EditArrival& a : viewers[i]->takeEditArrivals())
            if (a.editVersion >= result->editVersion && arrived[i] < 0) arrived[i] = a.at - sent;
        }
      }
      mirrors[0]->read(
          [&](const Field& f) { samples.push_back(sampleAround(f, scene, edit.position)); });
      sampleTimes.push_back(client::netClockSeconds() - sent);
      sleep(0.05);
    }
    if (!result || !result->accepted) {
      ++refused;
      std::printf("  edit %d: %s\n", e, result ? result->reason.c_str() : "no answer");
      continue;
    }
    if (edit.op == EditOp::AddLight) light = result->target;
    const double slowest = *std::max_element(arrived.begin(), arrived.end());
    const bool everyone =
        std::none_of(arrived.begin(), arrived.end(), [](double a) { return a < 0; });
    if (everyone) photon.push_back(slowest * 1e3);
    // Settled: from the last sample below the threshold on, every sample is within it.
    double settledAt = 0;
    for (std::size_t k = 0; k + 1 < samples.size(); ++k) {
      if (psnr(samples[k], samples.back()) < o.settleDb) settledAt = sampleTimes[k + 1];
    }
    if (settledAt >= sampleTimes.back() - 0.2) ++unsettled;
    settle.push_back(settledAt);
    std::printf(
        "  edit %2d: every viewer %s %.1f ms after the send; field around it settled "
        "(%.0f dB) after %.2f s\n",
        e, everyone ? "applied it" : "NOT all applied", slowest * 1e3, o.settleDb, settledAt);
  }

  server.stop();
  for (auto& v : viewers) v->stop();
  editorClient.stop();
  const NetServerStats stats = server.server().stats();
  std::printf(
      "edits: %s; %d viewers, %d edits every %.1f s, field at %.0f updates/s, %d rays "
      "per probe; %llu applied, %d refused, %d not settled within the interval\n",
      machineDescription().c_str(), o.clients, o.edits, o.interval, o.rate, o.rays,
      static_cast<unsigned long long>(stats.editsApplied), refused, unsettled);
  figure("edit_to_photon_p50_ms", percentile(photon, 0.5), "ms");
  figure("edit_to_photon_p99_ms", percentile(photon, 0.99), "ms");
  figure("edit_settle_s", percentile(settle, 0.5), "s");
  figure("edit_settle_p90_s", percentile(settle, 0.9), "s");
  return synced && refused == 0 && int(photon.size()) == o.edits ? 0 : 1;
}

}  // namespace

Benchmark addEdits(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "edits", "runtime edits: edit to every viewer's applied state, and the field's settling");
  static EditsSetup o;
  cmd->add_option("--scene", o.scene, "glTF/OBJ scene, or 'builtin'");
  cmd->add_option("--sidecar", o.sidecar, "scene.json sidecar");
  addSceneLoadOptions(*cmd, sceneLoadOptions());
  cmd->add_option("--clients", o.clients, "viewer clients, each with its own session")
      ->check(CLI::Range(1, 200));
  cmd->add_option("--edits", o.edits, "edits the editor sends")->check(CLI::Range(1, 10000));
  cmd->add_option("--interval", o.interval, "seconds between edits (the field settles)")
      ->check(CLI::Range(0.2, 60.0));
  cmd->add_option("--rate", o.rate, "field updates per second")->check(CLI::Range(1.0, 240.0));
  cmd->add_option("--rays", o.rays, "rays per probe per update")->check(CLI::Range(8, 4096));
  cmd->add_option("--bake-updates", o.bakeUpdates, "updates of the field before serving")
      ->check(CLI::Range(1, 1000));
  cmd->add_option("--budget", o.budget, "most probes per update (0: every due probe)")
      ->check(CLI::Range(0, 1 << 24));
  cmd->add_option("--settle-db", o.settleDb, "PSNR within which the field counts as settled");
  return {cmd, [] { return runEdits(o); }};
}

}  // namespace pc::bench
