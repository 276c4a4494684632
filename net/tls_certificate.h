// The development certificate a server makes for itself, and certificate fingerprints.
#pragma once

#include <string>

#include "net/tls_context.h"

namespace pc::net {

struct DevCertificate {
  std::string certificatePem, keyPem;
  std::string fingerprint;  // "sha256:<hex>"
};

// A fresh P-256 key and a self-signed certificate (CA:TRUE, so a client may also take it as
// its CA file) for localhost, 127.0.0.1 and ::1, valid from an hour ago for 30 days.
Result<DevCertificate> makeDevCertificate();

}  // namespace pc::net
