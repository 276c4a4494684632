// The real executables: probecast-server and the headless probecast-client (lavapipe, a tiny
// image) over loopback. The server is killed mid-stream (SIGKILL: no goodbye) and restarted on
// the same port; the client must keep rendering through the outage, reconnect and resync.
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
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace {

namespace fs = std::filesystem;
const std::string kBin = std::string(PC_BUILD_DIR) + "/bin/";

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// A child process, killed (SIGKILL) and reaped when the handle goes.
class Child {
 public:
  Child(std::vector<std::string> args, const fs::path& log) {
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
    posix_spawn_file_actions_adddup2(&actions, 1, 2);
    if (posix_spawn(&pid_, argv[0], &actions, nullptr, argv.data(), environ) != 0) pid_ = -1;
    posix_spawn_file_actions_destroy(&actions);
  }
  ~Child() { kill(SIGKILL); }
  bool running() const { return pid_ > 0; }
  void kill(int sig) {
    if (pid_ <= 0) return;
    ::kill(pid_, sig);
    int status = 0;
    waitpid(pid_, &status, 0);
    pid_ = -1;
  }

 private:
  pid_t pid_ = -1;
};

std::uint16_t freePort() {
  boost::asio::io_context io;
  boost::asio::ip::tcp::acceptor a(io, {boost::asio::ip::make_address("127.0.0.1"), 0});
  return a.local_endpoint().port();
}

bool canConnect(std::uint16_t port) {
  boost::asio::io_context io;
  boost::asio::ip::tcp::socket s(io);
  boost::system::error_code ec;
  s.connect({boost::asio::ip::make_address("127.0.0.1"), port}, ec);
  return !ec;
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

template <typename F>
bool waitUntil(F&& done, double limit) {
  const double start = now();
  while (!done()) {
    if (now() - start > limit) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return true;
}

TEST(NetRestart, HeadlessClientKeepsRenderingReconnectsAndResyncs) {
  if (!fs::exists(kBin + "probecast-server") || !fs::exists(kBin + "probecast-client"))
    GTEST_SKIP() << "probecast-server and probecast-client are not built";
  const fs::path dir = fs::path(PC_BUILD_DIR) / "test-net-restart";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::uint16_t port = freePort();
  const std::string portText = std::to_string(port);
  auto serverArgs = [&] {
    return std::vector<std::string>{kBin + "probecast-server", "--scene", "builtin", "--backend",
                                     "embree", "--rays", "32", "--warmup", "4", "--rate", "10",
                                     "--bind", "127.0.0.1", "--port", portText, "--token",
                                     "restart-token", "--stats-interval", "0"};
  };
  auto server = std::make_unique<Child>(serverArgs(), dir / "server.log");
  ASSERT_TRUE(server->running());
  ASSERT_TRUE(waitUntil([&] { return canConnect(port); }, 30.0)) << "server never listened";

  const fs::path summary = dir / "client.json";
  Child client({kBin + "probecast-client", "--scene", "builtin", "--connect",
                "127.0.0.1:" + portText, "--token", "restart-token", "--width", "48", "--height",
                "32", "--msaa", "2", "--duration", "120", "--save-every", "0", "--no-exr",
                "--max-fps", "30", "--out", dir.string(), "--summary", summary.string()},
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
  std::printf("resynced %.2f s after the restarted server listened (client: %.3f s from connect "
              "to every brick held; status polled every 0.25 s)\n",
              resync, field(s, "last_resync_seconds", -1.0));
  const int framesAfter = field(s, "frames", 0);
  ASSERT_TRUE(waitUntil([&] { return field(readSummary(summary), "frames", 0) > framesAfter + 2; }, 20.0));
  client.kill(SIGTERM);
  server->kill(SIGTERM);
}

}  // namespace
