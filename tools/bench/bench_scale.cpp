// scale: the field served past one machine's worth of clients, on this host. Starts a
// nats-server (JetStream in a temporary folder), probecast-server exporting its field to it,
// R probecast-relay processes, and N load-generator clients spread evenly over the relays (in
// this process, one generator per relay); measures a window, then starts a few real clients
// given every relay, which choose one by load, kills the relay most of them chose (SIGKILL)
// and times their move to the least loaded survivors.
//
// Figures: relay_cpu_ms_per_client_s (the relays' CPU in the window / N / window: what a client
// costs its relay; printed per relay too, and _max the busiest relay's), field_server_cpu_ms_
// per_s (the field server's whole process: it serves no client, so it should not grow with R
// or N; run R = 2, 3 to see it flat), p99 latency from the field server's publish to a client's
// apply (through NATS and a relay), starved clients, the held field's PSNR (5th percentile over
// clients: its error against the current field), and failover_s (the slowest of the moving
// clients, from the kill to holding every brick on another relay).
// clang-format off
#include <utility>  // first: Boost.Asio 1.74 uses std::exchange without including it
// clang-format on
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>

#include <algorithm>
#include <boost/asio.hpp>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "bench.h"
#include "client/net_client.h"
#include "loadgen/load_generator.h"
#include "loadgen/proc_stats.h"
#include "loadgen/server_load.h"
#include "loadgen/server_process.h"
#include "net/tls_certificate.h"
#include "protocol/connect_token.h"
#include "protocol/secure_io.h"

extern char** environ;

namespace pc::bench {

namespace {

namespace fs = std::filesystem;

struct ScaleSetup {
  int relays = 2;
  int clients = 100;  // load-generator clients, spread evenly over the relays
  double seconds = 10, warmup = 2;
  double rateLimitMbit = 1.0;
  int failoverClients = 8;
  int loadThreads = 0;    // network threads per load generator; 0: one per 250 clients
  bool noResume = false;  // movers start new sessions (the whole field again), as before resume
  int rays = 64, serverWarmup = 8;
  double fieldRate = 10;
  std::string natsServer = "/usr/sbin/nats-server";
  std::string dir;  // default: a folder in the temporary directory
};

double seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}
void sleepFor(double s) { std::this_thread::sleep_for(std::chrono::duration<double>(s)); }

std::uint16_t freePort() {
  boost::asio::io_context io;
  boost::asio::ip::tcp::acceptor a(io, {boost::asio::ip::make_address("127.0.0.1"), 0});
  return a.local_endpoint().port();
}

bool listening(std::uint16_t port) {
  boost::asio::io_context io;
  boost::asio::ip::tcp::socket s(io);
  boost::system::error_code ec;
  s.connect({boost::asio::ip::make_address("127.0.0.1"), port}, ec);
  return !ec;
}

// The nats-server child: JetStream, its store in `dir`, log to a file; SIGTERM when done.
class NatsProcess {
 public:
  static Result<std::unique_ptr<NatsProcess>> start(const std::string& exe, const fs::path& dir) {
    auto p = std::unique_ptr<NatsProcess>(new NatsProcess);
    p->port_ = freePort();
    std::vector<std::string> args{exe,
                                  "-a",
                                  "127.0.0.1",
                                  "-p",
                                  std::to_string(p->port_),
                                  "-js",
                                  "-sd",
                                  (dir / "nats-store").string()};
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    const std::string log = (dir / "nats.log").string();
    posix_spawn_file_actions_addopen(&actions, 2, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int rc = posix_spawn(&p->pid_, argv[0], &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    if (rc != 0) return Error{"cannot start " + exe + ": " + std::strerror(rc)};
    for (int i = 0; i < 200 && !listening(p->port_); ++i) sleepFor(0.05);
    if (!listening(p->port_)) return Error{exe + " never listened (see " + log + ")"};
    return p;
  }
  ~NatsProcess() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGTERM);
    waitpid(pid_, nullptr, 0);
  }
  std::string url() const { return "nats://127.0.0.1:" + std::to_string(port_); }

 private:
  pid_t pid_ = -1;
  std::uint16_t port_ = 0;
};

double cpuSeconds(pid_t pid) {
  auto s = load::readProcStats(pid);
  return s ? s->cpuSeconds : 0.0;
}

int runScale(const ScaleSetup& s) {
  if (s.relays < 2) return std::fprintf(stderr, "scale: --relays must be at least 2\n"), 1;
  if (!fs::exists(s.natsServer))
    return std::fprintf(stderr, "scale: %s not found (--nats-server)\n", s.natsServer.c_str()), 1;
  const fs::path dir =
      s.dir.empty() ? fs::temp_directory_path() / "probecast-bench-scale" : fs::path(s.dir);
  fs::remove_all(dir);
  fs::create_directories(dir);
  load::raiseFileLimit();
  // This process holds a TCP and a UDP socket per client (and the movers'); each relay a TCP
  // socket per client. Better said now than as connect errors a minute in.
  if (rlimit files{}; getrlimit(RLIMIT_NOFILE, &files) == 0 && files.rlim_cur != RLIM_INFINITY &&
                      files.rlim_cur < rlim_t(2 * (s.clients + s.failoverClients) + 256)) {
    return std::fprintf(stderr,
                        "scale: %d clients need about %d open files, the limit is %llu (raise "
                        "it: ulimit -n)\n",
                        s.clients, 2 * (s.clients + s.failoverClients) + 256,
                        (unsigned long long)files.rlim_cur),
           1;
  }

  // Keys, a token per client (the relays' per-token caps stay on), one certificate for every
  // relay.
  const KeyPair issuer = generateKeyPair();
  const std::string verifyKey = (dir / "issuer.pub").string();
  if (Status w = writeKeyFile(verifyKey, issuer.verify); !w)
    return std::fprintf(stderr, "scale: %s\n", w.error().message.c_str()), 1;
  const std::int64_t now = unixSeconds();
  std::vector<std::string> tokens;
  for (int i = 0; i < s.clients + s.failoverClients; ++i)
    tokens.push_back(issueToken(issuer.signing, newTokenClaims("scale-" + std::to_string(i), "*",
                                                               TokenRole::Viewer, 1, now, 3600))
                         .value());
  auto dev = net::makeDevCertificate();
  if (!dev) return std::fprintf(stderr, "scale: %s\n", dev.error().message.c_str()), 1;
  const std::string cert = (dir / "cert.pem").string(), key = (dir / "key.pem").string();
  std::ofstream(cert) << dev->certificatePem;
  if (Status w = writeFileAtomically(key, dev->keyPem, 0600); !w)
    return std::fprintf(stderr, "scale: %s\n", w.error().message.c_str()), 1;

  auto nats = NatsProcess::start(s.natsServer, dir);
  if (!nats) return std::fprintf(stderr, "scale: %s\n", nats.error().message.c_str()), 1;
  const std::vector<std::string> noCaps{"--max-clients",
                                        std::to_string(s.clients + s.failoverClients + 16),
                                        "--max-sessions-per-address",
                                        "0",
                                        "--max-pending-per-address",
                                        "0",
                                        "--handshakes-per-second-per-address",
                                        "0",
                                        "--stats-interval",
                                        "0",
                                        "--rate-limit",
                                        std::to_string(s.rateLimitMbit * 1e6 / 8)};
  load::ServerProcessOptions server;
  server.executable = load::siblingExecutable("probecast-server");
  server.args = {"--scene",
                 "builtin",
                 "--backend",
                 "embree",
                 "--rays",
                 std::to_string(s.rays),
                 "--warmup",
                 std::to_string(s.serverWarmup),
                 "--rate",
                 std::to_string(s.fieldRate),
                 "--bind",
                 "127.0.0.1",
                 "--port",
                 "0",
                 "--token-key",
                 verifyKey,
                 "--dev-self-signed",
                 "--nats",
                 (*nats)->url()};
  server.args.insert(server.args.end(), noCaps.begin(), noCaps.end());
  server.logPath = (dir / "server.log").string();
  auto field = load::ServerProcess::start(server);
  if (!field)
    return std::fprintf(stderr, "scale: field server: %s\n", field.error().message.c_str()), 1;

  std::vector<std::unique_ptr<load::ServerProcess>> relays;
  for (int r = 0; r < s.relays; ++r) {
    load::ServerProcessOptions o;
    o.executable = load::siblingExecutable("probecast-relay");
    o.args = {"--nats",      (*nats)->url(),
              "--relay-id",  "relay-" + std::to_string(r),
              "--bind",      "127.0.0.1",
              "--port",      "0",
              "--token-key", verifyKey,
              "--tls-cert",  cert,
              "--tls-key",   key};
    o.args.insert(o.args.end(), noCaps.begin(), noCaps.end());
    o.logPath = (dir / ("relay-" + std::to_string(r) + ".log")).string();
    auto relay = load::ServerProcess::start(o);
    if (!relay)
      return std::fprintf(stderr, "scale: relay %d: %s\n", r, relay.error().message.c_str()), 1;
    relays.push_back(std::move(relay).value());
  }

  // The load: N clients, N/R on each relay (one generator per relay, in this process).
  std::vector<std::unique_ptr<load::LoadGenerator>> generators;
  for (int r = 0; r < s.relays; ++r) {
    load::LoadOptions o;
    o.host = "127.0.0.1";
    o.port = relays[std::size_t(r)]->port();
    o.caFile = cert;
    o.clients = s.clients / s.relays + (r < s.clients % s.relays ? 1 : 0);
    for (int i = r; i < s.clients; i += s.relays) o.clientTokens.push_back(tokens[std::size_t(i)]);
    o.rampSeconds = std::max(1.0, 0.005 * o.clients);
    // A thousand clients are more than one network thread keeps up with at 1 Mbit/s each.
    o.threads = s.loadThreads > 0 ? s.loadThreads : std::max(1, (o.clients + 249) / 250);
    auto g = load::LoadGenerator::create(o);
    if (!g)
      return std::fprintf(stderr, "scale: load generator: %s\n", g.error().message.c_str()), 1;
    (*g)->start();
    generators.push_back(std::move(g).value());
  }
  const double joinStart = seconds();
  auto allSynced = [&] {
    for (auto& g : generators) {
      const load::LoadSnapshot snap = g->snapshot();
      if (snap.synced < snap.clients) return false;
    }
    return true;
  };
  while (!allSynced() && seconds() - joinStart < 60) sleepFor(0.1);
  const bool synced = allSynced();
  sleepFor(s.warmup);

  // The window.
  for (auto& g : generators) g->beginWindow();
  std::vector<double> relayCpu0, relayCpu1;
  for (auto& r : relays) relayCpu0.push_back(cpuSeconds(r->pid()));
  const double fieldCpu0 = cpuSeconds((*field)->pid()), t0 = seconds();
  sleepFor(s.seconds);
  for (auto& r : relays) relayCpu1.push_back(cpuSeconds(r->pid()));
  const double fieldCpu1 = cpuSeconds((*field)->pid()), window = seconds() - t0;
  std::vector<load::LoadReport> reports;
  for (auto& g : generators) reports.push_back(g->report());

  // Failover: real clients given every relay choose one by load (PROTOCOL.md "Choosing an
  // endpoint by load"); the relay most of them chose is killed, and they move to the least
  // loaded survivor.
  std::vector<std::unique_ptr<client::FieldMirror>> mirrors;
  std::vector<std::unique_ptr<client::NetClient>> movers;
  auto endpointOf = [&](std::size_t r) { return "127.0.0.1:" + std::to_string(relays[r]->port()); };
  for (int i = 0; i < s.failoverClients; ++i) {
    client::NetClientOptions o;
    o.host = "127.0.0.1";
    o.port = relays[0]->port();
    for (std::size_t r = 1; r < relays.size(); ++r)
      o.alternates.push_back({"127.0.0.1", relays[r]->port()});
    o.caFile = cert;
    o.token = tokens[std::size_t(s.clients + i)];
    o.name = "mover-" + std::to_string(i);
    o.resume = !s.noResume;
    mirrors.push_back(std::make_unique<client::FieldMirror>());
    movers.push_back(std::make_unique<client::NetClient>(*mirrors.back(), o));
    movers.back()->start();
  }
  const double moveStart = seconds();
  auto allMoversSynced = [&] {
    for (auto& m : movers)
      if (!m->stats().synced) return false;
    return true;
  };
  while (!allMoversSynced() && seconds() - moveStart < 30) sleepFor(0.01);
  std::vector<int> moversOn(relays.size(), 0);
  for (auto& m : movers) {
    const std::string at = m->stats().endpoint;
    for (std::size_t r = 0; r < relays.size(); ++r) moversOn[r] += at == endpointOf(r);
  }
  const std::size_t victim =
      std::size_t(std::max_element(moversOn.begin(), moversOn.end()) - moversOn.begin());
  std::vector<std::size_t> moving;  // the movers on the victim
  for (std::size_t i = 0; i < movers.size(); ++i)
    if (movers[i]->stats().endpoint == endpointOf(victim)) moving.push_back(i);
  // Bytes the movers receive from the kill until they hold every brick again: the whole field
  // for a new session, what changed since for one that resumed.
  auto moverBytes = [&] {
    double bytes = 0;
    for (std::size_t i : moving) {
      const client::NetClientStats st = movers[i]->stats();
      bytes += double(st.tcpBytes + st.udpBytes);
    }
    return bytes;
  };
  auto moved = [&] {
    for (std::size_t i : moving) {
      const client::NetClientStats st = movers[i]->stats();
      if (!st.synced || st.endpoint == endpointOf(victim)) return false;
    }
    return true;
  };
  const double bytesAtKill = moverBytes();
  ::kill(relays[victim]->pid(), SIGKILL);
  const double killed = seconds();
  double failover = -1;
  while (!moving.empty() && seconds() - killed < 30) {
    if (moved()) {
      failover = seconds() - killed;
      break;
    }
    sleepFor(0.005);
  }
  // Where they went: each survivor's share of the movers.
  std::string landed;
  for (std::size_t r = 0; r < relays.size(); ++r) {
    if (r == victim) continue;
    int n = 0;
    for (std::size_t i : moving) n += movers[i]->stats().endpoint == endpointOf(r);
    landed += " relay-" + std::to_string(r) + ":" + std::to_string(n);
  }
  const double moverKB =
      (moverBytes() - bytesAtKill) / 1e3 / double(std::max<std::size_t>(1, moving.size()));
  int mirrorsHeld = 0;
  for (std::size_t i : moving) mirrorsHeld += mirrors[i]->present() ? 1 : 0;
  for (auto& m : movers) m->stop();
  for (auto& g : generators) g->stop();
  for (std::size_t r = 0; r < relays.size(); ++r)
    if (r != victim) (void)relays[r]->stop();
  (void)(*field)->stop();

  // Figures over every relay's clients.
  double p99 = 0, psnrP5 = 1e9;
  int starved = 0;
  std::uint64_t errors = 0;
  for (const load::LoadReport& r : reports) {
    p99 = std::max(p99, r.latencyMs.p99);
    starved += r.starvedClients;
    errors += r.errors;
    psnrP5 = std::min(psnrP5, r.all.heldPsnrP5);
  }
  double relayCpu = 0, relayMaxMsPerClientS = 0;
  std::vector<double> perRelay;  // ms of CPU per client-second, relay by relay
  for (std::size_t r = 0; r < relays.size(); ++r) {
    relayCpu += relayCpu1[r] - relayCpu0[r];
    const int clients = std::max(1, reports[r].clients);
    perRelay.push_back((relayCpu1[r] - relayCpu0[r]) * 1e3 / double(clients) / window);
    relayMaxMsPerClientS = std::max(relayMaxMsPerClientS, perRelay.back());
  }
  const double relayMsPerClientS = relayCpu * 1e3 / double(s.clients) / window;
  const double fieldMsPerS = (fieldCpu1 - fieldCpu0) * 1e3 / window;
  std::printf("scale: %d relays, %d clients (%s), %.1f s window, %s\n", s.relays, s.clients,
              synced ? "all synced" : "NOT all synced within 60 s", window,
              machineDescription().c_str());
  std::printf("  relays %.3f ms CPU per client-second, field server %.1f ms CPU per second\n",
              relayMsPerClientS, fieldMsPerS);
  for (std::size_t r = 0; r < relays.size(); ++r)
    std::printf("  relay-%zu: %d clients, %.3f ms CPU per client-second\n", r, reports[r].clients,
                perRelay[r]);
  std::printf(
      "  latency p99 %.1f ms (publish -> apply, through NATS), starved %d, errors %llu, "
      "held field PSNR p5 %.1f dB\n",
      p99, starved, (unsigned long long)errors, psnrP5);
  for (const load::LoadReport& r : reports) {
    for (const load::ClientReport& c : r.perClient) {
      if (!c.starved) continue;
      std::printf("  a starved client: %s\n", c.starvedWhy.c_str());  // one, as an example
      break;
    }
  }
  std::printf(
      "  failover: relay-%zu killed under %zu of %d clients, who moved in %.3f s (%s) to the "
      "least loaded survivors (%s ), %.1f kB each on the way, %d of them kept their field "
      "(logs in %s)\n",
      victim, moving.size(), s.failoverClients, failover, s.noResume ? "new sessions" : "resumed",
      landed.c_str(), moverKB, mirrorsHeld, dir.c_str());
  const std::string sfx =
      ".relays_" + std::to_string(s.relays) + ".clients_" + std::to_string(s.clients);
  figure("relay_cpu_ms_per_client_s" + sfx, relayMsPerClientS, "ms");
  figure("relay_cpu_ms_per_client_s_max" + sfx, relayMaxMsPerClientS, "ms");
  figure("field_server_cpu_ms_per_s" + sfx, fieldMsPerS, "ms");
  figure("p99_latency_ms" + sfx, p99, "ms");
  figure("starved_clients" + sfx, starved, "count");
  figure("held_psnr_db_p5" + sfx, psnrP5, "dB");
  figure("failover_s" + sfx, failover, "s");
  figure("failover_kb_per_client" + sfx, moverKB, "kB");
  return synced && failover >= 0 && mirrorsHeld == int(moving.size()) ? 0 : 2;
}

}  // namespace

Benchmark addScale(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "scale",
      "the field through NATS to relays: relay CPU per client, field-server CPU, latency, "
      "failover");
  static ScaleSetup s;
  cmd->add_option("--relays", s.relays, "probecast-relay processes (at least 2)");
  cmd->add_option("--clients", s.clients, "load-generator clients over all relays");
  cmd->add_option("--seconds", s.seconds, "measured window, s");
  cmd->add_option("--warmup", s.warmup, "s after every client is synced, before the window");
  cmd->add_option("--rate-limit", s.rateLimitMbit, "send rate per client, Mbit/s");
  cmd->add_flag("--no-resume", s.noResume,
                "movers start new sessions on the other relay (the whole field sent again) "
                "instead of resuming from their mirrors");
  cmd->add_option("--failover-clients", s.failoverClients,
                  "real clients given every relay, whose move is timed when the relay most of them "
                  "chose by load is killed");
  cmd->add_option("--load-threads", s.loadThreads,
                  "network threads per relay's load generator (0: one per 250 clients)");
  cmd->add_option("--rays", s.rays, "field server rays per probe per update");
  cmd->add_option("--field-rate", s.fieldRate, "field server updates per second");
  cmd->add_option("--nats-server", s.natsServer, "the nats-server executable");
  cmd->add_option("--dir", s.dir, "folder for keys, the NATS store and the logs");
  return {cmd, [] { return runScale(s); }};
}

}  // namespace pc::bench
