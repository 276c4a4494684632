#include "data_folders.h"

#include <cstdlib>
#include <system_error>

// The install's data folder relative to its executables' folder (CMake: from
// CMAKE_INSTALL_BINDIR to CMAKE_INSTALL_DATADIR/probecast); builds that do not say take the
// GNU layout.
#ifndef PC_DATA_FROM_BIN
#define PC_DATA_FROM_BIN "../share/probecast"
#endif

namespace pc {

namespace fs = std::filesystem;

std::vector<fs::path> dataFolders() {
  std::vector<fs::path> folders;
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const fs::path bin = exe.parent_path();
    folders.push_back(bin);
    folders.push_back((bin / PC_DATA_FROM_BIN).lexically_normal());
  }
  if (const char* env = std::getenv("PROBECAST_DATA"); env != nullptr && *env != '\0')
    folders.push_back(fs::path(env));
  return folders;
}

std::string dataFolderList(std::string_view subfolder) {
  std::string list;
  for (const fs::path& folder : dataFolders()) {
    if (!list.empty()) list += ", ";
    list += (folder / subfolder).string();
  }
  return list.empty() ? "(no folder: the executable's path is unknown and $PROBECAST_DATA unset)"
                      : list;
}

Result<fs::path> findDataFile(std::string_view subfolder, std::string_view name) {
  std::error_code ec;
  for (const fs::path& folder : dataFolders()) {
    const fs::path candidate = folder / subfolder / name;
    if (fs::is_regular_file(candidate, ec)) return candidate;
  }
  return Error{std::string(name) + ": not found in " + dataFolderList(subfolder) +
               " (set $PROBECAST_DATA to the folder holding " + std::string(subfolder) + "/)"};
}

}  // namespace pc
