// Levelled log lines on stderr, and progress for long runs: a bar on a terminal, periodic
// lines otherwise. Lines are plain text by default, or one JSON object per line
// (setLogFormat), for a log collector. Events with fields (logEvent) come out as
// `message key=value ...` in text and as JSON members in JSON.
#pragma once

#include <chrono>
#include <cstdint>
#include <initializer_list>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>

namespace pc {

enum class LogLevel { Debug, Info, Warn, Error };
enum class LogFormat { Text, Json };
void setLogLevel(LogLevel level);
void setLogFormat(LogFormat format);
// "debug", "info", "warn", "error"; "text", "json". Nothing for any other name.
std::optional<LogLevel> parseLogLevel(std::string_view name);
std::optional<LogFormat> parseLogFormat(std::string_view name);

// One key=value field of a structured event. Numbers stay numbers in JSON.
struct LogField {
  LogField(std::string_view k, std::string_view v) : key(k), value(v) {}
  LogField(std::string_view k, const char* v) : key(k), value(v) {}
  LogField(std::string_view k, const std::string& v) : key(k), value(v) {}
  template <typename T, typename = std::enable_if_t<std::is_arithmetic_v<T>>>
  LogField(std::string_view k, T v) : key(k), value(std::to_string(v)), number(true) {}
  std::string_view key;
  std::string value;
  bool number = false;
};

void log(LogLevel level, std::string_view message);
void logEvent(LogLevel level, std::string_view message, std::initializer_list<LogField> fields);
inline void logInfo(std::string_view m) { log(LogLevel::Info, m); }
inline void logWarn(std::string_view m) { log(LogLevel::Warn, m); }
inline void logError(std::string_view m) { log(LogLevel::Error, m); }

// The line log/logEvent write (without the newline), for tests: `timestamp` is passed in.
std::string formatLogLine(LogFormat format, std::string_view timestamp, LogLevel level,
                          std::string_view message, std::initializer_list<LogField> fields);

class Progress {
 public:
  Progress(std::string label, std::uint64_t total);
  ~Progress();                        // finishes the bar / prints the last line
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
