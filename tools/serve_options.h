// What probecast-server and probecast-relay share on their command lines: the client-facing
// side (listener, connect tokens, TLS, stream tuning), what is reported (duration, statistics,
// metrics, logs), the per-client limits, NATS, and the wait for SIGINT/SIGTERM. Both serve
// clients with the same network layer, so they take the same flags for it.
#pragma once

#include <pthread.h>
#include <signal.h>

#include <CLI/CLI.hpp>
#include <ctime>
#include <string>
#include <vector>

#include "common/log.h"
#include "protocol/brick_precision.h"
#include "protocol/stream_tuning.h"
#include "relay/nats_client.h"
#include "server/net_server.h"
#include "tools/build_info.h"
#include "tools/token_input.h"

namespace pc {

struct ServeSetup {
  NetServerOptions net;
  StreamTuning tuning;
  PublisherOptions publisherOptions;  // from `tuning`
  double duration = 0, statsInterval = 2.0, rateLimit = 0;
  int metricsPort = 0;
  std::vector<std::string> tokenKeyFiles;
  std::string sceneName;
  std::string metricsTokenFile;
  std::string logFormat = "text", logLevel = "info";
};

inline void addStreamOptions(CLI::App& app, ServeSetup& s) {
  app.add_option("--bind", s.net.bindAddress, "address to listen on");
  app.add_option("--port", s.net.port, "TCP port (0: any free one)");
  app.add_option("--udp-port", s.net.udpPort,
                 "UDP port datagrams leave from and acks come to (0, the default: any free one)");
  app.add_option("--token-key", s.tokenKeyFiles,
                 "verify key file of a connect token issuer (probecast-token keygen); "
                 "repeat it while keys rotate (else $PROBECAST_TOKEN_KEY_FILE)");
  app.add_option("--revoked", s.net.revocationFile,
                 "revocation list: token ids refused (read again when it changes)");
  app.add_option("--scene-name", s.sceneName,
                 "the scene name connect tokens must name (server default: 'builtin', or the "
                 "scene file's folder name when the file is called scene.*, else its stem; "
                 "relay default: the field server's)");
  app.add_flag("--tcp-only", s.net.tcpOnly, "send datagrams over TCP to every client");
  app.add_option("--tls-cert", s.net.tls.certificateFile,
                 "TLS certificate chain (PEM) of the session port");
  app.add_option("--tls-key", s.net.tls.keyFile, "its private key (PEM)");
  app.add_flag("--dev-self-signed", s.net.tls.devSelfSigned,
               "make a self-signed certificate at start (development, tests); its fingerprint "
               "is printed for clients to pin");
  app.add_option("--dev-cert-out", s.net.tls.devCertificateOut,
                 "write the --dev-self-signed certificate here (PEM), for clients' --ca-file");
  app.add_flag("--no-tls{false}", s.net.tls.enabled,
               "plain TCP and unsealed datagrams (measuring TLS's cost, a trusted loopback); "
               "clients must say --no-tls too");
  app.add_option("--rate-limit", s.rateLimit, "bytes per second per client (0: default)");
  app.add_option("--stream-threshold", s.tuning.threshold,
                 "perceptual threshold T of the stream: changes of the gamma-encoded irradiance "
                 "below T are held back (0: every version exactly; docs/BENCHMARKS.md has the "
                 "bandwidth and PSNR for each T)")
      ->check(CLI::Range(0.0, 0.5));
  app.add_option("--max-precision", s.net.sender.maxPrecision,
                 "coarsest precision level a short link is sent (0: the codec's own always; "
                 "PROTOCOL.md, Precision levels)")
      ->check(CLI::Range(0, pc::kMaxPrecision));
  app.add_option("--send-threads", s.net.sendThreads,
                 "threads that poll, seal and send datagram sessions (0: half the cores, 1-8)")
      ->check(CLI::Range(0, 64));
}

// How long the process runs and what it reports.
inline void addReportOptions(CLI::App& app, ServeSetup& s) {
  app.add_option("--duration", s.duration, "exit after this many seconds (0: run until a signal)");
  app.add_option("--stats-interval", s.statsInterval, "seconds between statistics lines");
  app.add_option("--metrics-port", s.metricsPort,
                 "serve Prometheus metrics at http://BIND:PORT/metrics (0: off)")
      ->check(CLI::Range(0, 65535));
  app.add_option("--metrics-bind", s.net.metricsBindAddress,
                 "address the metrics endpoint listens on (default: 127.0.0.1)");
  app.add_option("--metrics-token-file", s.metricsTokenFile,
                 "file holding a bearer token every scrape must present (else 401)");
  app.add_option("--log-format", s.logFormat, "log lines: text, or json (one object per line)");
  app.add_option("--log-level", s.logLevel, "least severe level logged: debug, info, warn, error");
}

// What clients may do before they are turned away.
inline void addLimitOptions(CLI::App& app, ServeSetup& s) {
  NetServerOptions& net = s.net;
  app.add_option("--max-clients", net.maxClients, "clients past the handshake; more get a Reject");
  app.add_option("--max-pending", net.maxPendingConnections,
                 "connections awaiting their Hello; more are closed when accepted");
  app.add_option("--max-message-bytes", net.maxMessageBytes,
                 "largest message a client may send (0: derived from the field's brick count)");
  app.add_option("--max-messages-per-second", net.maxMessagesPerSecond,
                 "messages a client may send per second before it is disconnected as a flood");
  app.add_option("--max-write-queue", net.maxWriteQueueBytes,
                 "bytes queued to a client before it counts as not reading");
  app.add_option("--max-pending-per-address", net.maxPendingPerAddress,
                 "connections awaiting their Hello from one address (IPv6: /64) (0: no cap)");
  app.add_option("--max-sessions-per-address", net.maxSessionsPerAddress,
                 "sessions from one address (IPv6: /64) (0: no cap)");
  app.add_option("--handshakes-per-second-per-address", net.handshakesPerSecondPerAddress,
                 "connections one address may open per second, burst of two seconds' worth "
                 "(0: no cap)");
  app.add_option("--max-sessions-per-client", net.maxSessionsPerClient,
                 "sessions one client name may hold; more get a Reject (0: no cap)");
}

// The NATS connection. `urls` empty: no NATS (the server alone).
inline void addNatsOptions(CLI::App& app, pc::relay::NatsOptions& nats, std::string& bucket) {
  app.add_option("--nats", nats.urls,
                 "NATS server URL(s), comma-separated (nats://HOST:4222, tls://HOST:4222), "
                 "whose JetStream key-value bucket carries the field to relays");
  app.add_option("--nats-creds", nats.credentialsFile,
                 "NATS credentials file (.creds: user JWT and nkey seed)");
  app.add_option("--nats-user", nats.user, "NATS user name (with --nats-password-file)");
  app.add_option("--nats-password-file", nats.passwordFile,
                 "file whose first line is the NATS user's password");
  app.add_option("--nats-ca", nats.caFile,
                 "CA file (PEM) the NATS servers' TLS certificates chain to");
  app.add_option("--nats-bucket", bucket,
                 "key-value bucket of the field (letters, digits, '-', '_'); its name also "
                 "prefixes the pose and load subjects");
}

// What the shared options imply beyond their values (logging, the metrics token, the connect
// token keys, the stream's tuning), after checks CLI11 cannot make; false (with the error
// logged) where they do not hold.
inline bool applyServeOptions(ServeSetup& s) {
  const auto format = parseLogFormat(s.logFormat);
  const auto level = parseLogLevel(s.logLevel);
  if (!format) {
    logError("--log-format: expected text or json, got '" + s.logFormat + "'");
    return false;
  }
  if (!level) {
    logError("--log-level: expected debug, info, warn or error, got '" + s.logLevel + "'");
    return false;
  }
  setLogFormat(*format);
  setLogLevel(*level);
  if (s.metricsPort != 0) s.net.metricsPort = std::uint16_t(s.metricsPort);
  s.net.buildInfo = BuildInfo{PC_VERSION, gitRevision(), buildType()};
  if (!s.metricsTokenFile.empty()) {
    auto token = readTokenFile(s.metricsTokenFile);
    if (!token) {
      logError("--metrics-token-file: " + token.error().message);
      return false;
    }
    s.net.metricsToken = std::move(token).value();
  }
  if (s.tokenKeyFiles.empty()) {
    if (const char* env = std::getenv("PROBECAST_TOKEN_KEY_FILE")) s.tokenKeyFiles.push_back(env);
  }
  if (s.tokenKeyFiles.empty()) {
    logError(
        "no token verify key: pass --token-key FILE or set PROBECAST_TOKEN_KEY_FILE "
        "(probecast-token keygen makes one)");
    return false;
  }
  for (const std::string& file : s.tokenKeyFiles) {
    auto key = loadVerifyKey(file);
    if (!key) {
      logError("--token-key: " + key.error().message);
      return false;
    }
    s.net.tokenKeys.push_back(*key);
  }
  if (s.rateLimit > 0) s.net.sender.bytesPerSecond = s.rateLimit;
  applyStreamTuning(s.tuning, s.publisherOptions, s.net.sender);
  return true;
}

// SIGINT and SIGTERM go to the thread that waits for them (main), never to the worker
// threads: blocked before any thread starts (which inherit the mask), taken by sigtimedwait.
class Signals {
 public:
  Signals() {
    sigemptyset(&set_);
    sigaddset(&set_, SIGINT);
    sigaddset(&set_, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &set_, nullptr);
  }
  // The signal that arrived within `wait` (none: 0).
  int wait(timespec wait) const {
    const int sig = sigtimedwait(&set_, nullptr, &wait);
    return sig == SIGINT || sig == SIGTERM ? sig : 0;
  }
  int pending() const { return wait(timespec{0, 0}); }
  static const char* name(int sig) { return sig == SIGINT ? "SIGINT" : "SIGTERM"; }

 private:
  sigset_t set_;
};

// Where a serving process prints, for scripts to wait for: the TLS certificate to pin, then
// "ready port N". And the metrics endpoint.
inline void announceServing(const NetServerOptions& net, std::uint16_t port,
                            std::uint16_t metricsPort, const std::string& fingerprint) {
  if (metricsPort != 0) {
    const std::string bind = net.metricsBindAddress.empty() ? "127.0.0.1" : net.metricsBindAddress;
    logInfo("metrics at http://" + bind + ":" + std::to_string(metricsPort) + "/metrics");
  }
  if (!fingerprint.empty()) {
    logInfo("TLS certificate " + fingerprint);
    std::printf("tls-fingerprint %s\n", fingerprint.c_str());
  } else {
    logWarn("TLS is off (--no-tls): sessions and datagrams travel in clear");
  }
  std::printf("ready port %u\n", unsigned(port));
  std::fflush(stdout);
}

}  // namespace pc
