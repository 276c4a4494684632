#include "proc_stats.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace pc::load {

namespace {

// utime + stime of a /proc/.../stat file in seconds. The command name (field 2) may hold
// spaces, so fields are counted from its closing parenthesis; utime and stime are fields 14
// and 15, in clock ticks.
Result<double> statCpuSeconds(const std::string& path) {
  std::ifstream statFile(path);
  std::string stat((std::istreambuf_iterator<char>(statFile)), std::istreambuf_iterator<char>());
  const std::size_t close = stat.rfind(')');
  if (stat.empty()) return Error{"cannot read " + path};
  if (close == std::string::npos || close + 2 > stat.size())
    return Error{path + ": unexpected format"};
  std::istringstream fields(stat.substr(close + 2));
  std::string field;
  unsigned long long utime = 0, stime = 0;
  for (int i = 3; i <= 15 && (fields >> field); ++i) {
    if (i == 14) utime = std::stoull(field);
    if (i == 15) stime = std::stoull(field);
  }
  return double(utime + stime) / double(sysconf(_SC_CLK_TCK));
}

}  // namespace

Result<ProcStats> readProcStats(pid_t pid) {
  const std::string dir = "/proc/" + std::to_string(pid);
  ProcStats s;
  auto cpu = statCpuSeconds(dir + "/stat");
  if (!cpu) return cpu.error();
  s.cpuSeconds = *cpu;

  // Per thread: a thread that exits between the listing and the read is skipped.
  std::error_code tec;
  for (auto it = std::filesystem::directory_iterator(dir + "/task", tec);
       !tec && it != std::filesystem::directory_iterator(); it.increment(tec)) {
    std::ifstream commFile(it->path() / "comm");
    std::string name;
    if (!std::getline(commFile, name)) continue;
    auto threadCpu = statCpuSeconds((it->path() / "stat").string());
    if (threadCpu) s.threadCpuSeconds[name] += *threadCpu;
  }

  std::ifstream status(dir + "/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmRSS:", 0) == 0) s.rssMb = std::stod(line.substr(6)) / 1024.0;  // kB
  }

  std::error_code ec;
  for (auto it = std::filesystem::directory_iterator(dir + "/fd", ec);
       !ec && it != std::filesystem::directory_iterator(); it.increment(ec)) {
    ++s.openFds;
  }
  if (ec) return Error{"cannot list " + dir + "/fd: " + ec.message()};
  return s;
}

}  // namespace pc::load
