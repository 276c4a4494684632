// Files written under a temporary name and renamed into place when whole. A write that fails
// removes its temporary (TempFile's destructor), and so does a SIGINT or SIGTERM that ends the
// process part way (installTempFileCleanup): no <path>.tmp.<pid> is left behind, whatever stops
// the write.
#pragma once

#include <filesystem>

#include "result.h"

namespace pc {

class TempFile {
 public:
  // Takes charge of `path` (which the caller then creates and writes): removed unless committed.
  explicit TempFile(std::filesystem::path path);
  ~TempFile();
  TempFile(const TempFile&) = delete;
  TempFile& operator=(const TempFile&) = delete;

  const std::filesystem::path& path() const { return path_; }
  // Renames the file to `target`, which then holds it; the error names both and the reason.
  Status commit(const std::filesystem::path& target);

 private:
  void release();

  std::filesystem::path path_;
  int slot_ = -1;  // in the signal handler's table; -1 where the table was full
  bool committed_ = false;
};

// Handlers for SIGINT and SIGTERM that remove every temporary file still in charge of a
// TempFile, then end the process by the same signal (its default action, so the exit status
// says what stopped it). For tools that write their outputs at the end of long work (the bake).
void installTempFileCleanup();

}  // namespace pc
