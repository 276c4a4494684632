// The build's git revision and build type. Only this file includes the generated header, so
// a new revision recompiles this file alone (and relinks the tools).
#include "tools/build_info.h"

#include "git_revision.h"  // generated in the build tree by tools/git_revision.cmake

namespace pc {

const char* gitRevision() { return PC_GIT_REVISION; }

const char* buildType() {
  static constexpr char kType[] = PC_BUILD_TYPE;
  return kType[0] != '\0' ? kType : "unspecified";
}

}  // namespace pc
