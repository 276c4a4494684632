// probecast-loadgen: N protocol-only clients in one process against a probecast-server (no
// rendering, no Vulkan). Prints progress while clients join, then the report as a table, and
// with --json writes it as JSON (summary and per client). See loadgen/load_generator.h.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <thread>

#include "common/log.h"
#include "loadgen/load_generator.h"
#include "loadgen/server_load.h"
#include "tools/command_line.h"
#include "tools/token_input.h"

namespace {

void sleepSeconds(double s) { std::this_thread::sleep_for(std::chrono::duration<double>(s)); }

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"probecast load generator: many protocol-only clients against one server"};
  pc::load::LoadOptions o;
  double seconds = 10, warmup = 2;
  std::string jsonPath;
  bool decodeEach = false;
  pc::addConnectOption(app, o.host, o.port, o.alternates,
                       "the server; several (relays of one field, comma-separated or the flag "
                       "again): each client takes the least loaded (PROTOCOL.md, \"Choosing an "
                       "endpoint by load\")");
  // The spelling before --connect, as probecast-client has it; kept for one release.
  app.add_option("--host", o.host, "deprecated: --connect HOST:PORT")->group("Deprecated");
  app.add_option("--port", o.port, "deprecated: --connect HOST:PORT")->group("Deprecated");
  std::string tokenFile;
  app.add_option("--token-file", tokenFile,
                 "connect token (else $PROBECAST_TOKEN_FILE or $PROBECAST_TOKEN); every client "
                 "presents it, so the server's --max-sessions-per-client must allow them");
  app.add_option("--clients", o.clients, "number of clients");
  app.add_option("--threads", o.threads, "network threads shared by all clients");
  app.add_flag("--tcp-only", o.tcpOnly, "ask for datagrams over TCP");
  app.add_option("--server-fingerprint", o.serverFingerprint,
                 "trust the server whose TLS certificate has this SHA-256 (sha256:<hex>)");
  app.add_option("--ca-file", o.caFile,
                 "trust server certificates from this CA file (PEM) and check the host name");
  app.add_flag("--no-tls{false}", o.tls, "plain TCP, for a server run with --no-tls");
  app.add_option("--ramp", o.rampSeconds, "s over which clients first connect");
  app.add_option("--session-seconds", o.sessionSeconds,
                 "churn: end each session after about this long and reconnect (0: never)");
  app.add_option("--session-jitter", o.sessionJitter, "fraction of --session-seconds randomised");
  app.add_option("--max-sessions", o.maxSessions, "no new session after this many (0: no limit)");
  app.add_option("--starve-seconds", o.starveSeconds, "gap that makes a client starved");
  app.add_option("--pose-interval", o.poseInterval, "s between viewer poses");
  app.add_flag(
      "--other-host", [&](std::int64_t) { o.sameClock = false; },
      "server on another host: estimate the clock offset instead of sharing the clock");
  app.add_flag("--keep-field", o.keepField, "each receiver keeps a decoded field (as a renderer)");
  app.add_flag("--decode-each", decodeEach, "every client decodes every payload itself");
  app.add_option("--warmup", warmup, "s after the ramp before the measured window starts");
  app.add_option("--seconds", seconds, "measured window, s");
  app.add_option("--json", jsonPath, "write the report as JSON here");
  app.add_option("--series", o.seriesPath,
                 "write one CSV row per second of the run here (clients, kbit/s, latency "
                 "percentiles, staleness, held-field PSNR, errors; docs/BENCHMARKS.md)");
  app.add_option("--seed", o.seed, "random seed (pose phases, session jitter)");
  std::string rateMix;
  app.add_option("--rate-mix", rateMix,
                 "emulated links, MBIT:SHARE,... (e.g. 0.5:0.25,1:0.5,10:0.25; none: loopback)");
  app.add_option("--link-queue", o.linkQueueSeconds, "emulated links' queue, s at their rate");
  app.add_option("--min-held-psnr", o.minHeldPsnr, "held field worse than this starves, dB");
  app.add_option("--max-change-age", o.maxChangeAge, "changes older than this not held starve, s");
  if (auto code = pc::parseCommandLine(app, argc, argv)) return *code;
  if (!rateMix.empty()) {
    auto links = pc::load::parseRateMix(rateMix);
    if (!links) {
      std::fprintf(stderr, "probecast-loadgen: %s\n", links.error().message.c_str());
      return 2;
    }
    o.links = *links;
  }
  o.shareDecoding = !decodeEach;
  auto token = pc::connectToken(tokenFile);
  if (!token) return pc::logError(token.error().message), 1;
  o.token = *token;
  pc::load::raiseFileLimit();

  auto generator = pc::load::LoadGenerator::create(o);
  if (!generator) return pc::logError(generator.error().message), 1;
  pc::load::LoadGenerator& gen = **generator;
  gen.start();
  auto progress = [&](const char* phase) {
    const pc::load::LoadSnapshot s = gen.snapshot();
    std::printf("%s: %d/%d in session, %d synced, %llu sessions started, %llu errors\n", phase,
                s.inSession, s.clients, s.synced, (unsigned long long)s.sessionsStarted,
                (unsigned long long)s.errors);
    // Where the clients chose to be, given several endpoints.
    if (s.perEndpoint.size() > 1) {
      std::printf("  in session per endpoint:");
      for (const auto& [endpoint, n] : s.perEndpoint) std::printf(" %s %d", endpoint.c_str(), n);
      std::printf("\n");
    }
    std::fflush(stdout);
  };
  for (double t = 0; t < o.rampSeconds + warmup; t += 1.0) {
    sleepSeconds(1.0);
    progress("joining");
  }
  gen.beginWindow();
  for (double t = 0; t < seconds; t += 1.0) {
    sleepSeconds(std::min(1.0, seconds - t));
    if (int(t) % 5 == 4) progress("measuring");
  }
  const pc::load::LoadReport report = gen.report();
  gen.stop();
  std::printf("%s", pc::load::reportTable(report).c_str());
  if (!jsonPath.empty()) {
    std::ofstream out(jsonPath);
    out << pc::load::reportJson(report);
    if (!out) return pc::logError("cannot write " + jsonPath), 1;
  }
  return report.errors == 0 && report.starvedClients == 0 ? 0 : 2;
}
