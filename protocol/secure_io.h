// Small pieces the connect tokens and sealed datagrams share: random bytes from the operating
// system, the two base64 alphabets their text forms use, and files written the way secrets
// must be (created with their final permissions, replaced atomically).
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "common/result.h"

namespace pc {

// Fills `out` with bytes from the operating system's random generator (libsodium's
// randombytes_buf). Never fails: where the system offers no randomness at all, libsodium's
// initialisation fails and the process stops with a message, since no key, token id or nonce
// may be made without it.
void randomBytes(std::span<std::uint8_t> out);

// base64url without padding (RFC 4648 section 5), as tokens use it. Decoding is strict: any
// character outside the alphabet, padding, whitespace, or unused low bits that are not zero
// is refused, so every byte string has exactly one text form. `maxBytes` caps the output.
std::string base64UrlEncode(std::span<const std::uint8_t> bytes);
Result<std::vector<std::uint8_t>> base64UrlDecode(std::string_view text, std::size_t maxBytes);

// Standard base64 with padding (RFC 4648 section 4), as key files use it; as strict.
std::string base64Encode(std::span<const std::uint8_t> bytes);
Result<std::vector<std::uint8_t>> base64Decode(std::string_view text, std::size_t maxBytes);

// Lower-case hex and its strict inverse (either case accepted; `bytes` digits pairs exactly).
std::string hexEncode(std::span<const std::uint8_t> bytes);
Result<std::vector<std::uint8_t>> hexDecode(std::string_view text, std::size_t bytes);

// Writes `content` to `path` atomically: a new file in the same folder, created with `mode`
// (0600 for secrets: never readable by others, not even for a moment), written, synced and
// renamed over `path`. A failure leaves `path` as it was and names the file and the reason.
Status writeFileAtomically(const std::filesystem::path& path, std::string_view content,
                           unsigned mode);

// Reads a whole file of at most `maxBytes` (a larger one is refused, naming its size).
Result<std::string> readSmallFile(const std::filesystem::path& path, std::size_t maxBytes);

}  // namespace pc
