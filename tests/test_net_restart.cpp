// The real executables: probecast-server and the headless probecast-client (lavapipe, a tiny
// image) over loopback. The server is killed mid-stream (SIGKILL: no goodbye) and restarted on
// the same port; the client must keep rendering through the outage, reconnect and resync. And
// a server whose GPU fails mid-stream goes on updating on the CPU, its client still in session.
// The client's live summary file tells the test what it is doing.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>

#include <boost/asio.hpp>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "net/tls_certificate.h"
#include "protocol/connect_token.h"
#include "test_child_process.h"

namespace {

using pc::test::canConnect;
using pc::test::Child;
using pc::test::freePort;

namespace fs = std::filesystem;
const std::string kBin = std::string(PC_BUILD_DIR) + "/bin/";

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

nlohmann::json readSummary(const fs::path& p) {
  std::ifstream in(p);
  if (!in) return {};
  try {
    return nlohmann::json::parse(in);
  } catch (const std::exception&) {
    return {};
  }
}

// A field of the summary, or `otherwise` while the file is missing or partial.
template <typename T>
T field(const nlohmann::json& j, const char* key, T otherwise) {
  if (!j.is_object() || !j.contains(key)) return otherwise;
  return j[key].get<T>();
}

std::string readText(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// What a server and its clients need to meet: a token issuer's verify key, a token it signed
// (and one signed by a stranger), and a TLS certificate with its key that the client trusts as
// its CA file. The certificate lives in files, so a restarted server presents the same one.
struct Credentials {
  explicit Credentials(const fs::path& dir)
      : verifyKey((dir / "issuer.pub").string()),
        token((dir / "client.token").string()),
        wrongToken((dir / "stranger.token").string()),
        cert((dir / "cert.pem").string()),
        key((dir / "key.pem").string()) {
    const pc::KeyPair issuer = pc::generateKeyPair(), stranger = pc::generateKeyPair();
    EXPECT_TRUE(pc::writeKeyFile(verifyKey, issuer.verify).ok());
    const std::int64_t now = pc::unixSeconds();
    const pc::TokenClaims claims =
        pc::newTokenClaims("restart-client", "*", pc::TokenRole::Viewer, 1, now, 3600);
    std::ofstream(token) << pc::issueToken(issuer.signing, claims).value() << "\n";
    std::ofstream(wrongToken) << pc::issueToken(stranger.signing, claims).value() << "\n";
    auto dev = pc::net::makeDevCertificate();
    EXPECT_TRUE(dev.ok());
    std::ofstream(cert) << dev->certificatePem;
    std::ofstream(key) << dev->keyPem;
  }
  std::string verifyKey, token, wrongToken, cert, key;
};

template <typename F>
bool waitUntil(F&& done, double limit) {
  const double start = now();
  while (!done()) {
    if (now() - start > limit) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return true;
}

// A headless client whose token the server refuses renders its frames, then exits with 4 and
// an error naming the reject, not 0.
TEST(NetRestart, HeadlessClientThatIsAlwaysRejectedExitsWithFour) {
  if (!fs::exists(kBin + "probecast-server") || !fs::exists(kBin + "probecast-client"))
    GTEST_SKIP() << "probecast-server and probecast-client are not built";
  const fs::path dir = fs::path(PC_BUILD_DIR) / "test-net-rejected";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const Credentials creds(dir);
  const std::uint16_t port = freePort();
  const std::string portText = std::to_string(port);
  Child server({kBin + "probecast-server",
                "--scene",
                "builtin",
                "--backend",
                "embree",
                "--rays",
                "16",
                "--warmup",
                "1",
                "--bind",
                "127.0.0.1",
                "--port",
                portText,
                "--token-key",
                creds.verifyKey,
                "--tls-cert",
                creds.cert,
                "--tls-key",
                creds.key,
                "--stats-interval",
                "0"},
               dir / "server.log");
  ASSERT_TRUE(server.running());
  ASSERT_TRUE(waitUntil([&] { return canConnect(port); }, 30.0)) << "server never listened";
  Child client({kBin + "probecast-client",
                "--scene",
                "builtin",
                "--connect",
                "127.0.0.1:" + portText,
                "--token-file",
                creds.wrongToken,
                "--ca-file",
                creds.cert,
                "--width",
                "32",
                "--height",
                "24",
                "--msaa",
                "2",
                "--duration",
                "2",
                "--save-every",
                "0",
                "--no-exr",
                "--out",
                dir.string()},
               dir / "client.log");
  ASSERT_TRUE(client.running());
  ASSERT_TRUE(waitUntil([&] { return client.exited(); }, 60.0)) << "the client did not end";
  EXPECT_EQ(client.exitCode(), 4) << readText(dir / "client.log");
  EXPECT_NE(readText(dir / "client.log").find("the server rejected all"), std::string::npos)
      << readText(dir / "client.log");
}

TEST(NetRestart, HeadlessClientKeepsRenderingReconnectsAndResyncs) {
  if (!fs::exists(kBin + "probecast-server") || !fs::exists(kBin + "probecast-client"))
    GTEST_SKIP() << "probecast-server and probecast-client are not built";
  const fs::path dir = fs::path(PC_BUILD_DIR) / "test-net-restart";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const Credentials creds(dir);
  const std::uint16_t port = freePort();
  const std::string portText = std::to_string(port);
  auto serverArgs = [&] {
    return std::vector<std::string>{kBin + "probecast-server",
                                    "--scene",
                                    "builtin",
                                    "--backend",
                                    "embree",
                                    "--rays",
                                    "32",
                                    "--warmup",
                                    "4",
                                    "--rate",
                                    "10",
                                    "--bind",
                                    "127.0.0.1",
                                    "--port",
                                    portText,
                                    "--token-key",
                                    creds.verifyKey,
                                    "--tls-cert",
                                    creds.cert,
                                    "--tls-key",
                                    creds.key,
                                    "--stats-interval",
                                    "0"};
  };
  auto server = std::make_unique<Child>(serverArgs(), dir / "server.log");
  ASSERT_TRUE(server->running());
  ASSERT_TRUE(waitUntil([&] { return canConnect(port); }, 30.0)) << "server never listened";

  const fs::path summary = dir / "client.json";
  Child client({kBin + "probecast-client",
                "--scene",
                "builtin",
                "--connect",
                "127.0.0.1:" + portText,
                "--token-file",
                creds.token,
                "--ca-file",
                creds.cert,
                "--width",
                "48",
                "--height",
                "32",
                "--msaa",
                "2",
                "--duration",
                "120",
                "--save-every",
                "0",
                "--no-exr",
                "--max-fps",
                "30",
                "--out",
                dir.string(),
                "--summary",
                summary.string()},
               dir / "client.log");
  ASSERT_TRUE(client.running());
  nlohmann::json s;
  ASSERT_TRUE(waitUntil(
      [&] {
        s = readSummary(summary);
        return field(s, "synced", false) && field(s, "frames", 0) > 2;
      },
      60.0))
      << "the client never synced; see " << (dir / "client.log");

  // Kill the server mid-stream.
  server->kill(SIGKILL);
  const int framesAtKill = field(readSummary(summary), "frames", 0);
  ASSERT_TRUE(waitUntil(
      [&] {
        s = readSummary(summary);
        return !field(s, "connected", true);
      },
      10.0))
      << "the client never noticed the server had gone";
  // The client renders on without a server.
  ASSERT_TRUE(waitUntil(
      [&] {
        s = readSummary(summary);
        return field(s, "frames_while_disconnected", 0) >= 3;
      },
      20.0));
  EXPECT_GT(field(s, "frames", 0), framesAtKill);

  // The same port again.
  server = std::make_unique<Child>(serverArgs(), dir / "server2.log");
  ASSERT_TRUE(waitUntil([&] { return canConnect(port); }, 30.0)) << "server never listened again";
  const double back = now();
  const bool resynced = waitUntil(
      [&] {
        s = readSummary(summary);
        return field(s, "sessions", 0) >= 2 && field(s, "synced", false);
      },
      30.0);
  const double resync = now() - back;
  ASSERT_TRUE(resynced) << "no resync after the restart; see " << (dir / "client.log");
  std::printf(
      "resynced %.2f s after the restarted server listened (client: %.3f s from connect "
      "to every brick held; status polled every 0.25 s)\n",
      resync, field(s, "last_resync_seconds", -1.0));
  const int framesAfter = field(s, "frames", 0);
  ASSERT_TRUE(
      waitUntil([&] { return field(readSummary(summary), "frames", 0) > framesAfter + 2; }, 20.0));
  client.kill(SIGTERM);
  server->kill(SIGTERM);
}

// The server's GPU (lavapipe here) fails mid-stream as a lost device would
// (--gpu-fail-submission): the server logs the failure, its field thread goes on with Embree
// from the last completed field, and the client, still in its first session, keeps receiving
// new versions.
// A warm-up bake of a large scene can take minutes on the CPU: SIGTERM must end it between
// updates, not wait for it (here a warm-up of a million updates, which would take hours).
TEST(NetRestart, ServerStopsOnSigtermDuringItsWarmUp) {
  if (!fs::exists(kBin + "probecast-server")) GTEST_SKIP() << "probecast-server is not built";
  const fs::path dir = fs::path(PC_BUILD_DIR) / "test-net-warm-up-signal";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const Credentials creds(dir);
  const fs::path log = dir / "server.log";
  std::vector<std::string> args = {kBin + "probecast-server", "--port", std::to_string(freePort())};
  for (const std::string& a : std::initializer_list<std::string>{
           "--scene", "builtin", "--backend", "embree", "--rays", "64", "--warmup", "1000000",
           "--bind", "127.0.0.1", "--token-key", creds.verifyKey, "--tls-cert", creds.cert,
           "--tls-key", creds.key, "--stats-interval", "0"})
    args.push_back(a);
  Child server(args, log);
  ASSERT_TRUE(server.running());
  ASSERT_TRUE(waitUntil(
      [&] {
        return readText(log).find("warm-up: 1000000 updates") != std::string::npos ||
               server.exited();
      },
      60.0))
      << readText(log);
  ASSERT_FALSE(server.exited()) << readText(log);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // into the updates
  server.signal(SIGTERM);
  EXPECT_TRUE(waitUntil([&] { return server.exited(); }, 30.0)) << readText(log);
  EXPECT_EQ(server.exitCode(), 0);
  const std::string text = readText(log);
  EXPECT_NE(text.find("shutting down (SIGTERM) during the warm-up"), std::string::npos) << text;
  EXPECT_EQ(text.find("ready port"), std::string::npos) << text;
}

// With --log-format json the periodic statistics are one JSON object a line whose figures are
// members of their own (numbers as numbers), not a text line inside the message: a log
// collector reads clients, bandwidth and the field thread's figures without parsing prose.
TEST(NetRestart, ServerStatisticsAreJsonFieldsInAJsonLog) {
  if (!fs::exists(kBin + "probecast-server")) GTEST_SKIP() << "probecast-server is not built";
  const fs::path dir = fs::path(PC_BUILD_DIR) / "test-net-json-statistics";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const Credentials creds(dir);
  const fs::path log = dir / "server.log";
  std::vector<std::string> args = {kBin + "probecast-server", "--port", std::to_string(freePort())};
  for (const std::string& a :
       std::initializer_list<std::string>{"--scene",          "builtin",
                                          "--backend",        "embree",
                                          "--rays",           "16",
                                          "--warmup",         "1",
                                          "--rate",           "5",
                                          "--bind",           "127.0.0.1",
                                          "--token-key",      creds.verifyKey,
                                          "--tls-cert",       creds.cert,
                                          "--tls-key",        creds.key,
                                          "--stats-interval", "0.5",
                                          "--log-format",     "json",
                                          "--duration",       "4"})
    args.push_back(a);
  Child server(args, log);
  ASSERT_TRUE(server.running());
  ASSERT_TRUE(waitUntil([&] { return server.exited(); }, 120.0)) << readText(log);
  EXPECT_EQ(server.exitCode(), 0) << readText(log);

  std::istringstream lines(readText(log));
  std::string line;
  int records = 0;
  while (std::getline(lines, line)) {
    // stdout's announcements ("ready port N") are for scripts, not the log.
    if (line.empty() || line[0] != '{') continue;
    nlohmann::json j;
    ASSERT_NO_THROW(j = nlohmann::json::parse(line)) << "not a JSON line: " << line;
    if (j.value("msg", "") != "statistics") continue;
    ++records;
    for (const char* number : {"interval_s", "clients", "sent_kbit_s", "received_kbit_s",
                               "update_latency_mean_ms", "field_version", "accepted_total",
                               "animation_time_s", "field_updates_total", "last_update_ms"})
      EXPECT_TRUE(j.contains(number) && j[number].is_number()) << number << " in " << line;
    EXPECT_EQ(j["clients"], 0) << line;
    EXPECT_NEAR(j["interval_s"].get<double>(), 0.5, 0.3) << line;
    EXPECT_EQ(j.value("tracer", ""), "embree") << line;
  }
  EXPECT_GE(records, 3) << readText(log);
  // The text line is the text log's alone.
  EXPECT_EQ(readText(log).find("clients 0 |"), std::string::npos);
}

TEST(NetRestart, ServerGoesOnOnTheCpuWhenItsGpuFails) {
  if (!fs::exists(kBin + "probecast-server") || !fs::exists(kBin + "probecast-client"))
    GTEST_SKIP() << "probecast-server and probecast-client are not built";
  const fs::path dir = fs::path(PC_BUILD_DIR) / "test-net-gpu-failure";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const Credentials creds(dir);
  const std::uint16_t port = freePort();
  const std::string portText = std::to_string(port);
  const fs::path serverLog = dir / "server.log";
  // Two warm-up updates, then the field thread's updates at 10 a second: the 150th submission
  // fails about 15 s after the server listens (later on busy cores), with the client synced
  // long before (about 0.1 s after it connects, here).
  std::vector<std::string> args = {kBin + "probecast-server", "--port", portText};
  for (const std::string& a : std::initializer_list<std::string>{"--scene",
                                                                 "builtin",
                                                                 "--backend",
                                                                 "vulkan",
                                                                 "--rays",
                                                                 "32",
                                                                 "--warmup",
                                                                 "2",
                                                                 "--rate",
                                                                 "10",
                                                                 "--gpu-fail-submission",
                                                                 "150",
                                                                 "--bind",
                                                                 "127.0.0.1",
                                                                 "--token-key",
                                                                 creds.verifyKey,
                                                                 "--tls-cert",
                                                                 creds.cert,
                                                                 "--tls-key",
                                                                 creds.key,
                                                                 "--stats-interval",
                                                                 "0"})
    args.push_back(a);
  Child server(args, serverLog);
  ASSERT_TRUE(server.running());
  ASSERT_TRUE(waitUntil([&] { return canConnect(port) || server.exited(); }, 60.0));
  if (!canConnect(port)) {
    const std::string log = readText(serverLog);
    if (log.find("no Vulkan") != std::string::npos)
      GTEST_SKIP() << "no Vulkan ray-tracing device: " << log;
    FAIL() << "the server never listened: " << log;
  }
  const fs::path summary = dir / "client.json";
  Child client({kBin + "probecast-client",
                "--scene",
                "builtin",
                "--connect",
                "127.0.0.1:" + portText,
                "--token-file",
                creds.token,
                "--ca-file",
                creds.cert,
                "--width",
                "48",
                "--height",
                "32",
                "--msaa",
                "2",
                "--duration",
                "120",
                "--save-every",
                "0",
                "--no-exr",
                "--max-fps",
                "30",
                "--out",
                dir.string(),
                "--summary",
                summary.string()},
               dir / "client.log");
  ASSERT_TRUE(client.running());
  nlohmann::json s;
  ASSERT_TRUE(waitUntil([&] { return field(readSummary(summary), "synced", false); }, 60.0))
      << "the client never synced; see " << (dir / "client.log");
  ASSERT_EQ(readText(serverLog).find("VK_ERROR_DEVICE_LOST"), std::string::npos)
      << "the GPU failed before the client synced: the drill comes too early for this machine";

  ASSERT_TRUE(waitUntil(
      [&] { return readText(serverLog).find("go on with the embree") != std::string::npos; }, 60.0))
      << "no failure and fallback in " << serverLog << ":\n"
      << readText(serverLog);
  const std::string log = readText(serverLog);
  EXPECT_NE(log.find("vkQueueSubmit failed: VK_ERROR_DEVICE_LOST"), std::string::npos) << log;
  s = readSummary(summary);
  const auto versionAtFailure = field(s, "server_field_version", std::uint64_t(0));
  const auto appliedAtFailure = field(s, "bricks_applied", std::uint64_t(0));
  // New versions from the CPU reach the client, in the same session.
  ASSERT_TRUE(waitUntil(
      [&] {
        s = readSummary(summary);
        return field(s, "server_field_version", std::uint64_t(0)) >= versionAtFailure + 5 &&
               field(s, "bricks_applied", std::uint64_t(0)) > appliedAtFailure;
      },
      60.0))
      << "no new versions after the failure; see " << (dir / "client.log");
  EXPECT_EQ(field(s, "sessions", 0), 1);
  EXPECT_TRUE(field(s, "connected", false));
  EXPECT_FALSE(server.exited()) << readText(serverLog);
  client.kill(SIGTERM);
  server.kill(SIGTERM);
}

}  // namespace
