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

// The length of the well-formed UTF-8 sequence at s[i], with its code point in `cp`; 0 when
// the bytes there are not UTF-8 (a stray continuation, an overlong form, a surrogate, a cut
// sequence).
std::size_t utf8Sequence(std::string_view s, std::size_t i, char32_t& cp) {
  const unsigned char c = static_cast<unsigned char>(s[i]);
  std::size_t n = 1;
  char32_t least = 0;
  if (c < 0x80) {
    cp = c;
    return 1;
  } else if ((c & 0xE0) == 0xC0) {
    n = 2, cp = c & 0x1F, least = 0x80;
  } else if ((c & 0xF0) == 0xE0) {
    n = 3, cp = c & 0x0F, least = 0x800;
  } else if ((c & 0xF8) == 0xF0) {
    n = 4, cp = c & 0x07, least = 0x10000;
  } else {
    return 0;
  }
  if (i + n > s.size()) return 0;
  for (std::size_t k = 1; k < n; ++k) {
    const unsigned char d = static_cast<unsigned char>(s[i + k]);
    if ((d & 0xC0) != 0x80) return 0;
    cp = cp << 6 | (d & 0x3F);
  }
  if (cp < least || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) return 0;
  return n;
}

std::string hexEscape(const char* format, unsigned value) {
  char esc[12];
  std::snprintf(esc, sizeof esc, format, value);
  return esc;
}

// JSON strings: every control character escaped, and bytes that are not UTF-8 replaced by
// U+FFFD, so a line is valid JSON whatever a peer put into a field.
void appendJsonString(std::string& out, std::string_view s) {
  out.push_back('"');
  for (std::size_t i = 0; i < s.size();) {
    char32_t cp = 0;
    const std::size_t n = utf8Sequence(s, i, cp);
    if (n == 0) {
      out += "\\ufffd";
      ++i;
      continue;
    }
    switch (cp) {
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
        if (cp < 0x20 || (cp >= 0x7F && cp <= 0x9F)) {  // C0, DEL and C1 controls
          out += hexEscape("\\u%04x", unsigned(cp));
        } else {
          out.append(s.substr(i, n));
        }
    }
    i += n;
  }
  out.push_back('"');
}

// logfmt: a value with spaces, quotes, '=', control characters or anything beyond ASCII is
// quoted and escaped.
void appendTextValue(std::string& out, std::string_view v) {
  const bool plain = !v.empty() && std::all_of(v.begin(), v.end(), [](char c) {
    const auto u = static_cast<unsigned char>(c);
    return u > 0x20 && u < 0x7F && c != '"' && c != '=' && c != '\\';
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
                          std::string_view message, std::span<const LogField> fields) {
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
  // A message never spans lines or carries terminal controls, whatever was pasted into it.
  for (const char c : message) {
    const auto u = static_cast<unsigned char>(c);
    if (u < 0x20 || u == 0x7F) {
      line += hexEscape("\\x%02x", u);
    } else {
      line.push_back(c);
    }
  }
  for (const LogField& f : fields) {
    line.push_back(' ');
    line.append(f.key);
    line.push_back('=');
    appendTextValue(line, f.value);
  }
  return line;
}

namespace {

// Appends the escaped form of `s` to `out` while it stays within maxBytes; returns how many
// bytes of `s` it took.
std::size_t appendEscaped(std::string& out, std::string_view s, std::size_t maxBytes) {
  const std::size_t start = out.size();
  std::size_t i = 0;
  std::string piece;
  while (i < s.size()) {
    char32_t cp = 0;
    std::size_t n = utf8Sequence(s, i, cp);
    if (n == 0) {
      piece = hexEscape("\\x%02x", static_cast<unsigned char>(s[i]));
      n = 1;
    } else if (cp == '"' || cp == '\\') {
      piece = {'\\', char(cp)};
    } else if (cp == '\n') {
      piece = "\\n";
    } else if (cp == '\r') {
      piece = "\\r";
    } else if (cp == '\t') {
      piece = "\\t";
    } else if (cp < 0x20 || cp == 0x7F) {
      piece = hexEscape("\\x%02x", unsigned(cp));
    } else if ((cp >= 0x80 && cp <= 0x9F) || (cp >= 0x2028 && cp <= 0x202E) ||
               (cp >= 0x2066 && cp <= 0x2069)) {
      // C1 controls (a terminal takes U+009B for an escape sequence), line separators and
      // bidirectional overrides (which reorder what a reader sees).
      piece = hexEscape("\\u%04x", unsigned(cp));
    } else {
      piece.assign(s.substr(i, n));
    }
    if (out.size() - start + piece.size() > maxBytes) break;
    out += piece;
    i += n;
  }
  return i;
}

}  // namespace

std::string quoteUntrusted(std::string_view s, std::size_t maxBytes) {
  std::string out = "\"";
  const std::size_t taken = appendEscaped(out, s, maxBytes);
  out.push_back('"');
  if (taken < s.size()) out += "...(" + std::to_string(s.size() - taken) + " more bytes)";
  return out;
}

std::string escapeUntrusted(std::string_view s, std::size_t maxBytes) {
  std::string out;
  appendEscaped(out, s, maxBytes);
  return out;
}

bool LogBudget::take(double now) {
  if (now - windowStart_ >= interval_) {
    windowStart_ = now;
    used_ = 0;
  }
  if (used_ < burst_) {
    ++used_;
    return true;
  }
  ++suppressed_;
  return false;
}

void log(LogLevel level, std::string_view message) {
  logEvent(level, message, std::span<const LogField>());
}

void logEvent(LogLevel level, std::string_view message, std::initializer_list<LogField> fields) {
  logEvent(level, message, std::span<const LogField>(fields.begin(), fields.size()));
}

LogFormat logFormat() { return gFormat.load(std::memory_order_relaxed); }

void logRecord(LogLevel level, std::string_view message, std::span<const LogField> fields,
               std::string_view textLine) {
  if (logFormat() == LogFormat::Json) {
    logEvent(level, message, fields);
  } else {
    log(level, textLine);
  }
}

void logEvent(LogLevel level, std::string_view message, std::span<const LogField> fields) {
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
