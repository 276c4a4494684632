// Levelled log lines on stderr, and progress for long runs: a bar on a terminal, periodic
// lines otherwise. Lines are plain text by default, or one JSON object per line
// (setLogFormat), for a log collector. Events with fields (logEvent) come out as
// `message key=value ...` in text and as JSON members in JSON.
#pragma once

#include <chrono>
#include <cstdint>
#include <initializer_list>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>

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
void logEvent(LogLevel level, std::string_view message, std::span<const LogField> fields);
// A record for machines and a line for people (periodic statistics): in JSON logs one object
// with `message` and the named fields, in text logs `textLine` alone, as it always read.
void logRecord(LogLevel level, std::string_view message, std::span<const LogField> fields,
               std::string_view textLine);
LogFormat logFormat();
inline void logInfo(std::string_view m) { log(LogLevel::Info, m); }
inline void logWarn(std::string_view m) { log(LogLevel::Warn, m); }
inline void logError(std::string_view m) { log(LogLevel::Error, m); }

// A string a peer supplied (a client's name, a server's Reject reason, an HTTP request line),
// made safe to log or print: quoted, with quotes and backslashes escaped, control characters
// (C0, DEL, C1), bidirectional overrides and bytes that are not UTF-8 written as \xNN or
// \uNNNN, so it can neither forge a log line nor drive a terminal; cut after about maxBytes
// of output, the marker saying how many bytes of the original were left out.
std::string quoteUntrusted(std::string_view s, std::size_t maxBytes = 200);
// The same without the quotes and the marker, for a field of logEvent (which quotes a value
// as its format needs): escaped, and cut after maxBytes.
std::string escapeUntrusted(std::string_view s, std::size_t maxBytes = 200);

// Lets through at most `burst` lines per `interval` seconds and counts the rest, so that a
// loop driven by a peer (reconnects to a hostile server, refused connections) cannot fill a
// disk with log. Not thread-safe: one per caller's thread.
class LogBudget {
 public:
  LogBudget(int burst, double interval) : burst_(burst), interval_(interval) {}
  // True when a line may be written at `now` (seconds on any steady clock).
  bool take(double now);
  // Lines refused since the previous call (for a "N similar lines suppressed" note).
  std::uint64_t takeSuppressed() { return std::exchange(suppressed_, 0); }

 private:
  int burst_;
  double interval_;
  int used_ = 0;
  double windowStart_ = -1e300;
  std::uint64_t suppressed_ = 0;
};

// The line log/logEvent write (without the newline), for tests: `timestamp` is passed in.
std::string formatLogLine(LogFormat format, std::string_view timestamp, LogLevel level,
                          std::string_view message, std::span<const LogField> fields);
inline std::string formatLogLine(LogFormat format, std::string_view timestamp, LogLevel level,
                                 std::string_view message, std::initializer_list<LogField> fields) {
  return formatLogLine(format, timestamp, level, message,
                       std::span<const LogField>(fields.begin(), fields.size()));
}

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
