#include "server_load.h"

#include <sys/resource.h>
#include <sys/time.h>

#include <boost/asio.hpp>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <thread>

#include "proc_stats.h"
#include "protocol/connect_token.h"
#include "server_process.h"

namespace pc::load {

namespace {

double nowSeconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

void sleepSeconds(double s) { std::this_thread::sleep_for(std::chrono::duration<double>(s)); }

double selfCpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         double(u.ru_utime.tv_usec + u.ru_stime.tv_usec) * 1e-6;
}

// Sets `nice` on every thread of `pid` not named "pc-net"; how many threads were changed.
int reniceAllButNetwork(pid_t pid, int nice) {
  int changed = 0;
  std::error_code ec;
  const std::string dir = "/proc/" + std::to_string(pid) + "/task";
  for (auto it = std::filesystem::directory_iterator(dir, ec);
       !ec && it != std::filesystem::directory_iterator(); it.increment(ec)) {
    std::ifstream comm(it->path() / "comm");
    std::string name;
    if (!std::getline(comm, name) || name == "pc-net") continue;
    const id_t tid = id_t(std::stoul(it->path().filename().string()));
    if (setpriority(PRIO_PROCESS, tid, nice) == 0) ++changed;
  }
  return changed;
}

// A TCP port free now on 127.0.0.1, for the server's metrics endpoint (probecast-server's
// --metrics-port 0 means off, not any port). Another process could take it before the server
// binds it; the server then fails to start and says so.
Result<std::uint16_t> freeLocalPort() {
  namespace asio = boost::asio;
  asio::io_context io;
  boost::system::error_code ec;
  asio::ip::tcp::acceptor a(io);
  const asio::ip::tcp::endpoint any(asio::ip::make_address("127.0.0.1"), 0);
  a.open(any.protocol(), ec);
  if (!ec) a.bind(any, ec);
  if (ec) return Error{"no free TCP port for the metrics: " + ec.message()};
  return a.local_endpoint().port();
}

// GET /metrics from 127.0.0.1:port; the unlabelled samples by name.
Result<std::map<std::string, double>> fetchMetrics(std::uint16_t port) {
  namespace asio = boost::asio;
  asio::io_context io;
  asio::ip::tcp::socket socket(io);
  boost::system::error_code ec;
  socket.connect({asio::ip::make_address("127.0.0.1"), port}, ec);
  if (ec) return Error{"metrics: " + ec.message()};
  const std::string request =
      "GET /metrics HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n";
  asio::write(socket, asio::buffer(request), ec);
  if (ec) return Error{"metrics: " + ec.message()};
  std::string response;
  asio::read(socket, asio::dynamic_buffer(response), ec);
  if (ec && ec != asio::error::eof) return Error{"metrics: " + ec.message()};
  const std::size_t body = response.find("\r\n\r\n");
  if (body == std::string::npos) return Error{"metrics: no HTTP body"};
  std::map<std::string, double> samples;
  std::istringstream lines(response.substr(body + 4));
  for (std::string line; std::getline(lines, line);) {
    if (line.empty() || line[0] == '#' || line.find('{') != std::string::npos) continue;
    const std::size_t space = line.find(' ');
    if (space == std::string::npos) continue;
    samples[line.substr(0, space)] = std::strtod(line.c_str() + space + 1, nullptr);
  }
  return samples;
}

}  // namespace

void raiseFileLimit() {
  rlimit r{};
  if (getrlimit(RLIMIT_NOFILE, &r) == 0 && r.rlim_cur < r.rlim_max) {
    r.rlim_cur = r.rlim_max;
    setrlimit(RLIMIT_NOFILE, &r);
  }
}

Result<ServerLoadResult> runServerLoad(const ServerLoadOptions& options,
                                       const std::function<void(const std::string&)>& progress) {
  auto say = [&](const std::string& line) {
    if (progress) progress(line);
  };
  raiseFileLimit();
  ServerProcessOptions sp;
  sp.executable = options.serverExecutable;
  sp.logPath = options.serverLog;
  // A token issuer of this run: its verify key for the server, one token per client.
  const KeyPair keys = generateKeyPair();
  const std::string keyFile = options.serverLog + ".verify-key";
  if (Status s = writeKeyFile(keyFile, keys.verify); !s) return s.error();
  std::vector<std::string> tokens;
  const std::int64_t nowUnix = unixSeconds();
  for (int i = 0; i < options.load.clients; ++i) {
    auto token = issueToken(keys.signing, newTokenClaims("loadgen-" + std::to_string(i), "*",
                                                         TokenRole::Viewer, 1, nowUnix, 86400));
    if (!token) return token.error();
    tokens.push_back(*token);
  }
  auto metricsPort = freeLocalPort();
  if (!metricsPort) return metricsPort.error();
  sp.args = {"--scene", "builtin",     "--bind", "127.0.0.1",      "--port",
             "0",       "--token-key", keyFile,  "--metrics-port", std::to_string(*metricsPort)};
  // TLS with a certificate the server makes at start, pinned by the load generator; or
  // neither (--no-tls) when the load says so, to measure what TLS costs.
  sp.args.push_back(options.load.tls ? "--dev-self-signed" : "--no-tls");
  // Every simulated client comes from this one address: the per-address caps, which keep one
  // stranger from taking every place, would turn most of them away.
  for (const char* cap : {"--max-pending-per-address", "--max-sessions-per-address",
                          "--handshakes-per-second-per-address"}) {
    sp.args.insert(sp.args.end(), {cap, "0"});
  }
  sp.args.insert(sp.args.end(), options.serverArgs.begin(), options.serverArgs.end());
  auto server = ServerProcess::start(sp);
  if (!server) return server.error();
  const pid_t pid = (*server)->pid();

  ServerLoadResult result;
  if (options.fieldNice > 0) {
    const int n = reniceAllButNetwork(pid, options.fieldNice);
    say("server threads but the network thread at nice " + std::to_string(options.fieldNice) +
        ": " + std::to_string(n));
  }
  // Idle: the field thread alone.
  auto idle0 = readProcStats(pid);
  if (!idle0) return idle0.error();
  const double idleStart = nowSeconds();
  sleepSeconds(options.idleSeconds);
  auto idle1 = readProcStats(pid);
  if (!idle1) return idle1.error();
  const double idleSeconds = nowSeconds() - idleStart;
  result.serverIdleCpuMsPerS = (idle1->cpuSeconds - idle0->cpuSeconds) * 1e3 / idleSeconds;
  result.netIdleCpuMsPerS =
      (idle1->threadCpu("pc-net") - idle0->threadCpu("pc-net")) * 1e3 / idleSeconds;
  if (idle1->threadCpuSeconds.count("pc-net") == 0)
    return Error{"the server has no thread named pc-net (an older probecast-server?)"};
  say("server idle: " + std::to_string(int(result.serverIdleCpuMsPerS)) +
      " ms CPU per s, network thread " + std::to_string(result.netIdleCpuMsPerS));

  LoadOptions lo = options.load;
  lo.host = "127.0.0.1";
  lo.port = (*server)->port();
  lo.clientTokens = std::move(tokens);
  lo.serverFingerprint = (*server)->tlsFingerprint();
  auto generator = LoadGenerator::create(lo);
  if (!generator) return generator.error();
  LoadGenerator& gen = **generator;
  const double start = nowSeconds();
  gen.start();
  double lastSay = start;
  while (true) {
    const LoadSnapshot s = gen.snapshot();
    const double now = nowSeconds();
    if (s.synced == lo.clients) {
      result.allSynced = true;
      break;
    }
    if (now - start > lo.rampSeconds + options.joinLimit) break;
    if (now - lastSay >= 2.0) {
      lastSay = now;
      say("joining: " + std::to_string(s.inSession) + "/" + std::to_string(lo.clients) +
          " in session, " + std::to_string(s.synced) + " synced, " + std::to_string(s.errors) +
          " errors");
    }
    sleepSeconds(0.05);
  }
  result.joinSeconds = nowSeconds() - start;
  say(std::string(result.allSynced ? "all synced" : "NOT all synced") + " after " +
      std::to_string(result.joinSeconds) + " s; warming up");
  sleepSeconds(options.warmupSeconds);

  auto warm = readProcStats(pid);
  if (!warm) return warm.error();
  result.rssWarmMb = warm->rssMb;
  result.fdsWarm = warm->openFds;
  const double selfCpu0 = selfCpuSeconds();
  gen.beginWindow();
  const double windowStart = nowSeconds();
  const std::uint64_t version0 = gen.snapshot().newestFieldVersion;
  for (double t = 0; t < options.seconds;) {
    const double step = std::min(5.0, options.seconds - t);
    sleepSeconds(step);
    t += step;
    const LoadSnapshot s = gen.snapshot();
    say("measuring: " + std::to_string(int(t)) + " s, " + std::to_string(s.synced) + "/" +
        std::to_string(lo.clients) + " synced, " + std::to_string(s.errors) + " errors");
  }
  auto end = readProcStats(pid);
  const double window = nowSeconds() - windowStart;
  if (auto m = fetchMetrics(*metricsPort)) {
    auto mb = [&](const char* name) {
      auto it = m->find(name);
      return it == m->end() ? -1.0 : it->second / 1e6;
    };
    result.encodeCacheMb = mb("probecast_encode_cache_bytes");
    result.encodeCacheBoundMb = mb("probecast_encode_cache_bound_bytes");
    result.historyMb = mb("probecast_brick_history_bytes");
    result.historyBoundMb = mb("probecast_brick_history_bound_bytes");
    result.currentBricksMb = mb("probecast_current_bricks_bytes");
    result.changeCacheMb = mb("probecast_change_cache_bytes");
  } else {
    result.metricsError = m.error().message;
  }
  const double selfCpu1 = selfCpuSeconds();
  result.report = gen.report();
  result.fieldUpdatesPerS = double(gen.snapshot().newestFieldVersion - version0) / window;
  if (!end) return end.error();
  result.rssEndMb = end->rssMb;
  result.fdsEnd = end->openFds;
  result.serverCpuMsPerS = (end->cpuSeconds - warm->cpuSeconds) * 1e3 / window;
  result.netCpuMsPerS = (end->threadCpu("pc-net") - warm->threadCpu("pc-net")) * 1e3 / window;
  result.fieldCpuMsPerS = (end->threadCpu("pc-field") - warm->threadCpu("pc-field")) * 1e3 / window;
  result.cpuMsPerClientS = result.netCpuMsPerS / double(lo.clients);
  result.processCpuMsPerClientS =
      (result.serverCpuMsPerS - result.serverIdleCpuMsPerS) / double(lo.clients);
  result.loadgenCpuMsPerS = (selfCpu1 - selfCpu0) * 1e3 / window;
  gen.stop();
  Status exit = (*server)->stop();
  if (!exit) result.serverExit = exit.error().message;
  return result;
}

}  // namespace pc::load
