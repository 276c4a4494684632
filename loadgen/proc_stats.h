// What /proc says about a process (Linux): CPU time, resident memory, open file descriptors.
// The load benchmark and the soak test read the server's figures this way, so they measure
// the real probecast-server process and nothing of their own.
#pragma once

#include <sys/types.h>

#include "common/result.h"

namespace pc::load {

struct ProcStats {
  double cpuSeconds = 0;  // user + system, all threads
  double rssMb = 0;       // VmRSS
  int openFds = 0;        // entries of /proc/<pid>/fd
};

Result<ProcStats> readProcStats(pid_t pid);

}  // namespace pc::load
