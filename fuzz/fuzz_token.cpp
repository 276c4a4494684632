// Connect tokens (protocol/connect_token.h): TokenVerifier::verify and parseTokenUnverified on
// any text. The first input byte picks the mode, the scene asked for and the clock:
//   bit 0 clear: the rest is the token text, as a client would send it;
//   bit 0 set:   the rest is binary claims, which the target signs with the verify key's
//                signing key (libsodium directly, as PROTOCOL.md says), so that mutations get
//                past the signature to the claims parser and the time, revocation and scene
//                checks;
//   bits 1-2:    the scene asked for ("sponza", "cornell", "*", "");
//   bits 3-7:    the clock, kTokenNow + (value - 16) x 10 minutes.
// Checked: a refusal names its cause and the cause is one of the enum's; a token accepted
// parses to the same claims, and issuing those claims again gives the same text (Ed25519
// signatures are deterministic, the encoding canonical); a token the target signed is refused
// only as malformed (exactly when its claims do not parse) or for time, revocation or scene.
#include <sodium.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "fuzz_support.h"
#include "protocol/connect_token.h"
#include "protocol/secure_io.h"

namespace {

using namespace pc;

const TokenVerifier& verifier() {
  static const TokenVerifier v = [] {
    TokenVerifier t({fuzz::tokenKeys().verify});
    TokenId revoked;
    revoked.fill(0x0f);  // make_seeds issues one token with this id
    t.revoke(revoked);
    return t;
  }();
  return v;
}

std::string signClaims(const std::uint8_t* data, std::size_t size) {
  std::string token =
      std::string(kTokenPrefix) + base64UrlEncode(std::span<const std::uint8_t>(data, size));
  std::array<std::uint8_t, 64> signature;
  crypto_sign_detached(signature.data(), nullptr,
                       reinterpret_cast<const std::uint8_t*>(token.data()), token.size(),
                       fuzz::tokenKeys().signing.bytes().data());
  return token + "." + base64UrlEncode(signature);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::uint8_t mode = data[0];
  const bool signedHere = mode & 1;
  static const char* const kScenes[] = {"sponza", "cornell", "*", ""};
  const std::string scene = kScenes[(mode >> 1) & 3];
  const std::int64_t now = fuzz::kTokenNow + (std::int64_t(mode >> 3) - 16) * 600;
  const std::string token = signedHere
                                ? signClaims(data + 1, size - 1)
                                : std::string(reinterpret_cast<const char*>(data + 1), size - 1);

  TokenError cause = TokenError(255);
  Result<TokenClaims> verified = verifier().verify(token, scene, now, &cause);
  Result<TokenClaims> parsed = parseTokenUnverified(token);
  if (!verified) {
    if (std::size_t(cause) >= kTokenErrorCount) std::abort();
    const std::string label = "token refused (" + std::string(tokenErrorName(cause)) + "): ";
    if (verified.error().message.rfind(label, 0) != 0) std::abort();
    // Malformed exactly when the parser refuses it too.
    if ((cause == TokenError::Malformed) == parsed.ok()) std::abort();
    if (signedHere && cause == TokenError::BadSignature) std::abort();
    return 0;
  }
  if (!parsed || parsed->id != verified->id || parsed->client != verified->client ||
      parsed->scene != verified->scene || parsed->issuedAt != verified->issuedAt)
    std::abort();
  if (!checkTokenClaims(verified.value()).ok()) std::abort();
  Result<std::string> again = issueToken(fuzz::tokenKeys().signing, verified.value());
  if (!again || again.value() != token) std::abort();
  return 0;
}
