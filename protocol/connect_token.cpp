#include "protocol/connect_token.h"

#include <sodium.h>
#include <sys/stat.h>

#include <chrono>
#include <cstdlib>
#include <cstring>

#include "protocol/secure_io.h"
#include "protocol/sodium_init.h"

namespace pc {

namespace {

constexpr std::size_t kSignatureBytes = 64;
// Fixed part of the binary claims: id, issued-at, expires-at, role, weight, the two lengths.
constexpr std::size_t kClaimsFixedBytes = kTokenIdBytes + 8 + 8 + 1 + 1 + 1 + 1;
constexpr std::size_t kMaxClaimsBytes =
    kClaimsFixedBytes + kMaxTokenClientBytes + kMaxTokenSceneBytes;
constexpr std::string_view kSigningKeyTag = "probecast-signing-key v1 ";
constexpr std::string_view kVerifyKeyTag = "probecast-verify-key v1 ";
constexpr std::size_t kMaxKeyFileBytes = 4096;
constexpr std::size_t kMaxRevocationFileBytes = 16u << 20;

void putLe(std::string& out, std::uint64_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) out.push_back(char(std::uint8_t(v >> (8 * i))));
}

std::uint64_t getLe(const std::uint8_t* p, int bytes) {
  std::uint64_t v = 0;
  for (int i = 0; i < bytes; ++i) v |= std::uint64_t(p[i]) << (8 * i);
  return v;
}

bool printableAscii(std::string_view s) {
  for (char c : s)
    if (c < 0x20 || c > 0x7e) return false;
  return true;
}

bool noControlBytes(std::string_view s) {
  for (char c : s)
    if ((unsigned char)c < 0x20 || c == 0x7f) return false;
  return true;
}

std::string encodeClaims(const TokenClaims& c) {
  std::string out(reinterpret_cast<const char*>(c.id.data()), c.id.size());
  putLe(out, std::uint64_t(c.issuedAt), 8);
  putLe(out, std::uint64_t(c.expiresAt), 8);
  out.push_back(char(c.role));
  out.push_back(char(c.weight));
  out.push_back(char(c.client.size()));
  out += c.client;
  out.push_back(char(c.scene.size()));
  out += c.scene;
  return out;
}

Result<TokenClaims> decodeClaims(std::span<const std::uint8_t> b) {
  auto tooShort = [&] {
    return Error{"claims end early (" + std::to_string(b.size()) + " bytes)"};
  };
  if (b.size() < kClaimsFixedBytes) return tooShort();
  TokenClaims c;
  std::memcpy(c.id.data(), b.data(), kTokenIdBytes);
  const std::uint8_t* p = b.data() + kTokenIdBytes;
  c.issuedAt = std::int64_t(getLe(p, 8));
  c.expiresAt = std::int64_t(getLe(p + 8, 8));
  const std::uint8_t role = p[16];
  if (role != std::uint8_t(TokenRole::Viewer) && role != std::uint8_t(TokenRole::Editor))
    return Error{"unknown role " + std::to_string(role)};
  c.role = TokenRole(role);
  c.weight = p[17];
  std::size_t at = kTokenIdBytes + 18;
  const std::size_t clientLength = b[at++];
  if (b.size() < at + clientLength + 1) return tooShort();
  c.client.assign(reinterpret_cast<const char*>(b.data() + at), clientLength);
  at += clientLength;
  const std::size_t sceneLength = b[at++];
  if (b.size() < at + sceneLength) return tooShort();
  c.scene.assign(reinterpret_cast<const char*>(b.data() + at), sceneLength);
  at += sceneLength;
  if (at != b.size()) return Error{std::to_string(b.size() - at) + " bytes after the claims"};
  if (Status s = checkTokenClaims(c); !s) return s.error();
  return c;
}

// A token split into what it says and what signs it, every part checked for form.
struct TokenParts {
  std::string_view signedText;  // "pct1." and the claims' base64url: what the signature covers
  TokenClaims claims;
  std::vector<std::uint8_t> signature;
};

Result<TokenParts> splitToken(std::string_view token) {
  if (token.size() > kMaxTokenChars)
    return Error{"token is " + std::to_string(token.size()) + " characters, more than " +
                 std::to_string(kMaxTokenChars)};
  if (token.substr(0, kTokenPrefix.size()) != kTokenPrefix)
    return Error{"token does not start with '" + std::string(kTokenPrefix) + "'"};
  const std::size_t dot = token.find('.', kTokenPrefix.size());
  if (dot == std::string_view::npos) return Error{"token has no signature part"};
  TokenParts parts;
  parts.signedText = token.substr(0, dot);
  auto claims = base64UrlDecode(token.substr(kTokenPrefix.size(), dot - kTokenPrefix.size()),
                                kMaxClaimsBytes);
  if (!claims) return Error{"token claims: " + claims.error().message};
  auto signature = base64UrlDecode(token.substr(dot + 1), kSignatureBytes);
  if (!signature) return Error{"token signature: " + signature.error().message};
  if (signature->size() != kSignatureBytes)
    return Error{"token signature is " + std::to_string(signature->size()) + " bytes, not 64"};
  auto decoded = decodeClaims(claims.value());
  if (!decoded) return Error{"token claims: " + decoded.error().message};
  parts.claims = std::move(decoded.value());
  parts.signature = std::move(signature.value());
  return parts;
}

// A key line: the tag, then base64 of exactly `bytes` bytes, then at most one newline.
Result<std::vector<std::uint8_t>> parseKeyLine(std::string_view text, std::string_view tag,
                                               std::size_t bytes) {
  if (!text.empty() && text.back() == '\n') text.remove_suffix(1);
  const std::string what(tag.substr(0, tag.find(' ')));
  if (text.substr(0, tag.size()) != tag)
    return Error{"not a " + what + ": expected a line starting '" + std::string(tag) + "'"};
  auto key = base64Decode(text.substr(tag.size()), bytes);
  if (!key) return Error{what + ": " + key.error().message};
  if (key->size() != bytes)
    return Error{what + " is " + std::to_string(key->size()) + " bytes, not " +
                 std::to_string(bytes)};
  return key;
}

// b - a for b > a, exact whatever the values (the true difference fits 64 unsigned bits).
std::uint64_t secondsBetween(std::int64_t a, std::int64_t b) {
  return std::uint64_t(b) - std::uint64_t(a);
}

}  // namespace

std::string_view tokenErrorName(TokenError cause) {
  switch (cause) {
    case TokenError::Malformed:
      return "malformed";
    case TokenError::BadSignature:
      return "bad_signature";
    case TokenError::Expired:
      return "expired";
    case TokenError::NotYetValid:
      return "not_yet_valid";
    case TokenError::Revoked:
      return "revoked";
    case TokenError::WrongScene:
      return "wrong_scene";
  }
  return "unknown";
}

std::string_view tokenRoleName(TokenRole role) {
  return role == TokenRole::Editor ? "editor" : "viewer";
}

Result<TokenRole> parseTokenRole(std::string_view name) {
  if (name == "viewer") return TokenRole::Viewer;
  if (name == "editor") return TokenRole::Editor;
  return Error{"unknown role '" + std::string(name) + "' (viewer or editor)"};
}

std::string tokenIdHex(const TokenId& id) { return hexEncode(id); }

Result<TokenId> parseTokenIdHex(std::string_view hex) {
  auto bytes = hexDecode(hex, kTokenIdBytes);
  if (!bytes) return Error{"token id: " + bytes.error().message};
  TokenId id;
  std::memcpy(id.data(), bytes->data(), id.size());
  return id;
}

TokenClaims newTokenClaims(std::string client, std::string scene, TokenRole role,
                           std::uint32_t weight, std::int64_t nowUnix, std::int64_t ttlSeconds) {
  TokenClaims c;
  randomBytes(c.id);
  c.client = std::move(client);
  c.scene = std::move(scene);
  c.role = role;
  c.weight = weight;
  c.issuedAt = nowUnix;
  c.expiresAt = nowUnix + ttlSeconds;
  return c;
}

Status checkTokenClaims(const TokenClaims& c) {
  if (c.client.empty() || c.client.size() > kMaxTokenClientBytes)
    return Error{"client name is " + std::to_string(c.client.size()) + " bytes (1..64)"};
  if (!printableAscii(c.client)) return Error{"client name has a non-printable character"};
  if (c.scene.empty() || c.scene.size() > kMaxTokenSceneBytes)
    return Error{"scene is " + std::to_string(c.scene.size()) + " bytes (1..128)"};
  if (!noControlBytes(c.scene)) return Error{"scene has a control character"};
  if (c.role != TokenRole::Viewer && c.role != TokenRole::Editor)
    return Error{"unknown role " + std::to_string(int(c.role))};
  if (c.weight < 1 || c.weight > kMaxTokenWeight)
    return Error{"weight " + std::to_string(c.weight) + " is outside 1..16"};
  if (c.expiresAt <= c.issuedAt)
    return Error{"expires at " + std::to_string(c.expiresAt) + ", not after it is issued (" +
                 std::to_string(c.issuedAt) + ")"};
  return Status::success();
}

SigningKey::~SigningKey() { sodium_memzero(bytes_.data(), bytes_.size()); }

VerifyKey SigningKey::verifyKey() const {
  VerifyKey v;
  crypto_sign_ed25519_sk_to_pk(v.bytes.data(), bytes_.data());
  return v;
}

KeyPair generateKeyPair() {
  std::array<std::uint8_t, 32> seed;
  randomBytes(seed);
  KeyPair pair = keyPairFromSeed(seed);
  sodium_memzero(seed.data(), seed.size());
  return pair;
}

KeyPair keyPairFromSeed(const std::array<std::uint8_t, 32>& seed) {
  ensureSodium();
  std::array<std::uint8_t, 64> secret;
  KeyPair pair;
  crypto_sign_seed_keypair(pair.verify.bytes.data(), secret.data(), seed.data());
  pair.signing = SigningKey(secret);
  sodium_memzero(secret.data(), secret.size());
  return pair;
}

std::string signingKeyText(const SigningKey& key) {
  return std::string(kSigningKeyTag) + base64Encode(key.bytes());
}

std::string verifyKeyText(const VerifyKey& key) {
  return std::string(kVerifyKeyTag) + base64Encode(key.bytes);
}

Result<SigningKey> parseSigningKey(std::string_view text) {
  auto bytes = parseKeyLine(text, kSigningKeyTag, 64);
  if (!bytes) return bytes.error();
  std::array<std::uint8_t, 64> secret;
  std::memcpy(secret.data(), bytes->data(), secret.size());
  sodium_memzero(bytes->data(), bytes->size());
  // libsodium's secret key is the seed and the public key: they must belong together, or
  // the tokens it signs would verify under no key.
  std::array<std::uint8_t, 32> seed;
  std::memcpy(seed.data(), secret.data(), seed.size());
  const KeyPair fromSeed = keyPairFromSeed(seed);
  sodium_memzero(seed.data(), seed.size());
  const bool matches = sodium_memcmp(fromSeed.signing.bytes().data(), secret.data(), 64) == 0;
  SigningKey key(secret);
  sodium_memzero(secret.data(), secret.size());
  if (!matches) return Error{"probecast-signing-key: its public half does not match its seed"};
  return key;
}

Result<VerifyKey> parseVerifyKey(std::string_view text) {
  auto bytes = parseKeyLine(text, kVerifyKeyTag, 32);
  if (!bytes) return bytes.error();
  VerifyKey key;
  std::memcpy(key.bytes.data(), bytes->data(), key.bytes.size());
  return key;
}

Result<SigningKey> loadSigningKey(const std::filesystem::path& path) {
  struct stat st;
  if (::stat(path.c_str(), &st) != 0)
    return Error{"signing key " + path.string() + ": " + std::strerror(errno)};
  if ((st.st_mode & 077) != 0) {
    char mode[8];
    std::snprintf(mode, sizeof mode, "%04o", unsigned(st.st_mode & 07777));
    return Error{"signing key " + path.string() + " is accessible by group or others (mode " +
                 mode + "): chmod 600 it"};
  }
  auto text = readSmallFile(path, kMaxKeyFileBytes);
  if (!text) return Error{"signing key: " + text.error().message};
  auto key = parseSigningKey(text.value());
  sodium_memzero(text->data(), text->size());
  if (!key) return Error{path.string() + ": " + key.error().message};
  return key;
}

Result<VerifyKey> loadVerifyKey(const std::filesystem::path& path) {
  auto text = readSmallFile(path, kMaxKeyFileBytes);
  if (!text) return Error{"verify key: " + text.error().message};
  auto key = parseVerifyKey(text.value());
  if (!key) return Error{path.string() + ": " + key.error().message};
  return key;
}

Result<SigningKey> signingKeyFromEnvironment(const char* name) {
  const char* value = std::getenv(name);
  if (value == nullptr) return Error{std::string("environment variable ") + name + " is not set"};
  auto key = parseSigningKey(value);
  if (!key) return Error{std::string("environment variable ") + name + ": " + key.error().message};
  return key;
}

Status writeKeyFile(const std::filesystem::path& path, const SigningKey& key) {
  std::string text = signingKeyText(key) + "\n";
  Status s = writeFileAtomically(path, text, 0600);
  sodium_memzero(text.data(), text.size());
  return s;
}

Status writeKeyFile(const std::filesystem::path& path, const VerifyKey& key) {
  return writeFileAtomically(path, verifyKeyText(key) + "\n", 0644);
}

Result<std::string> issueToken(const SigningKey& key, const TokenClaims& claims) {
  if (Status s = checkTokenClaims(claims); !s) return Error{"cannot issue: " + s.error().message};
  ensureSodium();
  const std::string binary = encodeClaims(claims);
  std::string token = std::string(kTokenPrefix) +
                      base64UrlEncode(std::span(
                          reinterpret_cast<const std::uint8_t*>(binary.data()), binary.size()));
  std::array<std::uint8_t, kSignatureBytes> signature;
  crypto_sign_detached(signature.data(), nullptr,
                       reinterpret_cast<const std::uint8_t*>(token.data()), token.size(),
                       key.bytes().data());
  token += '.';
  token += base64UrlEncode(signature);
  return token;
}

Result<TokenClaims> parseTokenUnverified(std::string_view token) {
  auto parts = splitToken(token);
  if (!parts) return parts.error();
  return std::move(parts->claims);
}

Result<std::set<TokenId>> loadRevocations(const std::filesystem::path& path) {
  auto text = readSmallFile(path, kMaxRevocationFileBytes);
  if (!text) return Error{"revocation list: " + text.error().message};
  std::set<TokenId> ids;
  std::string_view rest = text.value();
  for (int line = 1; !rest.empty(); ++line) {
    const std::size_t end = rest.find('\n');
    std::string_view l = rest.substr(0, end);
    rest = end == std::string_view::npos ? std::string_view() : rest.substr(end + 1);
    if (const std::size_t hash = l.find('#'); hash != std::string_view::npos) l = l.substr(0, hash);
    while (!l.empty() && (l.front() == ' ' || l.front() == '\t')) l.remove_prefix(1);
    while (!l.empty() && (l.back() == ' ' || l.back() == '\t' || l.back() == '\r'))
      l.remove_suffix(1);
    if (l.empty()) continue;
    auto id = parseTokenIdHex(l);
    if (!id) return Error{path.string() + ":" + std::to_string(line) + ": " + id.error().message};
    ids.insert(id.value());
  }
  return ids;
}

bool TokenVerifier::isRevoked(const TokenId& id) const {
  return revoked_.count(id) != 0 || listed_.count(id) != 0;
}

Status TokenVerifier::loadRevocations(const std::filesystem::path& path) {
  listPath_ = path;
  listStamp_.reset();
  auto reloaded = reloadRevocations();
  if (!reloaded) return reloaded.error();
  return Status::success();
}

Result<bool> TokenVerifier::reloadRevocations() {
  if (listPath_.empty()) return false;
  struct stat st;
  if (::stat(listPath_.c_str(), &st) != 0)
    return Error{"revocation list " + listPath_.string() + ": " + std::strerror(errno)};
  const FileStamp stamp{std::int64_t(st.st_mtim.tv_sec) * 1000000000 + st.st_mtim.tv_nsec,
                        std::uint64_t(st.st_size), std::uint64_t(st.st_ino)};
  if (listStamp_ && *listStamp_ == stamp) return false;
  auto ids = pc::loadRevocations(listPath_);
  if (!ids) return ids.error();
  listed_ = std::move(ids.value());
  listStamp_ = stamp;
  return true;
}

Result<TokenClaims> TokenVerifier::verify(std::string_view token, std::string_view scene,
                                          std::int64_t nowUnix, TokenError* cause) const {
  auto refuse = [&](TokenError why, std::string message) -> Result<TokenClaims> {
    if (cause) *cause = why;
    return Error{"token refused (" + std::string(tokenErrorName(why)) + "): " + message};
  };
  auto parts = splitToken(token);
  if (!parts) return refuse(TokenError::Malformed, parts.error().message);
  ensureSodium();
  bool authentic = false;
  for (const VerifyKey& key : keys_) {
    if (crypto_sign_verify_detached(parts->signature.data(),
                                    reinterpret_cast<const std::uint8_t*>(parts->signedText.data()),
                                    parts->signedText.size(), key.bytes.data()) == 0) {
      authentic = true;
      break;
    }
  }
  const TokenClaims& c = parts->claims;
  const std::string who = "token " + tokenIdHex(c.id) + " of client '" + c.client + "'";
  if (!authentic)
    return refuse(TokenError::BadSignature, who + " is signed by none of the " +
                                                std::to_string(keys_.size()) + " verify key(s)");
  if (isRevoked(c.id)) return refuse(TokenError::Revoked, who + " is revoked");
  if (c.issuedAt > nowUnix &&
      secondsBetween(nowUnix, c.issuedAt) > std::uint64_t(kTokenClockSkewSeconds))
    return refuse(TokenError::NotYetValid,
                  who + " is issued at " + std::to_string(c.issuedAt) + ", " +
                      std::to_string(secondsBetween(nowUnix, c.issuedAt)) +
                      " s in the future (more than the 60 s clock skew allowed)");
  if (nowUnix >= c.expiresAt)
    return refuse(TokenError::Expired, who + " expired at " + std::to_string(c.expiresAt) + ", " +
                                           std::to_string(secondsBetween(c.expiresAt, nowUnix)) +
                                           " s ago");
  if (c.scene != kAnyScene && c.scene != scene)
    return refuse(TokenError::WrongScene,
                  who + " is for scene '" + c.scene + "', not '" + std::string(scene) + "'");
  return std::move(parts->claims);
}

std::int64_t unixSeconds() {
  return std::chrono::duration_cast<std::chrono::seconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace pc
