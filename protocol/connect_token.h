// Connect tokens: expiring, signed statements that a client may connect (which client, to
// which scene, in which role, with what share of the server). An issuer signs them with an
// Ed25519 signing key; servers and relays verify them with the public verify key alone, so
// they never hold the key that makes tokens. Format, key files and checks: PROTOCOL.md,
// "Connect tokens".
//
//   KeyPair keys = generateKeyPair();
//   Result<std::string> token = issueToken(keys.signing, newTokenClaims("alice", "*", ...));
//   TokenVerifier verifier({keys.verify});
//   TokenError cause;
//   Result<TokenClaims> claims = verifier.verify(*token, "sponza", nowUnix, &cause);
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "common/result.h"

namespace pc {

inline constexpr std::string_view kTokenPrefix = "pct1.";
inline constexpr std::size_t kMaxTokenChars = 1024;
inline constexpr std::size_t kTokenIdBytes = 16;
inline constexpr std::size_t kMaxTokenClientBytes = 64;
inline constexpr std::size_t kMaxTokenSceneBytes = 128;
inline constexpr std::uint32_t kMaxTokenWeight = 16;
// A token issued this far in the future is still accepted (the issuer's clock may run ahead).
inline constexpr std::int64_t kTokenClockSkewSeconds = 60;
// The scene claim that admits any scene.
inline constexpr std::string_view kAnyScene = "*";

using TokenId = std::array<std::uint8_t, kTokenIdBytes>;

enum class TokenRole : std::uint8_t { Viewer = 1, Editor = 2 };

struct TokenClaims {
  TokenId id{};
  std::string client;                    // 1..64 printable ASCII characters
  std::string scene = std::string("*");  // a scene name, or "*" for any; 1..128 bytes
  TokenRole role = TokenRole::Viewer;
  std::uint32_t weight = 1;    // the client's share of the server relative to others, 1..16
  std::int64_t issuedAt = 0;   // unix seconds
  std::int64_t expiresAt = 0;  // unix seconds; the token is valid while now < expiresAt
};

// Why a token was refused; tokenErrorName gives the metric label ("bad_signature").
enum class TokenError : std::uint8_t {
  Malformed,     // not a pct1 token: size, prefix, base64, layout or a claim out of range
  BadSignature,  // signed by none of the verifier's keys
  Expired,       // now >= expires-at
  NotYetValid,   // issued-at more than kTokenClockSkewSeconds after now
  Revoked,       // its id is on the revocation list
  WrongScene,    // names another scene than the one asked for
};
inline constexpr std::size_t kTokenErrorCount = 6;
std::string_view tokenErrorName(TokenError cause);

std::string_view tokenRoleName(TokenRole role);  // "viewer", "editor"
Result<TokenRole> parseTokenRole(std::string_view name);
std::string tokenIdHex(const TokenId& id);  // 32 lower-case hex digits
Result<TokenId> parseTokenIdHex(std::string_view hex);

// The clock tokens are issued and checked on: seconds since the Unix epoch, now.
std::int64_t unixSeconds();

// Claims for a new token: a random id, issued at `nowUnix`, expiring `ttlSeconds` later.
TokenClaims newTokenClaims(std::string client, std::string scene, TokenRole role,
                           std::uint32_t weight, std::int64_t nowUnix, std::int64_t ttlSeconds);
// Every claim in range (the limits above, expires-at after issued-at), or what is not.
Status checkTokenClaims(const TokenClaims& claims);

// Keys: libsodium's Ed25519 secret key (32-byte seed followed by the public key) and the
// public key. A SigningKey wipes its bytes when destroyed.
struct VerifyKey {
  std::array<std::uint8_t, 32> bytes{};
  bool operator==(const VerifyKey&) const = default;
};
class SigningKey {
 public:
  SigningKey() = default;
  explicit SigningKey(const std::array<std::uint8_t, 64>& bytes) : bytes_(bytes) {}
  SigningKey(const SigningKey&) = default;
  SigningKey& operator=(const SigningKey&) = default;
  ~SigningKey();
  const std::array<std::uint8_t, 64>& bytes() const { return bytes_; }
  VerifyKey verifyKey() const;  // its public half

 private:
  std::array<std::uint8_t, 64> bytes_{};
};
struct KeyPair {
  SigningKey signing;
  VerifyKey verify;
};
KeyPair generateKeyPair();
// The same pair every time for one seed: for tests and fuzzing, never for real keys.
KeyPair keyPairFromSeed(const std::array<std::uint8_t, 32>& seed);

// Key files hold one line, "probecast-signing-key v1 <base64>" or "probecast-verify-key v1
// <base64>" (standard base64 with padding), and a newline. A signing key file that group or
// others may access is refused, as ssh refuses such a private key. writeKeyFile replaces the
// file atomically, the signing key with mode 0600, the verify key 0644.
std::string signingKeyText(const SigningKey& key);  // the line, without the newline
std::string verifyKeyText(const VerifyKey& key);
Result<SigningKey> parseSigningKey(std::string_view text);  // one line, newline optional
Result<VerifyKey> parseVerifyKey(std::string_view text);
Result<SigningKey> loadSigningKey(const std::filesystem::path& path);
Result<VerifyKey> loadVerifyKey(const std::filesystem::path& path);
// A signing key from the environment variable `name` (its value is the key line); an error
// when it is unset or not a key. For tools that must not take a secret on the command line.
Result<SigningKey> signingKeyFromEnvironment(const char* name);
Status writeKeyFile(const std::filesystem::path& path, const SigningKey& key);
Status writeKeyFile(const std::filesystem::path& path, const VerifyKey& key);

// The token text for `claims`, signed; an Error when a claim is out of range.
Result<std::string> issueToken(const SigningKey& key, const TokenClaims& claims);
// The claims of a well-formed token, WITHOUT checking its signature or times: for showing a
// token (probecast-token inspect) and for finding its id to revoke. Never admit a client on it.
Result<TokenClaims> parseTokenUnverified(std::string_view token);

// Revocation lists: one token id (32 hex digits) per line; blank lines and anything after
// '#' ignored. The error names the file and line.
Result<std::set<TokenId>> loadRevocations(const std::filesystem::path& path);

// Checks tokens against one or more verify keys (several while keys rotate: a token signed by
// any of them is authentic) and a set of revoked token ids. Not thread-safe: one thread (the
// server's network thread) verifies and reloads.
class TokenVerifier {
 public:
  TokenVerifier() = default;
  explicit TokenVerifier(std::vector<VerifyKey> keys) : keys_(std::move(keys)) {}

  void addKey(const VerifyKey& key) { keys_.push_back(key); }
  std::size_t keyCount() const { return keys_.size(); }

  // Revokes one id (kept across reloads of the list file).
  void revoke(const TokenId& id) { revoked_.insert(id); }
  bool isRevoked(const TokenId& id) const;
  // Reads the revocation list file and remembers it for reloadRevocations. On an error the
  // ids already loaded stay revoked.
  Status loadRevocations(const std::filesystem::path& path);
  // Reads the list again when the file changed since it was last read (modification time,
  // size or inode): true when it did. An operator edits or replaces the file to revoke
  // without a restart. A file that is missing or has a bad line gives an Error and changes
  // nothing (a half-written list never un-revokes a token); the next call tries again.
  Result<bool> reloadRevocations();
  std::size_t revokedCount() const { return revoked_.size() + listed_.size(); }

  // The token's claims when it is well formed, signed by one of the keys, not revoked,
  // issued no later than now + kTokenClockSkewSeconds, not expired at `nowUnix`, and names
  // `scene` or "*". Otherwise an Error naming the problem, and the cause in `*cause` when
  // given (in that order of checks: the first that fails).
  Result<TokenClaims> verify(std::string_view token, std::string_view scene, std::int64_t nowUnix,
                             TokenError* cause = nullptr) const;

 private:
  struct FileStamp {
    std::int64_t mtimeNs = 0;
    std::uint64_t size = 0, inode = 0;
    bool operator==(const FileStamp&) const = default;
  };
  std::vector<VerifyKey> keys_;
  std::set<TokenId> revoked_;  // by revoke()
  std::set<TokenId> listed_;   // from the list file
  std::filesystem::path listPath_;
  std::optional<FileStamp> listStamp_;
};

}  // namespace pc
