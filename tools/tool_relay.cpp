// probecast-relay: a stateless edge in front of clients. It follows the field server's field
// through NATS JetStream (catching up from the bucket when it starts, then following its
// changes) and serves clients exactly as probecast-server does, with the same network layer
// and flags; its clients' viewer poses and its load go back over NATS. Two threads besides
// main: the follower and the network thread; main waits for SIGINT/SIGTERM (or --duration).
#include <CLI/CLI.hpp>
#include <cstdio>
#include <optional>
#include <string>
#include <vector>

#include "common/log.h"
#include "relay/relay.h"
#include "tools/command_line.h"
#include "tools/serve_options.h"

namespace {

struct RelaySetup : pc::ServeSetup {
  pc::relay::RelayOptions relay;
  double catchUpTimeout = 30;
};

std::optional<int> parseOptions(int argc, char** argv, RelaySetup& s) {
  CLI::App app{
      "probecast relay: follows the field server's field through NATS and serves clients as "
      "the server does"};
  pc::addNatsOptions(app, s.relay.nats, s.relay.bucket);
  app.add_option("--relay-id", s.relay.relayId,
                 "this relay's name in its pose and load subjects (default: host name and "
                 "process id)");
  app.add_option("--advertise", s.relay.advertise,
                 "HOST:PORT clients reach this relay at, in its load reports (default: the "
                 "bind address and port)");
  app.add_option("--catch-up-timeout", s.catchUpTimeout,
                 "seconds to wait for the field in the bucket before giving up (exit 1)")
      ->check(CLI::Range(0.1, 86400.0));
  pc::addStreamOptions(app, s);
  pc::addReportOptions(app, s);
  pc::addLimitOptions(app, s);
  if (auto code = pc::parseCommandLine(app, argc, argv)) return *code;
  if (!pc::applyServeOptions(s)) return 1;
  s.net.sceneName = s.sceneName;  // empty: the catalogue's
  s.relay.net = s.net;
  s.relay.publisher = s.publisherOptions;
  return std::nullopt;
}

std::string statsLine(const pc::relay::RelayStats& r, const pc::NetServerStats& n) {
  char line[256];
  std::snprintf(line, sizeof line,
                "clients %zu | field v%llu, %llu bricks taken, NATS %s, latency %.1f ms | "
                "accepted %llu, rejected %llu",
                n.clients.size(), (unsigned long long)r.fieldVersion,
                (unsigned long long)r.bricksApplied, r.natsConnected ? "up" : "down",
                r.natsLatencyMs, (unsigned long long)n.accepted, (unsigned long long)n.rejected);
  return line;
}

}  // namespace

int main(int argc, char** argv) {
  RelaySetup setup;
  if (auto code = parseOptions(argc, argv, setup)) return *code;
  const pc::Signals signals;
  auto relay = pc::relay::Relay::create(setup.relay);
  if (!relay) return pc::logError(relay.error().message), 1;
  if (pc::Status started = (*relay)->start(setup.catchUpTimeout); !started)
    return pc::logError(started.error().message), 1;
  pc::logInfo("relay listening on " + setup.net.bindAddress + ":" +
              std::to_string((*relay)->port()) + ", following bucket " + setup.relay.bucket);
  pc::announceServing(setup.net, (*relay)->port(), (*relay)->metricsPort(),
                      (*relay)->tlsFingerprint());

  const double start = pc::steadySeconds();
  double lastStats = start;
  pc::NetServerStats before = (*relay)->serverStats();
  while (true) {
    if (const int sig = signals.wait(timespec{0, 200'000'000})) {
      pc::logInfo(std::string("shutting down (") + pc::Signals::name(sig) + ")");
      break;
    }
    const double now = pc::steadySeconds();
    if (setup.duration > 0 && now - start >= setup.duration) {
      pc::logInfo("shutting down (--duration reached)");
      break;
    }
    if (setup.statsInterval > 0 && now - lastStats >= setup.statsInterval) {
      const pc::relay::RelayStats r = (*relay)->stats();
      const pc::NetServerStats n = (*relay)->serverStats();
      std::vector<pc::LogField> fields = pc::statisticsFields(n, before, now - lastStats);
      fields.insert(fields.end(), {{"bricks_taken_total", r.bricksApplied},
                                   {"nats_connected", r.natsConnected ? 1 : 0},
                                   {"nats_latency_ms", r.natsLatencyMs}});
      pc::logRecord(pc::LogLevel::Info, "statistics", fields, statsLine(r, n));
      before = n;
      lastStats = now;
    }
  }
  (*relay)->stop();
  return 0;
}
