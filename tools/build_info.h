// What the running tool was built from, for --version: the git revision and the build type.
#pragma once

namespace pc {

// `git describe --always --dirty --abbrev=7` of the sources at build time ("5bd65b5", or
// "5bd65b5-dirty" where tracked files differed from that commit), or "unknown" where they were
// not a git checkout (a release tarball, an installed copy).
const char* gitRevision();

// The CMake build type the tools were built as ("RelWithDebInfo", "Debug", ...), or
// "unspecified" where none was given.
const char* buildType();

}  // namespace pc
