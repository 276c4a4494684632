#include "output_path.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <string>

namespace pc {

namespace fs = std::filesystem;

Status prepareOutputDir(const fs::path& dir) {
  const fs::path where = dir.empty() ? fs::path(".") : dir;
  std::error_code ec;
  fs::create_directories(where, ec);
  if (ec) return Error{"cannot create the output folder " + where.string() + ": " + ec.message()};
  if (!fs::is_directory(where, ec)) {
    return Error{"the output folder " + where.string() + " is not a folder"};
  }
  // A file made and removed at once: the only test that also holds for read-only mounts,
  // access lists and full quotas, which permission bits do not show.
  const fs::path probe = where / (".probecast-write-check-" + std::to_string(getpid()));
  const int fd = open(probe.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (fd < 0) {
    return Error{"cannot write to the output folder " + where.string() + ": " +
                 std::strerror(errno)};
  }
  close(fd);
  fs::remove(probe, ec);
  return Status::success();
}

Status prepareOutputFile(const fs::path& file) {
  std::error_code ec;
  if (fs::is_directory(file, ec)) {
    return Error{"the output file " + file.string() + " is a folder"};
  }
  return prepareOutputDir(file.parent_path());
}

}  // namespace pc
