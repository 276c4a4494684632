// Connect tokens (protocol/connect_token.h): issue and verify round trips, every way a token
// is refused with its cause (any changed byte, another key, expiry, a token from the future,
// revocation and its reload, another scene), strict parsing of hand-made claims signed with
// the right key, and key files (their form, and a signing key others may read refused).
#include <gtest/gtest.h>
#include <sodium.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include "protocol/connect_token.h"
#include "protocol/secure_io.h"

namespace {

using namespace pc;
namespace fs = std::filesystem;

constexpr std::int64_t kNow = 1'800'000'000;

bool contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

KeyPair fixedKeys(std::uint8_t seedByte) {
  std::array<std::uint8_t, 32> seed;
  seed.fill(seedByte);
  return keyPairFromSeed(seed);
}

TokenClaims aliceClaims(std::string scene = "*") {
  return newTokenClaims("alice", std::move(scene), TokenRole::Viewer, 1, kNow, 3600);
}

std::string issue(const KeyPair& keys, const TokenClaims& claims) {
  auto token = issueToken(keys.signing, claims);
  EXPECT_TRUE(token.ok()) << token.error().message;
  return token.ok() ? token.value() : std::string();
}

// The verdict and cause of one verification.
struct Verdict {
  bool ok = false;
  TokenError cause = TokenError::Malformed;
  std::string message;
};
Verdict check(const TokenVerifier& v, std::string_view token, std::string_view scene = "sponza",
              std::int64_t now = kNow) {
  Verdict out;
  auto r = v.verify(token, scene, now, &out.cause);
  out.ok = r.ok();
  if (!r) out.message = r.error().message;
  return out;
}

// The binary claims laid out as PROTOCOL.md says, written independently of the library.
std::vector<std::uint8_t> claimsBytes(std::uint8_t role, std::uint8_t weight,
                                      const std::string& client, const std::string& scene,
                                      std::int64_t issued = kNow,
                                      std::int64_t expires = kNow + 60) {
  std::vector<std::uint8_t> b(16, 0xab);
  for (std::int64_t v : {issued, expires})
    for (int i = 0; i < 8; ++i) b.push_back(std::uint8_t(std::uint64_t(v) >> (8 * i)));
  b.push_back(role);
  b.push_back(weight);
  b.push_back(std::uint8_t(client.size()));
  b.insert(b.end(), client.begin(), client.end());
  b.push_back(std::uint8_t(scene.size()));
  b.insert(b.end(), scene.begin(), scene.end());
  return b;
}

// A token for any claim bytes, signed as the format says (Ed25519 over "pct1.<claims>").
std::string signRaw(const KeyPair& keys, const std::vector<std::uint8_t>& claims) {
  std::string token = "pct1." + base64UrlEncode(claims);
  std::array<std::uint8_t, 64> sig;
  crypto_sign_detached(sig.data(), nullptr, reinterpret_cast<const std::uint8_t*>(token.data()),
                       token.size(), keys.signing.bytes().data());
  return token + "." + base64UrlEncode(sig);
}

class TokenFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           ("pc_test_token_" + std::to_string(::getpid()) + "_" + info->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  void writeText(const fs::path& p, const std::string& text) {
    std::ofstream(p, std::ios::trunc) << text;
  }
  fs::path dir_;
};

TEST(ConnectToken, IssuedTokenVerifiesToTheSameClaims) {
  const KeyPair keys = fixedKeys(1);
  TokenClaims claims = newTokenClaims("render-farm-7", "sponza", TokenRole::Editor, 16, kNow, 90);
  const std::string token = issue(keys, claims);
  EXPECT_EQ(token.rfind("pct1.", 0), 0u);
  EXPECT_LE(token.size(), kMaxTokenChars);
  EXPECT_EQ(std::count(token.begin(), token.end(), '.'), 2);

  TokenVerifier verifier({keys.verify});
  TokenError cause = TokenError::Revoked;
  auto got = verifier.verify(token, "sponza", kNow, &cause);
  ASSERT_TRUE(got.ok()) << got.error().message;
  EXPECT_EQ(cause, TokenError::Revoked) << "cause is only written on a refusal";
  EXPECT_EQ(got->id, claims.id);
  EXPECT_EQ(got->client, "render-farm-7");
  EXPECT_EQ(got->scene, "sponza");
  EXPECT_EQ(got->role, TokenRole::Editor);
  EXPECT_EQ(got->weight, 16u);
  EXPECT_EQ(got->issuedAt, kNow);
  EXPECT_EQ(got->expiresAt, kNow + 90);
  auto unverified = parseTokenUnverified(token);
  ASSERT_TRUE(unverified.ok());
  EXPECT_EQ(unverified->id, claims.id);

  // Ids are random: two tokens of the same claims differ.
  EXPECT_NE(newTokenClaims("a", "*", TokenRole::Viewer, 1, kNow, 1).id,
            newTokenClaims("a", "*", TokenRole::Viewer, 1, kNow, 1).id);
  EXPECT_EQ(tokenIdHex(claims.id).size(), 32u);
  auto id = parseTokenIdHex(tokenIdHex(claims.id));
  ASSERT_TRUE(id.ok());
  EXPECT_EQ(id.value(), claims.id);
  EXPECT_FALSE(parseTokenIdHex("0123").ok());
  EXPECT_FALSE(parseTokenIdHex(std::string(31, '0') + "g").ok());
}

TEST(ConnectToken, LargestClaimsFitTheTokenLimit) {
  const KeyPair keys = fixedKeys(1);
  const std::string token = issue(keys, newTokenClaims(std::string(64, '~'), std::string(128, 's'),
                                                       TokenRole::Editor, 16, kNow, 1));
  EXPECT_EQ(token.size(), 396u) << "as PROTOCOL.md says";
  TokenVerifier verifier({keys.verify});
  EXPECT_TRUE(check(verifier, token, std::string(128, 's')).ok);
}

TEST(ConnectToken, EverySingleByteChangeIsRefused) {
  const KeyPair keys = fixedKeys(2);
  const std::string token = issue(keys, aliceClaims());
  TokenVerifier verifier({keys.verify});
  ASSERT_TRUE(check(verifier, token).ok);
  const std::string replacements =
      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789-_.=+/ \n";
  int tried = 0, malformed = 0, badSignature = 0;
  for (std::size_t i = 0; i < token.size(); ++i) {
    for (char c : replacements + std::string("\0\x80\xff", 3)) {
      if (c == token[i]) continue;
      std::string changed = token;
      changed[i] = c;
      const Verdict v = check(verifier, changed);
      ASSERT_FALSE(v.ok) << "byte " << i << " changed to '" << c << "' was accepted";
      ASSERT_TRUE(v.cause == TokenError::Malformed || v.cause == TokenError::BadSignature)
          << v.message;
      ++tried;
      (v.cause == TokenError::Malformed ? malformed : badSignature)++;
    }
  }
  EXPECT_GE(tried, int(token.size()) * 70);
  EXPECT_GT(malformed, 0);
  EXPECT_GT(badSignature, 0);
}

TEST(ConnectToken, OnlyTheVerifierKeysAccept) {
  const KeyPair issuer = fixedKeys(3), other = fixedKeys(4);
  const std::string token = issue(issuer, aliceClaims());
  TokenVerifier wrong({other.verify});
  const Verdict v = check(wrong, token);
  EXPECT_FALSE(v.ok);
  EXPECT_EQ(v.cause, TokenError::BadSignature);
  EXPECT_TRUE(contains(v.message, "bad_signature")) << v.message;
  EXPECT_TRUE(contains(v.message, "alice")) << v.message;
  // Key rotation: the new key and the old one both accepted while both are listed.
  wrong.addKey(issuer.verify);
  EXPECT_EQ(wrong.keyCount(), 2u);
  EXPECT_TRUE(check(wrong, token).ok);
  EXPECT_TRUE(check(wrong, issue(other, aliceClaims())).ok);
  // No keys: nothing is authentic.
  EXPECT_EQ(check(TokenVerifier(), token).cause, TokenError::BadSignature);
}

TEST(ConnectToken, ExpiredAtItsExpiryTime) {
  const KeyPair keys = fixedKeys(5);
  const TokenClaims claims = aliceClaims();
  const std::string token = issue(keys, claims);
  TokenVerifier verifier({keys.verify});
  EXPECT_TRUE(check(verifier, token, "x", claims.expiresAt - 1).ok);
  const Verdict v = check(verifier, token, "x", claims.expiresAt);
  EXPECT_FALSE(v.ok);
  EXPECT_EQ(v.cause, TokenError::Expired);
  EXPECT_TRUE(contains(v.message, "expired at 1800003600, 0 s ago")) << v.message;
  EXPECT_EQ(check(verifier, token, "x", claims.expiresAt + 86400).cause, TokenError::Expired);
}

TEST(ConnectToken, IssuedInTheFutureBeyondTheClockSkew) {
  const KeyPair keys = fixedKeys(6);
  const std::string token = issue(keys, aliceClaims());
  TokenVerifier verifier({keys.verify});
  EXPECT_TRUE(check(verifier, token, "x", kNow - kTokenClockSkewSeconds).ok);
  const Verdict v = check(verifier, token, "x", kNow - kTokenClockSkewSeconds - 1);
  EXPECT_FALSE(v.ok);
  EXPECT_EQ(v.cause, TokenError::NotYetValid);
  EXPECT_TRUE(contains(v.message, "61 s in the future")) << v.message;
  // Extreme clocks on either side give a cause, not an overflow.
  EXPECT_EQ(check(verifier, token, "x", INT64_MIN).cause, TokenError::NotYetValid);
  EXPECT_EQ(check(verifier, token, "x", INT64_MAX).cause, TokenError::Expired);
}

TEST(ConnectToken, SceneMustMatchUnlessAny) {
  const KeyPair keys = fixedKeys(7);
  TokenVerifier verifier({keys.verify});
  const std::string sponza = issue(keys, aliceClaims("sponza"));
  EXPECT_TRUE(check(verifier, sponza, "sponza").ok);
  const Verdict v = check(verifier, sponza, "cornell");
  EXPECT_FALSE(v.ok);
  EXPECT_EQ(v.cause, TokenError::WrongScene);
  EXPECT_TRUE(contains(v.message, "for scene 'sponza', not 'cornell'")) << v.message;
  EXPECT_EQ(check(verifier, sponza, "sponza2").cause, TokenError::WrongScene);
  const std::string any = issue(keys, aliceClaims("*"));
  EXPECT_TRUE(check(verifier, any, "sponza").ok);
  EXPECT_TRUE(check(verifier, any, "cornell").ok);
}

TEST(ConnectToken, CauseNamesAreMetricLabels) {
  EXPECT_EQ(tokenErrorName(TokenError::Malformed), "malformed");
  EXPECT_EQ(tokenErrorName(TokenError::BadSignature), "bad_signature");
  EXPECT_EQ(tokenErrorName(TokenError::Expired), "expired");
  EXPECT_EQ(tokenErrorName(TokenError::NotYetValid), "not_yet_valid");
  EXPECT_EQ(tokenErrorName(TokenError::Revoked), "revoked");
  EXPECT_EQ(tokenErrorName(TokenError::WrongScene), "wrong_scene");
}

TEST(ConnectToken, TruncatedOversizedAndGarbageTokensAreMalformed) {
  const KeyPair keys = fixedKeys(8);
  const std::string token = issue(keys, aliceClaims());
  TokenVerifier verifier({keys.verify});
  for (std::size_t n = 0; n < token.size(); ++n) {
    const Verdict v = check(verifier, token.substr(0, n));
    ASSERT_FALSE(v.ok) << "a token cut to " << n << " characters was accepted";
    ASSERT_EQ(v.cause, TokenError::Malformed) << n << ": " << v.message;
  }
  auto malformed = [&](const std::string& t, const std::string& why) {
    const Verdict v = check(verifier, t);
    EXPECT_FALSE(v.ok) << t;
    EXPECT_EQ(v.cause, TokenError::Malformed) << v.message;
    EXPECT_TRUE(contains(v.message, why)) << v.message;
  };
  malformed(token + "\n", "signature");
  malformed(token + "A", "signature");
  malformed(token + ".", "signature");
  malformed(" " + token, "does not start with 'pct1.'");
  malformed("pct2" + token.substr(4), "does not start with 'pct1.'");
  malformed(token + std::string(kMaxTokenChars, 'A'), "more than 1024");
  malformed("pct1.", "no signature part");
  malformed("pct1..", "signature is 0 bytes, not 64");
  malformed("pct1.AAAA", "no signature part");
  // Padding is not part of base64url as tokens use it.
  const std::size_t dot = token.rfind('.');
  malformed(token.substr(0, dot) + "=" + token.substr(dot), "base64url");
  std::mt19937 rng(7);
  for (int i = 0; i < 2000; ++i) {
    std::string garbage = "pct1.";
    const std::size_t n = rng() % 400;
    for (std::size_t k = 0; k < n; ++k) garbage.push_back(char(rng()));
    ASSERT_FALSE(check(verifier, garbage).ok);
    ASSERT_FALSE(parseTokenUnverified(garbage).ok());
  }
}

TEST(ConnectToken, SignedClaimsOutOfRangeAreMalformed) {
  const KeyPair keys = fixedKeys(9);
  TokenVerifier verifier({keys.verify});
  // The hand-made layout verifies: the test's layout is the library's.
  const Verdict good = check(verifier, signRaw(keys, claimsBytes(1, 1, "alice", "*")));
  ASSERT_TRUE(good.ok) << good.message;
  EXPECT_TRUE(check(verifier, signRaw(keys, claimsBytes(2, 16, " ~", "scene x")), "scene x").ok);

  auto malformed = [&](const std::vector<std::uint8_t>& claims, const std::string& why) {
    const Verdict v = check(verifier, signRaw(keys, claims));
    EXPECT_FALSE(v.ok) << why;
    EXPECT_EQ(v.cause, TokenError::Malformed) << v.message;
    EXPECT_TRUE(contains(v.message, why)) << v.message;
  };
  std::vector<std::uint8_t> trailing = claimsBytes(1, 1, "alice", "*");
  trailing.push_back(0);
  malformed(trailing, "1 bytes after the claims");
  std::vector<std::uint8_t> cut = claimsBytes(1, 1, "alice", "*");
  cut.pop_back();
  malformed(cut, "claims end early");
  malformed(std::vector<std::uint8_t>(35, 0), "claims end early");
  malformed(claimsBytes(0, 1, "alice", "*"), "unknown role 0");
  malformed(claimsBytes(3, 1, "alice", "*"), "unknown role 3");
  malformed(claimsBytes(1, 0, "alice", "*"), "weight 0 is outside 1..16");
  malformed(claimsBytes(1, 17, "alice", "*"), "weight 17 is outside 1..16");
  malformed(claimsBytes(1, 1, "", "*"), "client name is 0 bytes");
  malformed(claimsBytes(1, 1, std::string(65, 'a'), "*"), "client name is 65 bytes");
  malformed(claimsBytes(1, 1, "al\tice", "*"), "non-printable");
  malformed(claimsBytes(1, 1, "al\x7f", "*"), "non-printable");
  malformed(claimsBytes(1, 1, "\xc3\xa9", "*"), "non-printable");
  malformed(claimsBytes(1, 1, "alice", ""), "scene is 0 bytes");
  malformed(claimsBytes(1, 1, "alice", std::string(129, 's')), "scene is 129 bytes");
  malformed(claimsBytes(1, 1, "alice", "a\nb"), "control character");
  malformed(claimsBytes(1, 1, "alice", "*", kNow, kNow), "not after it is issued");

  // The issuer refuses the same claims before signing them.
  TokenClaims bad = aliceClaims();
  bad.weight = 0;
  auto refused = issueToken(keys.signing, bad);
  ASSERT_FALSE(refused.ok());
  EXPECT_TRUE(contains(refused.error().message, "cannot issue: weight 0"))
      << refused.error().message;
  bad = aliceClaims();
  bad.client = std::string(65, 'x');
  EXPECT_FALSE(issueToken(keys.signing, bad).ok());
}

TEST_F(TokenFiles, RevokedTokensAndTheListReloaded) {
  const KeyPair keys = fixedKeys(10);
  const TokenClaims aliceC = aliceClaims(),
                    bobC = newTokenClaims("bob", "*", TokenRole::Viewer, 1, kNow, 60);
  const std::string alice = issue(keys, aliceC), bob = issue(keys, bobC);
  const fs::path list = dir_ / "revoked.txt";
  writeText(list,
            "# revoked by the operator\n\n  " + tokenIdHex(aliceC.id) + "  # alice's laptop\n");
  TokenVerifier verifier({keys.verify});
  Status loaded = verifier.loadRevocations(list);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_EQ(verifier.revokedCount(), 1u);
  const Verdict v = check(verifier, alice);
  EXPECT_FALSE(v.ok);
  EXPECT_EQ(v.cause, TokenError::Revoked);
  EXPECT_TRUE(contains(v.message, tokenIdHex(aliceC.id) + " of client 'alice' is revoked"))
      << v.message;
  EXPECT_TRUE(check(verifier, bob).ok);

  // Unchanged file: nothing read.
  auto again = verifier.reloadRevocations();
  ASSERT_TRUE(again.ok());
  EXPECT_FALSE(again.value());

  // The operator replaces the list: bob revoked, alice no longer.
  writeText(list, tokenIdHex(bobC.id) + "\n");
  fs::last_write_time(list, fs::last_write_time(list) + std::chrono::seconds(1));
  auto reloaded = verifier.reloadRevocations();
  ASSERT_TRUE(reloaded.ok()) << reloaded.error().message;
  EXPECT_TRUE(reloaded.value());
  EXPECT_TRUE(check(verifier, alice).ok);
  EXPECT_EQ(check(verifier, bob).cause, TokenError::Revoked);

  // A broken list changes nothing and names the line; fixed, it is read on the next reload.
  writeText(list, tokenIdHex(aliceC.id) + "\nnot-an-id\n");
  fs::last_write_time(list, fs::last_write_time(list) + std::chrono::seconds(2));
  auto broken = verifier.reloadRevocations();
  ASSERT_FALSE(broken.ok());
  EXPECT_TRUE(contains(broken.error().message, "revoked.txt:2: token id"))
      << broken.error().message;
  EXPECT_EQ(check(verifier, bob).cause, TokenError::Revoked);
  EXPECT_TRUE(check(verifier, alice).ok);
  writeText(list, tokenIdHex(aliceC.id) + "\n" + tokenIdHex(bobC.id) + "\n");
  auto fixed = verifier.reloadRevocations();
  ASSERT_TRUE(fixed.ok());
  EXPECT_TRUE(fixed.value());
  EXPECT_EQ(check(verifier, alice).cause, TokenError::Revoked);

  // A revocation the verifier was told directly survives reloads of the file.
  writeText(list, "# empty\n");
  const TokenClaims carolC = aliceClaims();
  verifier.revoke(carolC.id);
  ASSERT_TRUE(verifier.reloadRevocations().ok());
  EXPECT_TRUE(check(verifier, alice).ok);
  EXPECT_EQ(check(verifier, issue(keys, carolC)).cause, TokenError::Revoked);

  // A missing list is an error naming it, and keeps what was revoked.
  fs::remove(list);
  auto missing = verifier.reloadRevocations();
  ASSERT_FALSE(missing.ok());
  EXPECT_TRUE(contains(missing.error().message, "revoked.txt")) << missing.error().message;
  EXPECT_FALSE(verifier.loadRevocations(dir_ / "nothing.txt").ok());
}

TEST_F(TokenFiles, KeyFilesRoundTripWithTheirModes) {
  const KeyPair keys = generateKeyPair();
  EXPECT_EQ(keys.signing.verifyKey(), keys.verify);
  const fs::path secret = dir_ / "signing.key", pub = dir_ / "verify.key";
  ASSERT_TRUE(writeKeyFile(secret, keys.signing).ok());
  ASSERT_TRUE(writeKeyFile(pub, keys.verify).ok());
  struct stat st;
  ASSERT_EQ(::stat(secret.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  ASSERT_EQ(::stat(pub.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0644u);

  auto text = readSmallFile(secret, 4096);
  ASSERT_TRUE(text.ok());
  EXPECT_EQ(text->rfind("probecast-signing-key v1 ", 0), 0u);
  EXPECT_EQ(text->back(), '\n');
  EXPECT_EQ(std::count(text->begin(), text->end(), '\n'), 1);
  auto pubText = readSmallFile(pub, 4096);
  ASSERT_TRUE(pubText.ok());
  EXPECT_EQ(pubText->rfind("probecast-verify-key v1 ", 0), 0u);

  auto loaded = loadSigningKey(secret);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_EQ(loaded->bytes(), keys.signing.bytes());
  auto loadedPub = loadVerifyKey(pub);
  ASSERT_TRUE(loadedPub.ok()) << loadedPub.error().message;
  EXPECT_EQ(loadedPub.value(), keys.verify);
  // A token signed with the loaded key verifies with the loaded verify key.
  TokenVerifier verifier({loadedPub.value()});
  auto token = issueToken(loaded.value(), aliceClaims());
  ASSERT_TRUE(token.ok());
  EXPECT_TRUE(check(verifier, token.value()).ok);

  // Overwriting replaces the file whole.
  const KeyPair next = generateKeyPair();
  ASSERT_TRUE(writeKeyFile(secret, next.signing).ok());
  EXPECT_EQ(loadSigningKey(secret)->bytes(), next.signing.bytes());
  EXPECT_FALSE(writeKeyFile(dir_ / "no-such-dir" / "k", next.verify).ok());
}

TEST_F(TokenFiles, SigningKeyOthersCanReadIsRefused) {
  const KeyPair keys = generateKeyPair();
  const fs::path secret = dir_ / "signing.key";
  ASSERT_TRUE(writeKeyFile(secret, keys.signing).ok());
  for (unsigned mode : {0640u, 0604u, 0660u, 0610u}) {
    ASSERT_EQ(::chmod(secret.c_str(), mode), 0);
    auto refused = loadSigningKey(secret);
    ASSERT_FALSE(refused.ok()) << std::oct << mode;
    EXPECT_TRUE(contains(refused.error().message, "is accessible by group or others"))
        << refused.error().message;
    EXPECT_TRUE(contains(refused.error().message, "chmod 600")) << refused.error().message;
  }
  ASSERT_EQ(::chmod(secret.c_str(), 0400), 0);
  EXPECT_TRUE(loadSigningKey(secret).ok());
  auto missing = loadSigningKey(dir_ / "absent.key");
  ASSERT_FALSE(missing.ok());
  EXPECT_TRUE(contains(missing.error().message, "absent.key")) << missing.error().message;
}

TEST_F(TokenFiles, BrokenKeyTextIsRefused) {
  const KeyPair keys = fixedKeys(11);
  const std::string line = signingKeyText(keys.signing);
  EXPECT_TRUE(parseSigningKey(line).ok());
  EXPECT_TRUE(parseSigningKey(line + "\n").ok());
  EXPECT_FALSE(parseSigningKey(line + "\n\n").ok());
  EXPECT_FALSE(parseSigningKey(line + " ").ok());
  EXPECT_FALSE(parseSigningKey(line.substr(0, line.size() - 4)).ok());
  // A verify key where a signing key belongs, and the reverse.
  auto swapped = parseSigningKey(verifyKeyText(keys.verify));
  ASSERT_FALSE(swapped.ok());
  EXPECT_TRUE(contains(swapped.error().message, "probecast-signing-key"))
      << swapped.error().message;
  EXPECT_FALSE(parseVerifyKey(line).ok());
  EXPECT_TRUE(parseVerifyKey(verifyKeyText(keys.verify)).ok());
  // A secret key whose public half belongs to another seed.
  std::array<std::uint8_t, 64> mixed = keys.signing.bytes();
  const KeyPair other = fixedKeys(12);
  std::copy(other.verify.bytes.begin(), other.verify.bytes.end(), mixed.begin() + 32);
  auto mismatch = parseSigningKey(signingKeyText(SigningKey(mixed)));
  ASSERT_FALSE(mismatch.ok());
  EXPECT_TRUE(contains(mismatch.error().message, "does not match")) << mismatch.error().message;

  // From the environment (never from the command line).
  ::setenv("PC_TEST_SIGNING_KEY", line.c_str(), 1);
  auto fromEnv = signingKeyFromEnvironment("PC_TEST_SIGNING_KEY");
  ASSERT_TRUE(fromEnv.ok()) << fromEnv.error().message;
  EXPECT_EQ(fromEnv->bytes(), keys.signing.bytes());
  ::unsetenv("PC_TEST_SIGNING_KEY");
  auto unset = signingKeyFromEnvironment("PC_TEST_SIGNING_KEY");
  ASSERT_FALSE(unset.ok());
  EXPECT_TRUE(contains(unset.error().message, "PC_TEST_SIGNING_KEY is not set"));
}

}  // namespace
