#include "protocol/secure_io.h"

#include <fcntl.h>
#include <sodium.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <system_error>

#include "protocol/sodium_init.h"

namespace pc {

namespace {

std::string encodeWith(std::span<const std::uint8_t> bytes, int variant) {
  std::string text(sodium_base64_encoded_len(bytes.size(), variant), '\0');
  sodium_bin2base64(text.data(), text.size(), bytes.data(), bytes.size(), variant);
  text.resize(text.size() - 1);  // the terminating NUL libsodium writes
  return text;
}

Result<std::vector<std::uint8_t>> decodeWith(std::string_view text, std::size_t maxBytes,
                                             int variant, const char* what) {
  ensureSodium();
  std::vector<std::uint8_t> bytes(maxBytes);
  std::size_t length = 0;
  // No characters ignored, and the whole text must be consumed (b64_end null).
  if (sodium_base642bin(bytes.data(), bytes.size(), text.data(), text.size(), nullptr, &length,
                        nullptr, variant) != 0) {
    return Error{std::string("not valid ") + what + " of at most " + std::to_string(maxBytes) +
                 " bytes"};
  }
  bytes.resize(length);
  // One text per byte string, whatever the decoder lets through: re-encoding gives the text.
  if (encodeWith(bytes, variant) != text)
    return Error{std::string("not the canonical ") + what + " of its bytes"};
  return bytes;
}

// Closes a descriptor and removes the temporary file unless it was renamed into place.
struct PendingFile {
  std::string path;
  int fd = -1;
  bool renamed = false;
  ~PendingFile() {
    if (fd >= 0) ::close(fd);
    if (!renamed) ::unlink(path.c_str());
  }
};

std::string errnoText() { return std::strerror(errno); }

}  // namespace

void ensureSodium() {
  static const bool ready = [] {
    if (sodium_init() < 0) {
      std::fprintf(stderr, "probecast: libsodium cannot initialise (no system randomness)\n");
      std::abort();
    }
    return true;
  }();
  (void)ready;
}

void randomBytes(std::span<std::uint8_t> out) {
  ensureSodium();
  randombytes_buf(out.data(), out.size());
}

std::string base64UrlEncode(std::span<const std::uint8_t> bytes) {
  return encodeWith(bytes, sodium_base64_VARIANT_URLSAFE_NO_PADDING);
}

Result<std::vector<std::uint8_t>> base64UrlDecode(std::string_view text, std::size_t maxBytes) {
  return decodeWith(text, maxBytes, sodium_base64_VARIANT_URLSAFE_NO_PADDING,
                    "base64url (no padding)");
}

std::string base64Encode(std::span<const std::uint8_t> bytes) {
  return encodeWith(bytes, sodium_base64_VARIANT_ORIGINAL);
}

Result<std::vector<std::uint8_t>> base64Decode(std::string_view text, std::size_t maxBytes) {
  return decodeWith(text, maxBytes, sodium_base64_VARIANT_ORIGINAL, "base64");
}

std::string hexEncode(std::span<const std::uint8_t> bytes) {
  static const char digits[] = "0123456789abcdef";
  std::string text;
  text.reserve(bytes.size() * 2);
  for (std::uint8_t b : bytes) {
    text.push_back(digits[b >> 4]);
    text.push_back(digits[b & 15]);
  }
  return text;
}

Result<std::vector<std::uint8_t>> hexDecode(std::string_view text, std::size_t bytes) {
  if (text.size() != bytes * 2)
    return Error{"expected " + std::to_string(bytes * 2) + " hex digits, got " +
                 std::to_string(text.size()) + " characters"};
  auto digit = [](char c) -> int {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
  };
  std::vector<std::uint8_t> out(bytes);
  for (std::size_t i = 0; i < bytes; ++i) {
    const int hi = digit(text[2 * i]), lo = digit(text[2 * i + 1]);
    if (hi < 0 || lo < 0) {
      std::string message = "not hex: character ";
      message += std::to_string(2 * i + (hi < 0 ? 1 : 2));
      message += " of '";
      message.append(text);
      message += "'";
      return Error{std::move(message)};
    }
    out[i] = std::uint8_t(hi * 16 + lo);
  }
  return out;
}

Status writeFileAtomically(const std::filesystem::path& path, std::string_view content,
                           unsigned mode) {
  const std::string where = path.string();
  // Same folder as the target, so the rename cannot cross file systems. O_EXCL: never write
  // through a file or link someone else put at the temporary name.
  PendingFile tmp{where + ".tmp." + std::to_string(::getpid())};
  ::unlink(tmp.path.c_str());
  tmp.fd = ::open(tmp.path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, mode_t(mode));
  if (tmp.fd < 0) return Error{"cannot create " + tmp.path + ": " + errnoText()};
  // The umask may have taken bits away from `mode`; a secret's mode is exact anyway.
  if (::fchmod(tmp.fd, mode_t(mode)) != 0)
    return Error{"cannot set the mode of " + tmp.path + ": " + errnoText()};
  std::size_t done = 0;
  while (done < content.size()) {
    const ssize_t n = ::write(tmp.fd, content.data() + done, content.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return Error{"cannot write " + tmp.path + ": " + errnoText()};
    done += std::size_t(n);
  }
  // On disk before the rename makes it visible: a power loss leaves the old file or the new.
  if (::fsync(tmp.fd) != 0) return Error{"cannot sync " + tmp.path + ": " + errnoText()};
  const int fd = tmp.fd;
  tmp.fd = -1;
  if (::close(fd) != 0) return Error{"cannot close " + tmp.path + ": " + errnoText()};
  if (::rename(tmp.path.c_str(), where.c_str()) != 0)
    return Error{"cannot rename " + tmp.path + " to " + where + ": " + errnoText()};
  tmp.renamed = true;
  return Status::success();
}

Result<std::string> readSmallFile(const std::filesystem::path& path, std::size_t maxBytes) {
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  if (ec) return Error{"cannot read " + path.string() + ": " + ec.message()};
  if (size > maxBytes)
    return Error{path.string() + " is " + std::to_string(size) + " bytes, more than the " +
                 std::to_string(maxBytes) + " expected"};
  std::ifstream in(path, std::ios::binary);
  std::string text(std::size_t(size), '\0');
  if (!in || !in.read(text.data(), std::streamsize(text.size())))
    return Error{"cannot read " + path.string() + ": " + errnoText()};
  return text;
}

}  // namespace pc
