#include "server_process.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <thread>

extern char** environ;

namespace pc::load {

namespace {

double nowSeconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace

std::string siblingExecutable(const std::string& name) {
  std::error_code ec;
  const auto self = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec) return name;
  return (self.parent_path() / name).string();
}

Result<std::unique_ptr<ServerProcess>> ServerProcess::start(const ServerProcessOptions& options) {
  // The log is opened here, not by the spawn: a spawn that fails to open it reports the error
  // as its own, which read as though the server's executable were missing.
  const int logFd = open(options.logPath.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (logFd < 0) {
    return Error{"cannot open the server's log " + options.logPath + ": " + std::strerror(errno)};
  }
  int pipeFds[2];
  if (pipe2(pipeFds, O_CLOEXEC) != 0) {
    const int err = errno;
    close(logFd);
    return Error{std::string("pipe: ") + std::strerror(err)};
  }
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, pipeFds[1], STDOUT_FILENO);
  posix_spawn_file_actions_adddup2(&actions, logFd, STDERR_FILENO);
  std::vector<std::string> argv = {options.executable};
  argv.insert(argv.end(), options.args.begin(), options.args.end());
  std::vector<char*> cargv;
  for (std::string& a : argv) cargv.push_back(a.data());
  cargv.push_back(nullptr);
  pid_t pid = -1;
  const int rc =
      posix_spawn(&pid, options.executable.c_str(), &actions, nullptr, cargv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  close(pipeFds[1]);
  close(logFd);
  if (rc != 0) {
    close(pipeFds[0]);
    return Error{"cannot start " + options.executable + ": " + std::strerror(rc)};
  }
  std::unique_ptr<ServerProcess> server(new ServerProcess(pid, pipeFds[0], 0));

  // Wait for "ready port N" on its stdout.
  std::string out;
  const double deadline = nowSeconds() + options.readyTimeout;
  while (true) {
    const std::size_t at = out.find("ready port ");
    const std::size_t end = at == std::string::npos ? at : out.find('\n', at);
    if (end != std::string::npos) {
      server->port_ = std::uint16_t(std::stoul(out.substr(at + 11, end - at - 11)));
      // The certificate to pin, printed before the ready line (none without TLS).
      const std::size_t tls = out.find("tls-fingerprint ");
      const std::size_t tlsEnd = tls == std::string::npos ? tls : out.find('\n', tls);
      if (tlsEnd != std::string::npos && tlsEnd < at)
        server->fingerprint_ = out.substr(tls + 16, tlsEnd - tls - 16);
      return server;
    }
    const double left = deadline - nowSeconds();
    if (left <= 0) {
      return Error{options.executable + " printed no 'ready port' line within " +
                   std::to_string(int(options.readyTimeout)) + " s (log: " + options.logPath + ")"};
    }
    pollfd p{server->stdout_, POLLIN, 0};
    if (::poll(&p, 1, int(std::min(left, 0.2) * 1000)) < 0 && errno != EINTR)
      return Error{std::string("poll: ") + std::strerror(errno)};
    if (p.revents & (POLLIN | POLLHUP)) {
      char buf[256];
      const ssize_t n = read(server->stdout_, buf, sizeof buf);
      if (n > 0) out.append(buf, std::size_t(n));
      if (n == 0) {
        return Error{options.executable + " exited before it was ready (log: " + options.logPath +
                     ")"};
      }
    }
  }
}

Status ServerProcess::stop(double timeout) {
  if (pid_ <= 0) return exit_;
  kill(pid_, SIGTERM);
  int status = 0;
  const double deadline = nowSeconds() + timeout;
  pid_t done = 0;
  while ((done = waitpid(pid_, &status, WNOHANG)) == 0 && nowSeconds() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  if (done == 0) {
    kill(pid_, SIGKILL);
    waitpid(pid_, &status, 0);
    exit_ = Error{"the server did not exit within " + std::to_string(timeout) + " s of SIGTERM"};
  } else if (WIFSIGNALED(status)) {
    exit_ = Error{std::string("the server died of signal ") + strsignal(WTERMSIG(status))};
  } else if (WIFEXITED(status) && WEXITSTATUS(status) != 0) {
    exit_ = Error{"the server exited with code " + std::to_string(WEXITSTATUS(status))};
  }
  pid_ = -1;
  if (stdout_ >= 0) close(stdout_);
  stdout_ = -1;
  return exit_;
}

ServerProcess::~ServerProcess() { (void)stop(); }

}  // namespace pc::load
