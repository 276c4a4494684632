// TLS 1.3 for the session stream: the server's context (certificate and key files, or a
// development certificate made at start), the client's (the system's trust store or a CA file,
// with host name verification, or a pinned certificate fingerprint), and the datagram secret
// both ends export from one TLS session.
#pragma once

// clang-format off
#include <utility>  // first: Boost.Asio 1.74 uses std::exchange without including it
// clang-format on
#include <array>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/ssl.hpp>
#include <cstdint>
#include <memory>
#include <string>

#include "common/result.h"

namespace pc::net {

namespace ssl = boost::asio::ssl;

struct DevCertificate;  // net/tls_certificate.h

struct TlsServerSettings {
  std::string certificateFile;  // PEM: the server's certificate, then any intermediates
  std::string keyFile;          // PEM: its private key
  // No files: a fresh P-256 key and a self-signed certificate for localhost, 127.0.0.1 and
  // ::1, valid 30 days. Clients trust it by its fingerprint (or by the PEM written to
  // devCertificateOut, as a CA file).
  bool devSelfSigned = false;
  std::string devCertificateOut;  // where to write the development certificate (optional)
  // The development certificate to use instead of a fresh one: a process that makes its
  // server again (a relay following a restarted field server) keeps its fingerprint.
  std::shared_ptr<const DevCertificate> devCertificate;
};

struct TlsServer {
  std::unique_ptr<ssl::context> context;
  std::string fingerprint;  // "sha256:" + 64 hex digits of the leaf certificate's DER
};

Result<TlsServer> makeTlsServer(const TlsServerSettings& settings);

struct TlsClientSettings {
  // A pinned fingerprint ("sha256:<hex>", colons between bytes allowed): the server's
  // certificate must have exactly this SHA-256, and nothing else is checked (self-signed
  // certificates included). Without a pin: the chain must verify against caFile (or the
  // system's trust store when caFile is empty) and name the host connected to.
  std::string pinnedFingerprint;
  std::string caFile;
};

// The parsed settings, shared by every connection of a client (and every simulated client of
// the load generator).
class TlsClient {
 public:
  static Result<std::shared_ptr<TlsClient>> create(const TlsClientSettings& settings);
  ssl::context& context() { return *context_; }
  // Sets one connection's SNI and verification (the pin, or the chain and `host`).
  Status prepare(ssl::stream<boost::asio::ip::tcp::socket>& stream, const std::string& host) const;
  const std::array<std::uint8_t, 32>* pin() const { return pinned_ ? &pin_ : nullptr; }

 private:
  std::unique_ptr<ssl::context> context_;
  bool pinned_ = false;
  std::array<std::uint8_t, 32> pin_{};
};

// "sha256:<hex>" (or the bare hex, with or without colons) -> 32 bytes.
Result<std::array<std::uint8_t, 32>> parseFingerprint(const std::string& text);
std::string formatFingerprint(const std::array<std::uint8_t, 32>& digest);
// SHA-256 of a certificate's DER encoding.
std::array<std::uint8_t, 32> certificateDigest(X509* certificate);

// 64 bytes of keying material exported from an established TLS 1.3 session (RFC 8446
// section 7.5, label "EXPORTER-probecast-datagram-keys", no context): the same on both ends,
// secret from anyone outside the session. The datagram keys are derived from it.
inline constexpr const char* kDatagramExporterLabel = "EXPORTER-probecast-datagram-keys";
Result<std::array<std::uint8_t, 64>> exportDatagramSecret(SSL* ssl);

// The OpenSSL error queue as text (and cleared), for messages.
std::string openSslErrors();

}  // namespace pc::net
