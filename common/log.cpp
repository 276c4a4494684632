// Log lines and progress output share one mutex, so lines from several threads never interleave
// and a log line never lands in the middle of a progress bar.
#include "log.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <ctime>
#include <mutex>
#include <string>
#include <utility>

namespace pc {

namespace {

std::mutex& outputMutex() {
  static std::mutex m;
  return m;
}
std::atomic<LogLevel> gLevel{LogLevel::Info};
std::atomic<LogFormat> gFormat{LogFormat::Text};
// True while a terminal progress bar occupies the current line (guarded by outputMutex).
bool gBarOnLine = false;

const char* levelName(LogLevel level) {
  switch (level) {
    case LogLevel::Debug:
      return "debug";
    case LogLevel::Info:
      return "info";
    case LogLevel::Warn:
      return "warn";
    case LogLevel::Error:
      return "error";
  }
  return "?";
}

// Text: local wall-clock time with milliseconds, "2024-05-01 12:34:56.789". JSON: UTC in
// RFC 3339, "2024-05-01T10:34:56.789Z", which collectors parse without knowing the zone.
std::string timestamp(LogFormat format) {
  using namespace std::chrono;
  auto now = system_clock::now();
  std::time_t t = system_clock::to_time_t(now);
  int ms = int(duration_cast<milliseconds>(now.time_since_epoch()).count() % 1000);
  std::tm tm{};
  char buf[40];
  std::size_t n = 0;
  if (format == LogFormat::Json) {
    gmtime_r(&t, &tm);
    n = std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%S", &tm);
    std::snprintf(buf + n, sizeof buf - n, ".%03dZ", ms);
  } else {
    localtime_r(&t, &tm);
    n = std::strftime(buf, sizeof buf, "%Y-%m-%d %H:%M:%S", &tm);
    std::snprintf(buf + n, sizeof buf - n, ".%03d", ms);
  }
  return buf;
}

void appendJsonString(std::string& out, std::string_view s) {
  out.push_back('"');
  for (const char c : s) {
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\r':
        out += "\\r";
        break;
      case '\t':
        out += "\\t";
        break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          char esc[8];
          std::snprintf(esc, sizeof esc, "\\u%04x", unsigned(static_cast<unsigned char>(c)));
          out += esc;
        } else {
          out.push_back(c);
        }
    }
  }
  out.push_back('"');
}

// logfmt: a value with spaces, quotes, '=' or control characters is quoted and escaped.
void appendTextValue(std::string& out, std::string_view v) {
  const bool plain = !v.empty() && std::all_of(v.begin(), v.end(), [](char c) {
    return static_cast<unsigned char>(c) > 0x20 && c != '"' && c != '=' && c != '\\';
  });
  if (plain) {
    out.append(v);
  } else {
    appendJsonString(out, v);
  }
}

// "42s", "3m07s", "2h05m".
std::string formatDuration(double seconds) {
  if (!(seconds >= 0.0)) seconds = 0.0;
  long s = long(seconds + 0.5);
  char buf[32];
  if (s < 60) {
    std::snprintf(buf, sizeof buf, "%.1fs", seconds);
  } else if (s < 3600) {
    std::snprintf(buf, sizeof buf, "%ldm%02lds", s / 60, s % 60);
  } else {
    std::snprintf(buf, sizeof buf, "%ldh%02ldm", s / 3600, (s % 3600) / 60);
  }
  return buf;
}

void clearBarLocked() {
  if (gBarOnLine) {
    std::fputs("\r\033[2K", stderr);
    gBarOnLine = false;
  }
}

}  // namespace

void setLogLevel(LogLevel level) { gLevel.store(level, std::memory_order_relaxed); }
void setLogFormat(LogFormat format) { gFormat.store(format, std::memory_order_relaxed); }

std::optional<LogLevel> parseLogLevel(std::string_view name) {
  for (LogLevel l : {LogLevel::Debug, LogLevel::Info, LogLevel::Warn, LogLevel::Error}) {
    if (name == levelName(l)) return l;
  }
  return std::nullopt;
}

std::optional<LogFormat> parseLogFormat(std::string_view name) {
  if (name == "text") return LogFormat::Text;
  if (name == "json") return LogFormat::Json;
  return std::nullopt;
}

std::string formatLogLine(LogFormat format, std::string_view time, LogLevel level,
                          std::string_view message, std::initializer_list<LogField> fields) {
  std::string line;
  line.reserve(64 + message.size());
  if (format == LogFormat::Json) {
    line.append("{\"ts\":");
    appendJsonString(line, time);
    line += ",\"level\":\"";
    line += levelName(level);
    line += "\",\"msg\":";
    appendJsonString(line, message);
    for (const LogField& f : fields) {
      line.push_back(',');
      appendJsonString(line, f.key);
      line.push_back(':');
      if (f.number) {
        line += f.value;
      } else {
        appendJsonString(line, f.value);
      }
    }
    line.push_back('}');
    return line;
  }
  line.push_back('[');
  line.append(time);
  line += "] [";
  line += levelName(level);
  line += "] ";
  line.append(message);
  for (const LogField& f : fields) {
    line.push_back(' ');
    line.append(f.key);
    line.push_back('=');
    appendTextValue(line, f.value);
  }
  return line;
}

void log(LogLevel level, std::string_view message) { logEvent(level, message, {}); }

void logEvent(LogLevel level, std::string_view message, std::initializer_list<LogField> fields) {
  if (level < gLevel.load(std::memory_order_relaxed)) return;
  const LogFormat format = gFormat.load(std::memory_order_relaxed);
  std::string line = formatLogLine(format, timestamp(format), level, message, fields);
  line.push_back('\n');
  std::lock_guard lock(outputMutex());
  clearBarLocked();  // the bar is redrawn by the next advance()
  std::fputs(line.c_str(), stderr);
  std::fflush(stderr);
}

Progress::Progress(std::string label, std::uint64_t total)
    : label_(std::move(label)),
      total_(total),
      tty_(isatty(fileno(stderr)) != 0),
      start_(std::chrono::steady_clock::now()),
      last_(start_) {}

Progress::~Progress() {
  std::lock_guard lock(outputMutex());
  print(true);
}

void Progress::advance(std::uint64_t n) {
  std::lock_guard lock(outputMutex());
  done_ += n;
  auto now = std::chrono::steady_clock::now();
  // A bar redraws at most 10 times a second; a log file gets a line every 5 seconds.
  auto interval = tty_ ? std::chrono::milliseconds(100) : std::chrono::milliseconds(5000);
  if (now - last_ >= interval) {
    last_ = now;
    print(false);
  }
}

// Called with outputMutex held.
void Progress::print(bool final) {
  using namespace std::chrono;
  const double elapsed = duration<double>(steady_clock::now() - start_).count();
  const std::uint64_t done = total_ > 0 ? std::min(done_, total_) : done_;
  const double fraction = total_ > 0 ? double(done) / double(total_) : 1.0;
  std::string eta = "?";
  if (final) {
    eta = "done";
  } else if (done > 0) {
    eta = formatDuration(elapsed * (1.0 - fraction) / fraction);
  }
  char stats[160];
  std::snprintf(stats, sizeof stats, "%5.1f%% %llu/%llu elapsed %s eta %s", fraction * 100.0,
                static_cast<unsigned long long>(done), static_cast<unsigned long long>(total_),
                formatDuration(elapsed).c_str(), eta.c_str());
  if (tty_) {
    constexpr int kWidth = 30;
    int filled = int(fraction * kWidth);
    std::string bar(std::size_t(filled), '#');
    bar.append(std::size_t(kWidth - filled), '.');
    std::fprintf(stderr, "\r\033[2K%s [%s] %s", label_.c_str(), bar.c_str(), stats);
    gBarOnLine = !final;
    if (final) std::fputc('\n', stderr);
  } else {
    const LogFormat format = gFormat.load(std::memory_order_relaxed);
    const std::string line =
        formatLogLine(format, timestamp(format), LogLevel::Info, label_ + ": " + stats, {});
    std::fprintf(stderr, "%s\n", line.c_str());
  }
  std::fflush(stderr);
}

}  // namespace pc
