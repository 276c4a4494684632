// load: many clients against one real server. Starts build/bin/probecast-server on the built-in
// scene as a child process (so its CPU time and resident memory come from /proc/<pid>), runs
// the load generator's protocol-only clients in this process (loadgen/), and reports update
// latency from the server's publish to the client's apply, server CPU per client, errors,
// starved clients and the server's memory growth over the window.
//
// With several --clients values (e.g. 10,100,300,1000) it runs each against a fresh server and
// prints the fan-out curve: the server encodes each brick version once for all clients, so
// what each client costs is sending, and cpu_ms_per_client_s should stay flat as N grows.
// cpu_ms_per_client_s = CPU of the server's network threads (all named "pc-net": the one
// that runs the sessions and the ones that poll, seal and send with it, --send-threads; they
// do all the per-client work) during the window / N / window, read from
// /proc/<pid>/task/<tid>/stat; the whole process's figure (process_cpu_ms_per_client_s, minus its
// idle CPU) is printed too but includes the field thread, whose CPU varies with what the shared
// cores give it. The server and the clients share this machine's cores; --field-nice lowers the
// priority of the server's tracing threads (everything but pc-net) so that serving comes first.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "bench.h"
#include "loadgen/server_load.h"
#include "loadgen/server_process.h"
#include "protocol/brick_precision.h"

namespace pc::bench {

namespace {

struct LoadSetup {
  std::vector<int> clients = {100};
  double seconds = 30;
  double warmup = 3;
  double ramp = -1;  // < 0: 5 ms per client, at least 1 s
  int threads = 0;   // 0: a quarter of the machine's cores, at least 1
  bool tcpOnly = false;
  bool tls = true;
  bool tlsCost = false;
  double rateLimitMbit = 1.0;  // per client, the server's token bucket
  double fieldRate = 10;       // server field updates per second
  int rays = 256;              // the server's default
  int serverWarmup = 8;
  int maxPrecision = kMaxPrecision;  // the server's default
  int sendThreads = 0;               // the server's default (half the cores, 1-8)
  double starveSeconds = 2.0;
  std::string server;     // default: probecast-server beside this executable
  std::string serverLog;  // default: load-server.log in the build folder of the server
  std::string rateMix;
  std::string json;
  std::string series;         // default: beside --json
  double sessionSeconds = 0;  // churn
  int fieldNice = 10;
};

std::string suffix(int clients) { return ".clients_" + std::to_string(clients); }

// Where a run's series goes: --series, else beside --json; with several client counts each
// run's file names its count. Empty: no series.
std::string seriesPath(const LoadSetup& s, int clients, bool several) {
  std::filesystem::path path = s.series;
  if (path.empty() && !s.json.empty())
    path = std::filesystem::path(s.json).replace_extension(".series.csv");
  if (path.empty() || !several) return path.string();
  const std::string ext = path.extension().string();
  return path.replace_extension(suffix(clients) + ext).string();
}

}  // namespace

Benchmark addLoad(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "load",
      "many protocol-only clients against a probecast-server process: latency, server "
      "CPU per client, memory");
  static LoadSetup s;
  cmd->add_option("--clients", s.clients,
                  "clients; several values (10,100,1000) give the fan-out curve, each against a "
                  "fresh server")
      ->delimiter(',');
  cmd->add_option("--seconds", s.seconds, "measured window per run, s");
  cmd->add_option("--warmup", s.warmup, "s after every client is synced, before the window");
  cmd->add_option("--ramp", s.ramp, "s over which clients join (default 5 ms per client, >= 1 s)");
  cmd->add_option("--threads", s.threads,
                  "the load generator's network threads (0: a quarter of the cores, at least "
                  "one: a thousand clients' datagrams are more than one thread reads in time, and "
                  "its late arrival times read as queueing delay)")
      ->check(CLI::Range(0, 256));
  cmd->add_flag("--tcp-only", s.tcpOnly, "datagrams over TCP");
  cmd->add_flag("--no-tls{false}", s.tls,
                "plain sessions and unsealed datagrams (to measure what TLS costs)");
  cmd->add_flag("--tls-cost", s.tlsCost,
                "run every client count twice, with TLS and sealed datagrams and without, "
                "and print the ratio of their cpu_ms_per_client_s");
  cmd->add_option("--rate-limit", s.rateLimitMbit, "server send rate per client, Mbit/s");
  cmd->add_option("--field-rate", s.fieldRate, "server field updates per second");
  cmd->add_option("--rays", s.rays, "server rays per probe per update");
  cmd->add_option("--server-warmup", s.serverWarmup, "server warm-up bake updates");
  cmd->add_option("--max-precision", s.maxPrecision,
                  "server's coarsest precision level for short links (0: the codec's own)")
      ->check(CLI::Range(0, kMaxPrecision));
  cmd->add_option("--send-threads", s.sendThreads,
                  "server threads that poll, seal and send datagram sessions (0: its default)")
      ->check(CLI::Range(0, 64));
  cmd->add_option("--starve-seconds", s.starveSeconds, "gap that makes a client starved");
  cmd->add_option("--session-seconds", s.sessionSeconds,
                  "churn: sessions end after about this long");
  cmd->add_option("--field-nice", s.fieldNice,
                  "nice value for the server's threads but its network thread (field thread, "
                  "tracer workers); 0 leaves them")
      ->check(CLI::Range(0, 19));
  cmd->add_option("--server", s.server, "probecast-server executable");
  cmd->add_option("--server-log", s.serverLog, "the server's log");
  cmd->add_option("--json", s.json, "write the last run's loadgen report as JSON here");
  cmd->add_option("--series", s.series,
                  "write each run's per-second series here as CSV (several client counts: "
                  "FILE.clients_N.csv); default with --json: beside it, <json>.series.csv");
  cmd->add_option("--rate-mix", s.rateMix,
                  "emulated client links, MBIT:SHARE,... (e.g. 0.5:0.25,1:0.5,10:0.25)");
  return {
      cmd, [] {
        std::vector<load::ServerLoadResult> runs;
        std::vector<std::pair<int, bool>> plan;
        for (int n : s.clients) {
          if (s.tlsCost) {
            plan.push_back({n, true});
            plan.push_back({n, false});
          } else {
            plan.push_back({n, s.tls});
          }
        }
        for (const auto& [n, tls] : plan) {
          load::ServerLoadOptions o;
          o.serverExecutable =
              s.server.empty() ? load::siblingExecutable("probecast-server") : s.server;
          // Beside the build's bin/ folder by default, wherever the benchmark runs from.
          o.serverLog =
              !s.serverLog.empty()
                  ? s.serverLog
                  : (std::filesystem::path(o.serverExecutable).parent_path().parent_path() /
                     "load-server.log")
                        .string();
          if (!s.rateMix.empty()) {
            auto links = load::parseRateMix(s.rateMix);
            if (!links) {
              std::fprintf(stderr, "load: %s\n", links.error().message.c_str());
              return 2;
            }
            o.load.links = *links;
          }
          o.serverArgs = {"--rate",           std::to_string(s.fieldRate),
                          "--rays",           std::to_string(s.rays),
                          "--warmup",         std::to_string(s.serverWarmup),
                          "--rate-limit",     std::to_string(s.rateLimitMbit * 1e6 / 8),
                          "--max-clients",    std::to_string(n + 16),
                          "--max-precision",  std::to_string(s.maxPrecision),
                          "--send-threads",   std::to_string(s.sendThreads),
                          "--stats-interval", "0"};
          if (s.tcpOnly) o.serverArgs.push_back("--tcp-only");
          o.load.clients = n;
          o.load.threads =
              s.threads > 0 ? s.threads : std::max(1, int(std::thread::hardware_concurrency()) / 4);
          o.load.tcpOnly = s.tcpOnly;
          o.load.tls = tls;
          o.load.rampSeconds = s.ramp >= 0 ? s.ramp : std::max(1.0, 0.005 * n);
          o.load.starveSeconds = s.starveSeconds;
          o.load.sessionSeconds = s.sessionSeconds;
          o.load.seriesPath = seriesPath(s, n, s.clients.size() > 1);
          o.warmupSeconds = s.warmup;
          o.fieldNice = s.fieldNice;
          o.seconds = s.seconds;
          std::printf("load: %d clients, %.0f s window, %s\n", n, s.seconds,
                      tls ? "TLS and sealed datagrams" : "plain (--no-tls)");
          std::fflush(stdout);
          auto r = load::runServerLoad(o, [](const std::string& line) {
            std::printf("  %s\n", line.c_str());
            std::fflush(stdout);
          });
          if (!r) {
            std::fprintf(stderr, "load: %s\n", r.error().message.c_str());
            return 1;
          }
          std::printf("%s", load::reportTable(r->report).c_str());
          if (!r->serverExit.empty()) std::printf("server exit: %s\n", r->serverExit.c_str());
          if (!s.json.empty()) {
            std::ofstream(s.json) << load::reportJson(r->report);
          }
          runs.push_back(std::move(r).value());
        }

        std::printf("\nMachine: %s (server and clients share it)\n", machineDescription().c_str());
        std::printf(
            "Server: built-in scene, %.0f field updates/s asked, %d rays, %.1f Mbit/s "
            "per client, %s, default --stream-threshold; its threads but pc-net at "
            "nice %d\n",
            s.fieldRate, s.rays, s.rateLimitMbit, s.tcpOnly ? "TCP only" : "UDP", s.fieldNice);
        std::printf("%7s %7s %7s %8s %8s %9s %8s %8s %8s %9s %5s %9s %9s %7s %6s %7s %8s\n",
                    "clients", "synced", "join s", "p50 ms", "p99 ms", "stale p95", "kbit/cl",
                    "srv ms/s", "net ms/s", "field ms/s", "upd/s", "net/cl/s", "srv/cl/s",
                    "lg ms/s", "errors", "starved", "RSS grow");
        for (const load::ServerLoadResult& r : runs) {
          const load::LoadReport& l = r.report;
          std::printf(
              "%7d %7s %7.1f %8.1f %8.1f %9.1f %8.1f %8.0f %8.1f %9.0f %5.1f %9.4f %9.3f "
              "%7.0f %6llu %7d %8.2f\n",
              l.clients, r.allSynced ? "yes" : "NO", r.joinSeconds, l.latencyMs.p50,
              l.latencyMs.p99, l.stalenessMs.p95, l.kbitPerClient.mean, r.serverCpuMsPerS,
              r.netCpuMsPerS, r.fieldCpuMsPerS, r.fieldUpdatesPerS, r.cpuMsPerClientS,
              r.processCpuMsPerClientS, r.loadgenCpuMsPerS, (unsigned long long)l.errors,
              l.starvedClients, r.rssEndMb - r.rssWarmMb);
        }
        std::printf(
            "net = the server's network threads (pc-net, /proc/<pid>/task), idle "
            "before any client %.2f ms/s; net/cl/s = cpu_ms_per_client_s = net / "
            "clients; srv = the whole server process (idle %.1f ms/s), "
            "srv/cl/s = (srv - srv idle) / clients; field = the field thread alone "
            "(its tracer's worker threads count in srv only); upd/s = field versions "
            "published per second in the window; lg = the load "
            "generator's own CPU; RSS grow = server resident memory over the window, MB "
            "(after warm-up %.1f MB)\n",
            runs.back().netIdleCpuMsPerS, runs.back().serverIdleCpuMsPerS, runs.back().rssWarmMb);
        // The server's caches beside its RSS, from its /metrics at the window's end.
        std::printf("%7s %9s %9s %9s %9s %9s %9s %9s %9s\n", "clients", "RSS warm", "RSS end",
                    "encode", "(bound)", "history", "(bound)", "current", "compare");
        for (const load::ServerLoadResult& r : runs) {
          std::printf("%7d %9.1f %9.1f %9.2f %9.2f %9.2f %9.2f %9.2f %9.2f\n", r.report.clients,
                      r.rssWarmMb, r.rssEndMb, r.encodeCacheMb, r.encodeCacheBoundMb, r.historyMb,
                      r.historyBoundMb, r.currentBricksMb, r.changeCacheMb);
          if (!r.metricsError.empty()) std::printf("  (%s)\n", r.metricsError.c_str());
        }
        std::printf(
            "MB; encode = encoded updates (probecast_encode_cache_bytes), history = "
            "brick versions kept as residual bases beyond the current ones, current "
            "= the current brick versions, compare = the senders' shared perceptual "
            "comparisons (estimated); (bound) = what the field allows at most\n");

        auto figures = [](const load::ServerLoadResult& r, const std::string& sfx) {
          const load::LoadReport& l = r.report;
          figure("p50_latency_ms" + sfx, l.latencyMs.p50, "ms");
          figure("p99_latency_ms" + sfx, l.latencyMs.p99, "ms");
          figure("cpu_ms_per_client_s" + sfx, r.cpuMsPerClientS, "ms");
          figure("process_cpu_ms_per_client_s" + sfx, r.processCpuMsPerClientS, "ms");
          figure("errors" + sfx, double(l.errors), "count");
          figure("starved_clients" + sfx, double(l.starvedClients), "count");
          figure("held_psnr_db_p5" + sfx, l.all.heldPsnrP5, "dB");
          figure("oldest_change_s_p95" + sfx, l.all.oldestChangeP95, "s");
          for (const load::ClassReport& c : l.classes) {
            char cls[48];
            std::snprintf(cls, sizeof cls, ".link_%gmbit", c.linkMbit);
            figure(std::string("starved_clients") + cls + sfx, double(c.starved), "count");
            figure(std::string("p99_latency_ms") + cls + sfx, c.latencyMs.p99, "ms");
            figure(std::string("held_psnr_db_p5") + cls + sfx, c.heldPsnrP5, "dB");
            figure(std::string("oldest_change_s_p95") + cls + sfx, c.oldestChangeP95, "s");
            figure(std::string("link_drop_share") + cls + sfx, c.linkDropShare, "share");
          }
          figure("rss_growth_mb" + sfx, r.rssEndMb - r.rssWarmMb, "MB");
          figure("encode_cache_mb" + sfx, r.encodeCacheMb, "MB");
          figure("brick_history_mb" + sfx, r.historyMb, "MB");
        };
        if (s.tlsCost) {
          // Pairs: with TLS, then without, for each client count.
          std::printf("\n%7s %14s %14s %7s\n", "clients", "net/cl/s TLS", "net/cl/s plain",
                      "ratio");
          for (std::size_t i = 0; i + 1 < runs.size(); i += 2) {
            const double with = runs[i].cpuMsPerClientS, without = runs[i + 1].cpuMsPerClientS;
            const double ratio = without > 0 ? with / without : 0.0;
            std::printf("%7d %14.4f %14.4f %7.3f\n", runs[i].report.clients, with, without, ratio);
            const std::string sfx = suffix(runs[i].report.clients);
            figures(runs[i], sfx + ".tls");
            figures(runs[i + 1], sfx + ".plain");
            figure("tls_cpu_ratio" + sfx, ratio, "ratio");
          }
          return 0;
        }
        if (runs.size() > 1) {
          for (const load::ServerLoadResult& r : runs) figures(r, suffix(r.report.clients));
        }
        figures(runs.back(), "");
        return 0;
      }};
}

}  // namespace pc::bench
