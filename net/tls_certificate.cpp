// Certificates: the development self-signed certificate, fingerprints, OpenSSL's errors.
#include "net/tls_certificate.h"

#include <openssl/err.h>
#include <openssl/evp.h>
#include <openssl/pem.h>
#include <openssl/rand.h>
#include <openssl/x509v3.h>

#include <cstdio>
#include <fstream>

namespace pc::net {

std::string openSslErrors() {
  std::string text;
  while (unsigned long e = ERR_get_error()) {
    char buffer[256];
    ERR_error_string_n(e, buffer, sizeof buffer);
    if (!text.empty()) text += "; ";
    text += buffer;
  }
  return text.empty() ? "no OpenSSL error recorded" : text;
}

std::array<std::uint8_t, 32> certificateDigest(X509* certificate) {
  std::array<std::uint8_t, 32> digest{};
  unsigned int size = 0;
  X509_digest(certificate, EVP_sha256(), digest.data(), &size);
  return digest;
}

std::string formatFingerprint(const std::array<std::uint8_t, 32>& digest) {
  static const char* hex = "0123456789abcdef";
  std::string text = "sha256:";
  for (std::uint8_t b : digest) {
    text += hex[b >> 4];
    text += hex[b & 15];
  }
  return text;
}

Result<std::array<std::uint8_t, 32>> parseFingerprint(const std::string& text) {
  std::string_view s = text;
  if (s.starts_with("sha256:")) s.remove_prefix(7);
  std::string digits;
  for (char c : s) {
    if (c == ':') continue;
    if (!std::isxdigit(static_cast<unsigned char>(c)))
      return Error{"fingerprint '" + text.substr(0, 80) + "': not hexadecimal"};
    digits += char(std::tolower(static_cast<unsigned char>(c)));
  }
  if (digits.size() != 64) {
    return Error{"fingerprint '" + text.substr(0, 80) + "': " + std::to_string(digits.size()) +
                 " hex digits, a SHA-256 has 64"};
  }
  std::array<std::uint8_t, 32> digest{};
  for (std::size_t i = 0; i < 32; ++i)
    digest[i] = std::uint8_t(std::stoi(digits.substr(2 * i, 2), nullptr, 16));
  return digest;
}

namespace {

template <class T, void (*Free)(T*)>
struct Deleter {
  void operator()(T* p) const { Free(p); }
};
using KeyPtr = std::unique_ptr<EVP_PKEY, Deleter<EVP_PKEY, EVP_PKEY_free>>;
using CertPtr = std::unique_ptr<X509, Deleter<X509, X509_free>>;
using ExtPtr = std::unique_ptr<X509_EXTENSION, Deleter<X509_EXTENSION, X509_EXTENSION_free>>;

Status addExtension(X509* cert, int nid, const char* value) {
  X509V3_CTX ctx;
  X509V3_set_ctx_nodb(&ctx);
  X509V3_set_ctx(&ctx, cert, cert, nullptr, nullptr, 0);
  ExtPtr ext(X509V3_EXT_conf_nid(nullptr, &ctx, nid, value));
  if (!ext || !X509_add_ext(cert, ext.get(), -1))
    return Error{std::string("certificate extension ") + value + ": " + openSslErrors()};
  return Status::success();
}

}  // namespace

Result<DevCertificate> makeDevCertificate() {
  KeyPtr key(EVP_EC_gen("P-256"));
  if (!key) return Error{"generating a P-256 key: " + openSslErrors()};
  CertPtr cert(X509_new());
  if (!cert) return Error{"X509_new: " + openSslErrors()};
  X509_set_version(cert.get(), 2);
  std::uint8_t serial[16];
  RAND_bytes(serial, sizeof serial);
  serial[0] &= 0x7f;  // a positive serial number
  BIGNUM* bn = BN_bin2bn(serial, sizeof serial, nullptr);
  BN_to_ASN1_INTEGER(bn, X509_get_serialNumber(cert.get()));
  BN_free(bn);
  X509_gmtime_adj(X509_getm_notBefore(cert.get()), -3600);
  X509_gmtime_adj(X509_getm_notAfter(cert.get()), 30L * 24 * 3600);
  X509_set_pubkey(cert.get(), key.get());
  X509_NAME* name = X509_get_subject_name(cert.get());
  X509_NAME_add_entry_by_txt(name, "CN", MBSTRING_ASC,
                             reinterpret_cast<const unsigned char*>("probecast development"), -1,
                             -1, 0);
  X509_set_issuer_name(cert.get(), name);
  if (Status s =
          addExtension(cert.get(), NID_subject_alt_name, "DNS:localhost,IP:127.0.0.1,IP:::1");
      !s)
    return s.error();
  if (Status s = addExtension(cert.get(), NID_basic_constraints, "critical,CA:TRUE"); !s)
    return s.error();
  if (Status s = addExtension(cert.get(), NID_key_usage, "critical,digitalSignature,keyCertSign");
      !s)
    return s.error();
  if (!X509_sign(cert.get(), key.get(), EVP_sha256()))
    return Error{"signing the certificate: " + openSslErrors()};

  DevCertificate out;
  BIO* bio = BIO_new(BIO_s_mem());
  PEM_write_bio_X509(bio, cert.get());
  char* data = nullptr;
  long size = BIO_get_mem_data(bio, &data);
  out.certificatePem.assign(data, std::size_t(size));
  BIO_free(bio);
  bio = BIO_new(BIO_s_mem());
  PEM_write_bio_PrivateKey(bio, key.get(), nullptr, nullptr, 0, nullptr, nullptr);
  size = BIO_get_mem_data(bio, &data);
  out.keyPem.assign(data, std::size_t(size));
  BIO_free(bio);
  out.fingerprint = formatFingerprint(certificateDigest(cert.get()));
  return out;
}

Result<std::array<std::uint8_t, 64>> exportDatagramSecret(SSL* ssl) {
  std::array<std::uint8_t, 64> secret{};
  const std::string label = kDatagramExporterLabel;
  if (SSL_export_keying_material(ssl, secret.data(), secret.size(), label.data(), label.size(),
                                 nullptr, 0, 0) != 1)
    return Error{"exporting the datagram secret from the TLS session: " + openSslErrors()};
  return secret;
}

}  // namespace pc::net
