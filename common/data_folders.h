// Where a tool finds the files it reads at run time besides its inputs: the SPIR-V of the GPU
// tracer and the client renderer (shaders/) and the sidecars of the shared test scenes
// (sidecars/). Relative to the running executable, so that the build tree, a scripts/bundle
// copy and an installed prefix each find their own; never the source tree, which a copy of the
// tools on another machine does not have.
#pragma once

#include <filesystem>
#include <string_view>
#include <vector>

#include "result.h"

namespace pc {

// The data folders, in the order they are searched:
//   1. the executable's own folder (build/bin/shaders, a bundle's shaders/ and sidecars/);
//   2. the install's data folder reached from it (<prefix>/share/probecast from
//      <prefix>/bin, as CMake's GNUInstallDirs lay them out);
//   3. $PROBECAST_DATA, where it is set (a copy laid out otherwise).
std::vector<std::filesystem::path> dataFolders();

// The first <folder>/<subfolder>/<name> over dataFolders() that is a file; else an Error
// naming the file and every folder looked in.
Result<std::filesystem::path> findDataFile(std::string_view subfolder, std::string_view name);

// "<f1>/<subfolder>, <f2>/<subfolder>, ...": where findDataFile looks, for messages.
std::string dataFolderList(std::string_view subfolder);

}  // namespace pc
