// What /proc says about a process (Linux): CPU time, resident memory, open file descriptors.
// The load benchmark and the soak test read the server's figures this way, so they measure
// the real probecast-server process and nothing of their own.
#pragma once

#include <sys/types.h>

#include <map>
#include <string>

#include "common/result.h"

namespace pc::load {

struct ProcStats {
  double cpuSeconds = 0;  // user + system, all threads
  double rssMb = 0;       // VmRSS
  int openFds = 0;        // entries of /proc/<pid>/fd
  // CPU seconds by thread name (/proc/<pid>/task/<tid>/comm; threads of one name summed).
  // probecast-server names its network thread "pc-net" and its field thread "pc-field".
  std::map<std::string, double> threadCpuSeconds;
  double threadCpu(const std::string& name) const {
    auto it = threadCpuSeconds.find(name);
    return it == threadCpuSeconds.end() ? 0.0 : it->second;
  }
};

Result<ProcStats> readProcStats(pid_t pid);

}  // namespace pc::load
