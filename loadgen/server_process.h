// A probecast-server child process for the load benchmark and the load tests: started with
// given arguments, its "ready port N" line awaited, then stopped with SIGTERM (SIGKILL if it
// does not exit in time). Its stderr (the log) goes to a file, so a thousand join lines never
// reach the terminal.
#pragma once

#include <sys/types.h>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "common/result.h"

namespace pc::load {

struct ServerProcessOptions {
  std::string executable;         // path of probecast-server
  std::vector<std::string> args;  // should include --port 0 and --token-key
  std::string logPath = "/dev/null";
  double readyTimeout = 120.0;  // s for the warm-up bake and the listener
};

class ServerProcess {
 public:
  static Result<std::unique_ptr<ServerProcess>> start(const ServerProcessOptions& options);
  ~ServerProcess();  // stop()
  ServerProcess(const ServerProcess&) = delete;
  ServerProcess& operator=(const ServerProcess&) = delete;

  pid_t pid() const { return pid_; }
  std::uint16_t port() const { return port_; }
  // The server's TLS certificate fingerprint ("sha256:<hex>"); empty when it runs without TLS.
  const std::string& tlsFingerprint() const { return fingerprint_; }
  // SIGTERM, then SIGKILL after `timeout` s. The exit status (or an Error naming the signal
  // or a non-zero code). Idempotent.
  Status stop(double timeout = 10.0);

 private:
  ServerProcess(pid_t pid, int out, std::uint16_t port) : pid_(pid), stdout_(out), port_(port) {}
  pid_t pid_ = -1;
  int stdout_ = -1;
  std::uint16_t port_ = 0;
  std::string fingerprint_;
  Status exit_;
};

// probecast-server beside the running executable (both live in build/bin).
std::string siblingExecutable(const std::string& name);

}  // namespace pc::load
