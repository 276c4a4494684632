#include "temp_file.h"

#include <unistd.h>

#include <atomic>
#include <csignal>
#include <cstring>

namespace pc {

namespace {

// The temporaries a signal handler must remove, in storage it may read: fixed arrays, and an
// atomic state per slot (free, being filled, pending) so that it never reads a path half written.
constexpr int kSlots = 16;
constexpr std::size_t kPathBytes = 4096;
enum SlotState : int { kFree = 0, kFilling = 1, kPending = 2 };
struct Slot {
  std::atomic<int> state{kFree};
  char path[kPathBytes];
};
Slot slots[kSlots];
static_assert(std::atomic<int>::is_always_lock_free, "the signal handler reads these atomics");

extern "C" void removeTempFilesAndDie(int sig) {
  for (Slot& s : slots)
    if (s.state.load() == kPending) ::unlink(s.path);  // async-signal-safe
  std::signal(sig, SIG_DFL);
  std::raise(sig);
}

}  // namespace

TempFile::TempFile(std::filesystem::path path) : path_(std::move(path)) {
  const std::string& p = path_.native();
  if (p.size() >= kPathBytes) return;  // no slot: the destructor still removes it
  for (int i = 0; i < kSlots; ++i) {
    int expected = kFree;
    if (!slots[i].state.compare_exchange_strong(expected, kFilling)) continue;
    std::memcpy(slots[i].path, p.c_str(), p.size() + 1);
    slots[i].state.store(kPending);
    slot_ = i;
    return;
  }
}

TempFile::~TempFile() {
  if (!committed_) {
    std::error_code ec;
    std::filesystem::remove(path_, ec);
  }
  release();  // after the removal: a signal in between only removes it once more
}

Status TempFile::commit(const std::filesystem::path& target) {
  std::error_code ec;
  std::filesystem::rename(path_, target, ec);
  if (ec)
    return Error{"cannot rename " + path_.string() + " to " + target.string() + ": " +
                 ec.message()};
  committed_ = true;
  release();
  return Status::success();
}

void TempFile::release() {
  if (slot_ >= 0) slots[slot_].state.store(kFree);
  slot_ = -1;
}

void installTempFileCleanup() {
  struct sigaction action = {};
  action.sa_handler = removeTempFilesAndDie;
  sigemptyset(&action.sa_mask);
  for (int sig : {SIGINT, SIGTERM}) sigaction(sig, &action, nullptr);
}

}  // namespace pc
