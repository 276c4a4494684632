#include "net/tls_context.h"

#include <openssl/ssl.h>
#include <openssl/x509.h>

#include <fstream>

#include "common/log.h"
#include "net/tls_certificate.h"

namespace pc::net {

namespace {

// TLS 1.3 and nothing older, for both ends: its handshake encrypts the certificate, has no
// renegotiation, and its exporter is what the datagram keys come from.
Status restrictToTls13(ssl::context& context) {
  SSL_CTX* ctx = context.native_handle();
  if (SSL_CTX_set_min_proto_version(ctx, TLS1_3_VERSION) != 1 ||
      SSL_CTX_set_max_proto_version(ctx, TLS1_3_VERSION) != 1)
    return Error{"TLS 1.3 is not available: " + openSslErrors()};
  // No session tickets: each session has its own handshake and its own datagram keys, and
  // the server keeps no ticket key.
  SSL_CTX_set_num_tickets(ctx, 0);
  SSL_CTX_set_options(ctx, SSL_OP_NO_TICKET);
  return Status::success();
}

Status writePrivateFile(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) return Error{"cannot write " + path};
  out << text;
  out.close();
  if (!out) return Error{"cannot write " + path};
  return Status::success();
}

}  // namespace

Result<TlsServer> makeTlsServer(const TlsServerSettings& settings) {
  TlsServer server;
  server.context = std::make_unique<ssl::context>(ssl::context::tls_server);
  if (Status s = restrictToTls13(*server.context); !s) return s.error();
  SSL_CTX* ctx = server.context->native_handle();
  if (settings.devSelfSigned) {
    if (!settings.certificateFile.empty() || !settings.keyFile.empty())
      return Error{"a development certificate and certificate files exclude each other"};
    Result<DevCertificate> dev = settings.devCertificate
                                     ? Result<DevCertificate>(*settings.devCertificate)
                                     : makeDevCertificate();
    if (!dev) return dev.error();
    boost::system::error_code ec;
    server.context->use_certificate(boost::asio::buffer(dev->certificatePem), ssl::context::pem,
                                    ec);
    if (!ec)
      server.context->use_private_key(boost::asio::buffer(dev->keyPem), ssl::context::pem, ec);
    if (ec) return Error{"development certificate: " + ec.message() + ": " + openSslErrors()};
    if (!settings.devCertificateOut.empty()) {
      if (Status s = writePrivateFile(settings.devCertificateOut, dev->certificatePem); !s)
        return s.error();
    }
  } else {
    if (settings.certificateFile.empty() || settings.keyFile.empty()) {
      return Error{
          "TLS needs a certificate and a key (--tls-cert, --tls-key), or --dev-self-signed"};
    }
    if (SSL_CTX_use_certificate_chain_file(ctx, settings.certificateFile.c_str()) != 1)
      return Error{"certificate " + settings.certificateFile + ": " + openSslErrors()};
    if (SSL_CTX_use_PrivateKey_file(ctx, settings.keyFile.c_str(), SSL_FILETYPE_PEM) != 1)
      return Error{"private key " + settings.keyFile + ": " + openSslErrors()};
    if (SSL_CTX_check_private_key(ctx) != 1) {
      return Error{"private key " + settings.keyFile + " does not belong to certificate " +
                   settings.certificateFile};
    }
  }
  X509* leaf = SSL_CTX_get0_certificate(ctx);
  if (!leaf) return Error{"no certificate loaded: " + openSslErrors()};
  server.fingerprint = formatFingerprint(certificateDigest(leaf));
  return server;
}

Result<std::shared_ptr<TlsClient>> TlsClient::create(const TlsClientSettings& settings) {
  auto client = std::make_shared<TlsClient>();
  client->context_ = std::make_unique<ssl::context>(ssl::context::tls_client);
  if (Status s = restrictToTls13(*client->context_); !s) return s.error();
  if (!settings.pinnedFingerprint.empty()) {
    auto pin = parseFingerprint(settings.pinnedFingerprint);
    if (!pin) return pin.error();
    client->pin_ = *pin;
    client->pinned_ = true;
  } else {
    boost::system::error_code ec;
    if (settings.caFile.empty()) {
      client->context_->set_default_verify_paths(ec);
      if (ec) return Error{"the system's trust store: " + ec.message()};
    } else {
      client->context_->load_verify_file(settings.caFile, ec);
      if (ec) return Error{"CA file " + settings.caFile + ": " + ec.message()};
    }
  }
  client->context_->set_verify_mode(ssl::verify_peer);
  return client;
}

Status TlsClient::prepare(ssl::stream<boost::asio::ip::tcp::socket>& stream,
                          const std::string& host) const {
  boost::system::error_code ec;
  boost::asio::ip::make_address(host, ec);
  const bool isAddress = !ec;
  // SNI names hosts, never addresses (RFC 6066).
  if (!isAddress && SSL_set_tlsext_host_name(stream.native_handle(), host.c_str()) != 1)
    return Error{"server name " + host + ": " + openSslErrors()};
  if (pinned_) {
    // The pin is the whole check: the leaf certificate's digest must equal it, whoever issued
    // it. Certificates above the leaf are not looked at.
    const std::array<std::uint8_t, 32> pin = pin_;
    stream.set_verify_callback([pin](bool, ssl::verify_context& verify) {
      X509_STORE_CTX* store = verify.native_handle();
      if (X509_STORE_CTX_get_error_depth(store) != 0) return true;
      X509* leaf = X509_STORE_CTX_get_current_cert(store);
      return leaf && certificateDigest(leaf) == pin;
    });
  } else {
    stream.set_verify_callback(ssl::host_name_verification(host), ec);
    if (ec) return Error{"host name verification: " + ec.message()};
  }
  return Status::success();
}

}  // namespace pc::net
