// probecast-token: makes the key pair that signs connect tokens, issues tokens, shows and
// checks them, and revokes them (protocol/connect_token.h; protocol/PROTOCOL.md, "Connect
// tokens"). Secrets come from files or the environment, never from the command line, where
// other users could read them (ps, /proc, shell history).
//
//   probecast-token keygen --signing-key signing.key --verify-key verify.key
//   probecast-token issue --signing-key signing.key --client alice --ttl 8h --output alice.token
//   probecast-token inspect alice.token --verify-key verify.key --scene sponza
//   probecast-token revoke --list revoked.txt alice.token
//
// Exit status: 0 done (inspect: the token is valid, or was not checked), 1 a failure or an
// invalid token (the message names what was wrong), 2 a usage error.
#include <CLI/CLI.hpp>
#include <cctype>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "protocol/connect_token.h"
#include "protocol/secure_io.h"
#include "tools/command_line.h"

namespace {

namespace fs = std::filesystem;
using namespace pc;

constexpr const char* kSigningKeyVariable = "PROBECAST_SIGNING_KEY";
constexpr std::int64_t kMaxTtlSeconds = 3650ll * 86400;  // ten years
constexpr std::size_t kMaxTokenFileBytes = 4096;

int fail(const std::string& message) {
  std::fprintf(stderr, "probecast-token: error: %s\n", message.c_str());
  return 1;
}

// "90", "3600s", "30m", "1h", "2d": seconds, 1 s .. 10 years.
std::optional<std::int64_t> parseTtl(const std::string& text) {
  std::size_t digits = 0;
  while (digits < text.size() && std::isdigit(static_cast<unsigned char>(text[digits]))) ++digits;
  if (digits == 0 || digits > 10 || text.size() > digits + 1) return std::nullopt;
  std::int64_t unit = 1;
  if (digits < text.size()) {
    switch (text[digits]) {
      case 's':
        unit = 1;
        break;
      case 'm':
        unit = 60;
        break;
      case 'h':
        unit = 3600;
        break;
      case 'd':
        unit = 86400;
        break;
      default:
        return std::nullopt;
    }
  }
  const std::int64_t seconds = std::stoll(text.substr(0, digits)) * unit;
  if (seconds < 1 || seconds > kMaxTtlSeconds) return std::nullopt;
  return seconds;
}

const CLI::Validator kTtl(
    [](std::string& text) -> std::string {
      if (parseTtl(text)) return {};
      return "expected a duration of 1 s to 3650 d such as 3600s, 30m, 24h or 2d, got '" + text +
             "'";
    },
    "DURATION");

std::string utcTime(std::int64_t unix) {
  const std::time_t t = std::time_t(unix);
  std::tm tm{};
  char text[32];
  if (gmtime_r(&t, &tm) == nullptr ||
      std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%SZ", &tm) == 0)
    return "(out of range)";
  return text;
}

// A token file: the token and at most one line ending after it.
Result<std::string> readTokenFile(const std::string& path) {
  auto text = readSmallFile(path, kMaxTokenFileBytes);
  if (!text) return text.error();
  std::string token = std::move(text.value());
  if (!token.empty() && token.back() == '\n') token.pop_back();
  if (!token.empty() && token.back() == '\r') token.pop_back();
  return token;
}

Result<SigningKey> signingKey(const std::string& path) {
  if (!path.empty()) return loadSigningKey(path);
  auto key = signingKeyFromEnvironment(kSigningKeyVariable);
  if (!key)
    return Error{"no signing key: give --signing-key FILE or set " +
                 std::string(kSigningKeyVariable) + " (" + key.error().message + ")"};
  return key;
}

struct KeygenArgs {
  std::string signingPath, verifyPath;
  bool force = false;
};

int keygen(const KeygenArgs& a) {
  if (fs::path(a.signingPath) == fs::path(a.verifyPath))
    return fail("--signing-key and --verify-key name the same file " + a.signingPath);
  for (const std::string& path : {a.signingPath, a.verifyPath}) {
    std::error_code ec;
    if (fs::exists(fs::symlink_status(path, ec)) && !a.force)
      return fail(path + " exists (--force to replace it)");
  }
  const KeyPair keys = generateKeyPair();
  if (Status s = writeKeyFile(a.signingPath, keys.signing); !s)
    return fail("signing key: " + s.error().message);
  if (Status s = writeKeyFile(a.verifyPath, keys.verify); !s)
    return fail("verify key: " + s.error().message);
  std::printf("wrote signing key %s (mode 0600: keep it secret) and verify key %s\n",
              a.signingPath.c_str(), a.verifyPath.c_str());
  return 0;
}

struct IssueArgs {
  std::string signingPath, client, scene = std::string(kAnyScene), role = "viewer", ttl = "24h",
                                   out;
  std::uint32_t weight = 1;
};

int issue(const IssueArgs& a) {
  auto key = signingKey(a.signingPath);
  if (!key) return fail(key.error().message);
  const TokenClaims claims = newTokenClaims(a.client, a.scene, parseTokenRole(a.role).value(),
                                            a.weight, unixSeconds(), *parseTtl(a.ttl));
  auto token = issueToken(key.value(), claims);
  if (!token) return fail(token.error().message);
  if (a.out.empty()) {
    std::printf("%s\n", token->c_str());
    return 0;
  }
  // A token admits its holder until it expires: as private as a password.
  if (Status s = writeFileAtomically(a.out, token.value() + "\n", 0600); !s)
    return fail(s.error().message);
  std::printf("wrote token %s for client '%s' to %s (expires %s)\n", tokenIdHex(claims.id).c_str(),
              claims.client.c_str(), a.out.c_str(), utcTime(claims.expiresAt).c_str());
  return 0;
}

struct InspectArgs {
  std::string tokenPath, scene, listPath;
  std::vector<std::string> verifyPaths;
};

int inspect(const InspectArgs& a) {
  auto token = readTokenFile(a.tokenPath);
  if (!token) return fail(token.error().message);
  auto claims = parseTokenUnverified(token.value());
  if (!claims) return fail(a.tokenPath + ": " + claims.error().message);
  const TokenClaims& c = claims.value();
  std::printf("id       %s\n", tokenIdHex(c.id).c_str());
  std::printf("client   %s\n", c.client.c_str());
  std::printf("scene    %s\n", c.scene.c_str());
  std::printf("role     %s\n", std::string(tokenRoleName(c.role)).c_str());
  std::printf("weight   %u\n", unsigned(c.weight));
  std::printf("issued   %s (%lld)\n", utcTime(c.issuedAt).c_str(), (long long)c.issuedAt);
  std::printf("expires  %s (%lld)\n", utcTime(c.expiresAt).c_str(), (long long)c.expiresAt);
  if (a.verifyPaths.empty()) {
    std::printf("status   not verified (give --verify-key)\n");
    return 0;
  }
  TokenVerifier verifier;
  for (const std::string& path : a.verifyPaths) {
    auto key = loadVerifyKey(path);
    if (!key) return fail(key.error().message);
    verifier.addKey(key.value());
  }
  if (!a.listPath.empty()) {
    if (Status s = verifier.loadRevocations(a.listPath); !s) return fail(s.error().message);
  }
  // Without --scene the token is checked for its own scene (any scene passes).
  TokenError cause = TokenError::Malformed;
  auto verified =
      verifier.verify(token.value(), a.scene.empty() ? c.scene : a.scene, unixSeconds(), &cause);
  if (!verified) {
    std::printf("status   invalid: %s\n", std::string(tokenErrorName(cause)).c_str());
    return fail(verified.error().message);
  }
  std::printf("status   valid\n");
  return 0;
}

struct RevokeArgs {
  std::string listPath, what;
};

int revoke(const RevokeArgs& a) {
  // An id, unless a file of that name exists; otherwise a token file (its id is read without
  // checking its signature: revoking anything is safe).
  std::error_code ec;
  TokenId id;
  std::string note;
  auto asId = parseTokenIdHex(a.what);
  if (asId && !fs::exists(a.what, ec)) {
    id = asId.value();
  } else {
    auto token = readTokenFile(a.what);
    if (!token)
      return fail(a.what + " is neither a token id (32 hex digits) nor a token file: " +
                  token.error().message);
    auto claims = parseTokenUnverified(token.value());
    if (!claims) return fail(a.what + ": " + claims.error().message);
    id = claims->id;
    note = "client " + claims->client + ", ";
  }
  std::string list;
  unsigned mode = 0644;
  if (fs::exists(a.listPath, ec)) {
    // Never append to a list the verifiers could not read.
    auto listed = loadRevocations(a.listPath);
    if (!listed) return fail(listed.error().message);
    if (listed->count(id)) {
      std::printf("%s is already revoked in %s\n", tokenIdHex(id).c_str(), a.listPath.c_str());
      return 0;
    }
    auto text = readSmallFile(a.listPath, std::size_t(16) << 20);
    if (!text) return fail(text.error().message);
    list = std::move(text.value());
    if (!list.empty() && list.back() != '\n') list += '\n';
    mode = unsigned(fs::status(a.listPath, ec).permissions()) & 0777;
  }
  list += tokenIdHex(id) + "  # " + note + "revoked " + utcTime(unixSeconds()) + "\n";
  // Replaced whole, so that a verifier reloading it never reads half a line.
  if (Status s = writeFileAtomically(a.listPath, list, mode); !s) return fail(s.error().message);
  std::printf("revoked %s in %s\n", tokenIdHex(id).c_str(), a.listPath.c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "Connect tokens: make the signing key pair, issue tokens, inspect and verify them, revoke "
      "them. The signing key is read from a file (mode 0600) or the environment variable " +
      std::string(kSigningKeyVariable) + " (its key line), never from the command line."};
  app.require_subcommand(1);

  KeygenArgs k;
  CLI::App* keygenCmd = app.add_subcommand("keygen", "make a new signing key and verify key");
  keygenCmd->add_option("--signing-key", k.signingPath, "secret key file to write (mode 0600)")
      ->required();
  keygenCmd->add_option("--verify-key", k.verifyPath, "public key file to write (mode 0644)")
      ->required();
  keygenCmd->add_flag("--force", k.force, "replace existing key files");

  IssueArgs i;
  CLI::App* issueCmd = app.add_subcommand("issue", "issue a signed token");
  issueCmd->add_option(
      "--signing-key", i.signingPath,
      std::string("signing key file (else the environment variable ") + kSigningKeyVariable + ")");
  issueCmd->add_option("--client", i.client, "client name (1..64 printable ASCII characters)")
      ->required();
  issueCmd->add_option("--scene", i.scene, "the scene it admits to, or * for any");
  issueCmd->add_option("--role", i.role, "viewer or editor")
      ->check(CLI::IsMember({"viewer", "editor"}));
  issueCmd->add_option("--weight", i.weight, "share of the server relative to other clients")
      ->check(CLI::Range(1u, kMaxTokenWeight));
  issueCmd->add_option("--ttl", i.ttl, "time to live: seconds, or with s, m, h or d")->check(kTtl);
  // Files are -o/--output and folders --out in every tool; --out named this file before.
  issueCmd->add_option("-o,--output", i.out,
                       "write the token to this file (mode 0600), not stdout");
  issueCmd->add_option("--out", i.out, "deprecated: -o/--output FILE")->group("Deprecated");

  InspectArgs n;
  CLI::App* inspectCmd =
      app.add_subcommand("inspect", "show a token's claims; verify it with --verify-key");
  inspectCmd->add_option("TOKEN-FILE", n.tokenPath, "file holding the token")->required();
  inspectCmd->add_option("--verify-key", n.verifyPaths,
                         "verify key file (repeat for keys in rotation); exit 1 if invalid");
  inspectCmd->add_option("--scene", n.scene,
                         "the scene it must admit to (default: the token's own)");
  inspectCmd->add_option("--list", n.listPath, "revocation list to check it against");

  RevokeArgs r;
  CLI::App* revokeCmd = app.add_subcommand("revoke", "add a token's id to a revocation list");
  revokeCmd->add_option("--list", r.listPath, "revocation list file (created if missing)")
      ->required();
  revokeCmd->add_option("TOKEN-FILE|ID", r.what, "a token file, or a token id (32 hex digits)")
      ->required();

  // Usage errors exit 2 here (1 means a failure or an invalid token).
  if (auto code = pc::parseCommandLine(app, argc, argv)) return *code == 0 ? 0 : 2;
  if (keygenCmd->parsed()) return keygen(k);
  if (issueCmd->parsed()) return issue(i);
  if (inspectCmd->parsed()) return inspect(n);
  if (revokeCmd->parsed()) return revoke(r);
  return 2;
}
