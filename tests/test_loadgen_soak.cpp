// Soak: clients connect and disconnect over and over against a probecast-server process; its
// open file descriptors must come back to their baseline exactly, its resident memory within
// a small tolerance (the allocator keeps some freed pages). Labelled `soak` in CTest. By
// default 500 connects (the CI run); PC_SOAK_CONNECTS=10000 for the full soak.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>

#include "loadgen/load_generator.h"
#include "loadgen/proc_stats.h"
#include "loadgen/server_load.h"
#include "loadgen/server_process.h"
#include "protocol/connect_token.h"

namespace pc {
namespace {

// The soak's token issuer (fixed: a test key) and one token per client.
const KeyPair& soakKeys() {
  static const KeyPair keys = keyPairFromSeed({42});
  return keys;
}
std::vector<std::string> soakTokens(int clients) {
  const std::int64_t now = unixSeconds();
  std::vector<std::string> tokens;
  for (int i = 0; i < clients; ++i) {
    tokens.push_back(issueToken(soakKeys().signing, newTokenClaims("soak-" + std::to_string(i), "*",
                                                                   TokenRole::Viewer, 1, now, 3600))
                         .value());
  }
  return tokens;
}
// Resident memory the server may keep after the soak beyond its baseline: freed session
// buffers that the allocator holds on to rather than returning to the system.
constexpr double kRssToleranceMb = 8.0;

void sleepSeconds(double s) { std::this_thread::sleep_for(std::chrono::duration<double>(s)); }

std::uint64_t soakConnects() {
  if (const char* env = std::getenv("PC_SOAK_CONNECTS")) return std::strtoull(env, nullptr, 10);
  return 500;
}

// Runs `sessions` short sessions from `clients` clients at once; returns the generator's
// error count.
std::uint64_t churn(const load::ServerProcess& server, int clients, std::uint64_t sessions) {
  load::LoadOptions o;
  o.port = server.port();
  o.serverFingerprint = server.tlsFingerprint();
  o.clientTokens = soakTokens(clients);
  o.clients = clients;
  o.rampSeconds = 0.2;
  o.sessionSeconds = 0.3;
  o.sessionJitter = 0.6;
  o.rejoinDelay = 0.01;
  o.maxSessions = sessions;
  auto gen = load::LoadGenerator::create(o);
  EXPECT_TRUE(gen.ok());
  if (!gen) return 1;
  (*gen)->start();
  double lastPrint = 0;
  for (double t = 0;; t += 0.05) {
    const load::LoadSnapshot s = (*gen)->snapshot();
    if (s.sessionsStarted >= sessions && s.sessionsEnded >= s.sessionsStarted) break;
    if (t - lastPrint >= 5.0) {
      lastPrint = t;
      std::printf("  %llu sessions started, %llu ended, %llu errors\n",
                  (unsigned long long)s.sessionsStarted, (unsigned long long)s.sessionsEnded,
                  (unsigned long long)s.errors);
    }
    if (t > 60.0 + double(sessions) * 0.05) {
      ADD_FAILURE() << "sessions did not finish: " << s.sessionsEnded << " of " << sessions;
      break;
    }
    sleepSeconds(0.05);
  }
  const load::LoadReport r = (*gen)->report();
  (*gen)->stop();
  for (const std::string& e : r.errorSamples) std::printf("  error: %s\n", e.c_str());
  return r.errors;
}

TEST(LoadgenSoak, ServerFileDescriptorsAndMemoryReturnToBaselineAfterConnectCycles) {
  load::raiseFileLimit();
  load::ServerProcessOptions sp;
  sp.executable = std::string(PC_BUILD_DIR) + "/bin/probecast-server";
  sp.logPath = std::string(PC_BUILD_DIR) + "/test_loadgen_soak_server.log";
  // The field freezes after 1 s of animation: no new versions, so the server's shared caches
  // stop growing and what remains is per-session state.
  const std::string keyFile = std::string(PC_BUILD_DIR) + "/test_loadgen_soak.verify-key";
  ASSERT_TRUE(writeKeyFile(keyFile, soakKeys().verify).ok());
  sp.args = {"--scene", "builtin", "--bind", "127.0.0.1", "--port", "0", "--token-key", keyFile,
             "--dev-self-signed", "--rays", "16", "--warmup", "2", "--rate", "10", "--freeze-at",
             "1.0", "--max-clients", "200", "--stats-interval", "0",
             // The soak's clients all come from one address: its caps would turn most away.
             "--max-pending-per-address", "0", "--max-sessions-per-address", "0",
             "--handshakes-per-second-per-address", "0"};
  auto server = load::ServerProcess::start(sp);
  ASSERT_TRUE(server.ok()) << server.error().message;
  const pid_t pid = (*server)->pid();
  sleepSeconds(1.5);  // past the freeze

  // Warm-up round of the same shape as the soak (50 clients at a time): the first sessions
  // fill the encode cache, and the allocator's pools grow to the soak's peak concurrency.
  EXPECT_EQ(churn(**server, 50, 200), 0u);
  sleepSeconds(1.0);
  auto base = load::readProcStats(pid);
  ASSERT_TRUE(base.ok()) << base.error().message;

  const std::uint64_t connects = soakConnects();
  std::printf("soak: %llu connects, 50 clients at a time; baseline %d fds, %.1f MB resident\n",
              (unsigned long long)connects, base->openFds, base->rssMb);
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(churn(**server, 50, connects), 0u);
  const double took =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  // The server notices closed connections within its poll; give it a moment.
  Result<load::ProcStats> after = Error{};
  for (int i = 0; i < 50; ++i) {
    after = load::readProcStats(pid);
    ASSERT_TRUE(after.ok()) << after.error().message;
    if (after->openFds == base->openFds) break;
    sleepSeconds(0.1);
  }
  std::printf(
      "soak: %.1f s; after: %d fds (baseline %d), %.1f MB resident (baseline %.1f, "
      "%+.2f MB)\n",
      took, after->openFds, base->openFds, after->rssMb, base->rssMb, after->rssMb - base->rssMb);
  EXPECT_EQ(after->openFds, base->openFds);
  EXPECT_LE(after->rssMb - base->rssMb, kRssToleranceMb);
  EXPECT_TRUE((*server)->stop().ok());
}

}  // namespace
}  // namespace pc
