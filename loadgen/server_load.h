// One load measurement against a probecast-server process on this host: start the server,
// measure its idle CPU (the field thread alone), let the clients join and warm up, then
// measure a window. Server CPU, resident memory and open descriptors come from /proc/<pid>.
// Used by `probecast-bench load` and the load tests.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "load_generator.h"

namespace pc::load {

struct ServerLoadOptions {
  std::string serverExecutable;         // probecast-server
  std::vector<std::string> serverArgs;  // besides --scene builtin, --bind, --port, --token-key
  std::string serverLog = "/dev/null";
  LoadOptions load;            // host, port, tokens and fingerprint are filled in
  double idleSeconds = 2.0;    // server CPU without clients, measured before they join
  double joinLimit = 60.0;     // s after the ramp for every client to hold every brick
  double warmupSeconds = 2.0;  // after every client is synced
  double seconds = 10.0;       // the measured window
  // > 0: every server thread but the network thread ("pc-net") gets this nice value once the
  // server is ready (the field thread and the tracer's worker threads), so that on a machine
  // whose cores the server shares with the clients, tracing yields to serving. 0 leaves them.
  int fieldNice = 0;
};

struct ServerLoadResult {
  LoadReport report;
  bool allSynced = false;          // every client held every brick before the window
  double joinSeconds = 0;          // from start to all synced
  double serverIdleCpuMsPerS = 0;  // whole process, no clients (field thread, tracer workers)
  double netIdleCpuMsPerS = 0;     // the network thread ("pc-net"), no clients
  double serverCpuMsPerS = 0;      // whole process, during the window
  double netCpuMsPerS = 0;         // the network thread, during the window
  double fieldCpuMsPerS = 0;       // the field thread ("pc-field"), during the window
  double fieldUpdatesPerS = 0;     // field versions published during the window (clients saw)
  // Network thread in the window / clients: what serving one client costs the server per
  // second. The idle figure is not subtracted: /proc counts thread CPU in 10 ms ticks, so a
  // short idle measurement of a nearly idle thread is mostly rounding (it is printed instead). The
  // network thread does all per-client work (sender polls, sends, session messages); the field
  // thread's work does not depend on the client count and its CPU varies with what the two shared
  // cores give it, so it is left out.
  double cpuMsPerClientS = 0;
  // (whole process in the window - whole process idle) / clients: includes that variation.
  double processCpuMsPerClientS = 0;
  double loadgenCpuMsPerS = 0;         // this process during the window
  double rssWarmMb = 0, rssEndMb = 0;  // server, after the warm-up and at the window's end
  int fdsWarm = 0, fdsEnd = 0;
  // The server's own memory gauges at the window's end (its /metrics), MB: encoded updates,
  // brick history beyond the current versions and its bound, current brick versions, shared
  // perceptual comparisons. Negative when /metrics could not be read.
  double encodeCacheMb = -1, encodeCacheBoundMb = -1, historyMb = -1, historyBoundMb = -1;
  double currentBricksMb = -1, changeCacheMb = -1;
  std::string metricsError;  // why they could not be read
  std::string serverExit;    // empty when it exited cleanly on SIGTERM
};

// `progress` gets a line now and then (may be null).
Result<ServerLoadResult> runServerLoad(const ServerLoadOptions& options,
                                       const std::function<void(const std::string&)>& progress);

// Raises the soft open-file limit to the hard one (children inherit it): each client holds a
// TCP and a UDP socket, and the server one TCP socket per client.
void raiseFileLimit();

}  // namespace pc::load
