// Output paths checked before the work that fills them: a tool that bakes for minutes and only
// then finds its output folder unwritable has wasted the bake, so it asks first.
#pragma once

#include <filesystem>

#include "result.h"

namespace pc {

// Makes `dir` (and its parents) and checks that a file can be created in it, by creating and
// removing one. The error names the folder and the reason.
Status prepareOutputDir(const std::filesystem::path& dir);
// The same for the folder `file` will be written to (the working directory when it names
// none); also refuses a `file` that is a folder.
Status prepareOutputFile(const std::filesystem::path& file);

}  // namespace pc
