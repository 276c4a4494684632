// faults: the streaming protocol over an in-memory link with loss (with bursts), duplication,
// reordering, corruption and delay, while the server traces the built-in room's field with a
// moving light. After the faults stop the field stops changing; the figure is how long the
// client then takes to hold every brick's current version (simulated seconds, worst case over
// loss rates and seeds). Runs the same simulation as tests/test_protocol_stream.cpp.
#include <algorithm>
#include <cstdio>
#include <optional>
#include <sstream>

#include "bench.h"
#include "protocol/stream_simulation.h"
#include "server/bake.h"
#include "server/tracer.h"

namespace pc::bench {

namespace {

struct FaultsSetup {
  std::string losses = "0,0.1,0.3,0.5";
  int seeds = 3;
  double faultSeconds = 3.0;
  double tickHz = 10.0;
  int probesPerAxis = 8;
  int rays = 64;
};

std::vector<double> parseList(const std::string& s) {
  std::vector<double> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) out.push_back(std::stod(item));
  return out;
}

}  // namespace

Benchmark addFaults(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "faults", "stream convergence after loss, bursts, duplication, reordering, corruption");
  static FaultsSetup s;
  cmd->add_option("--loss", s.losses, "comma-separated loss rates");
  cmd->add_option("--seeds", s.seeds, "runs per loss rate");
  cmd->add_option("--fault-seconds", s.faultSeconds, "simulated seconds of faults");
  cmd->add_option("--tick-hz", s.tickHz, "field updates per simulated second");
  cmd->add_option("--probes-per-axis", s.probesPerAxis,
                  "cascade size of the built-in room's field");
  cmd->add_option("--rays", s.rays, "rays per probe per update");
  return {
      cmd, [] {
        Scene scene = builtinScene();
        FieldSettings settings;
        settings.raysPerProbe = s.rays;
        auto tracer = makeEmbreeTracer(scene);
        if (!tracer) {
          std::fprintf(stderr, "faults: %s\n", tracer.error().message.c_str());
          return 1;
        }
        Field initial = Field::create(defaultVolumes(scene, s.probesPerAxis), settings);
        initial.sceneHash = scene.hash;
        BakeOptions bake;
        bake.updates = 8;
        if (auto baked = bakeField(initial, **tracer, bake); !baked) {
          std::fprintf(stderr, "faults: %s\n", baked.error().message.c_str());
          return 1;
        }
        int bricks = 0;
        for (int k = 0; k < initial.cascadeCount(); ++k)
          bricks += gpu::pcBrickCount(initial.cascade(k));

        std::printf(
            "faults: built-in room, %d probes in %d bricks, %d cascades, %.0f updates/s, "
            "%.1f s of faults then a frozen field; %s\n",
            initial.probeCount(), bricks, initial.cascadeCount(), s.tickHz, s.faultSeconds,
            machineDescription().c_str());
        std::printf(
            "faults also: 2%% burst starts (mean 10 lost), 10%% duplicated, 20%% "
            "reordered by up to 60 ms, 5%% corrupted, 30-50 ms delay\n\n");
        std::printf("%6s %5s %10s %9s %8s %8s %9s %9s %10s %12s\n", "loss", "seed", "converge_s",
                    "datagrams", "updates", "resends", "residual", "lost", "rejected",
                    "bytes/update");
        double worst = 0;
        bool allConverged = true;
        std::uint64_t bytes = 0, updates = 0;
        for (double loss : parseList(s.losses)) {
          for (int seed = 1; seed <= s.seeds; ++seed) {
            Field server = initial;
            std::uint32_t rotation = 5000;
            std::optional<Error> failure;  // the first failed tracer call; the rest are skipped
            auto advance = [&](Field& f, double t) {
              if (failure) return;
              if (Status s = (*tracer)->setState(evaluateScene(scene, t)); !s) {
                failure = s.error();
                return;
              }
              UpdateRequest req;
              req.rotationSeed = rotation++;
              req.probes = allProbes(f);
              req.changeThreshold = 1e-4f;
              if (auto updated = (*tracer)->update(f, req); !updated) failure = updated.error();
            };
            StreamSimulationOptions o;
            o.seed = std::uint64_t(seed) * 1000 + std::uint64_t(loss * 100);
            o.tickInterval = 1.0 / s.tickHz;
            o.faultSeconds = s.faultSeconds;
            o.settleLimitSeconds = 5.0;
            o.viewer = scene.cameras.empty() ? glm::vec3(0.0f) : scene.cameras[0].position;
            o.faults.loss = loss;
            o.faults.burstStart = 0.02;
            o.faults.burstLength = 10;
            o.faults.duplicate = 0.1;
            o.faults.reorder = 0.2;
            o.faults.reorderDelay = 0.06;
            o.faults.corrupt = 0.05;
            o.faults.delay = 0.03;
            o.faults.jitter = 0.02;
            o.calm.delay = 0.01;
            auto r = runStreamSimulation(server, advance, o);
            if (failure) {
              std::fprintf(stderr, "faults: %s\n", failure->message.c_str());
              return 1;
            }
            allConverged &= r.converged;
            const double converge = r.converged ? r.convergeSeconds : o.settleLimitSeconds;
            worst = std::max(worst, converge);
            bytes += r.sender.bytes;
            updates += r.sender.updates;
            std::printf("%5.0f%% %5d %10.3f %9llu %8llu %8llu %9llu %9llu %10llu %12.0f%s\n",
                        loss * 100, seed, converge, (unsigned long long)r.sender.datagrams,
                        (unsigned long long)r.sender.updates, (unsigned long long)r.sender.resends,
                        (unsigned long long)r.sender.residualUpdates,
                        (unsigned long long)r.link.lost,
                        (unsigned long long)r.receiver.rejectedDatagrams,
                        r.sender.updates ? double(r.sender.bytes) / double(r.sender.updates) : 0.0,
                        r.converged ? "" : "  (did not converge)");
          }
        }
        // RTXGI's formats: 1,288 bytes per probe, 64 probe slots per brick.
        const double raw = 1288.0 * 64.0;
        const double perUpdate = updates ? double(bytes) / double(updates) : 0.0;
        std::printf("\nmean datagram bytes per brick update %.0f (raw RTXGI formats %.0f: %.1fx)\n",
                    perUpdate, raw, perUpdate > 0 ? raw / perUpdate : 0.0);
        if (!allConverged) std::printf("some runs did not converge within 5 s\n");
        figure("converge_s", worst, "s");
        return allConverged ? 0 : 2;
      }};
}

}  // namespace pc::bench
