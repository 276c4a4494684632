// Levelled log lines on stderr, and progress for long runs: a bar on a terminal, periodic
// lines otherwise.
#pragma once

#include <chrono>
#include <cstdint>
#include <string>
#include <string_view>

namespace pc {

enum class LogLevel { Debug, Info, Warn, Error };
void setLogLevel(LogLevel level);
void log(LogLevel level, std::string_view message);
inline void logInfo(std::string_view m) { log(LogLevel::Info, m); }
inline void logWarn(std::string_view m) { log(LogLevel::Warn, m); }
inline void logError(std::string_view m) { log(LogLevel::Error, m); }

class Progress {
 public:
  Progress(std::string label, std::uint64_t total);
  ~Progress();  // finishes the bar / prints the last line
  void advance(std::uint64_t n = 1);  // thread-safe
 private:
  void print(bool final);
  std::string label_;
  std::uint64_t total_;
  std::uint64_t done_ = 0;
  bool tty_;
  std::chrono::steady_clock::time_point start_, last_;
};

}  // namespace pc
