#include "proc_stats.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace pc::load {

Result<ProcStats> readProcStats(pid_t pid) {
  const std::string dir = "/proc/" + std::to_string(pid);
  ProcStats s;

  // /proc/<pid>/stat: the command name (field 2) may hold spaces, so fields are counted from
  // its closing parenthesis; utime and stime are fields 14 and 15, in clock ticks.
  std::ifstream statFile(dir + "/stat");
  std::string stat((std::istreambuf_iterator<char>(statFile)), std::istreambuf_iterator<char>());
  const std::size_t close = stat.rfind(')');
  if (!statFile.good() && stat.empty()) return Error{"cannot read " + dir + "/stat"};
  if (close == std::string::npos) return Error{dir + "/stat: unexpected format"};
  std::istringstream fields(stat.substr(close + 2));
  std::string field;
  unsigned long long utime = 0, stime = 0;
  for (int i = 3; i <= 15 && (fields >> field); ++i) {
    if (i == 14) utime = std::stoull(field);
    if (i == 15) stime = std::stoull(field);
  }
  s.cpuSeconds = double(utime + stime) / double(sysconf(_SC_CLK_TCK));

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
