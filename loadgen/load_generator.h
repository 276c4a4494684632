// probecast-loadgen's engine: many protocol-only clients in one process, without rendering.
// Each client is a real session, the ClientSession every client runs (protocol/
// client_session.h: TCP hello with the token, session info, scene states, acks, repair
// requests, viewer poses, brick datagrams over UDP or TCP into a StreamReceiver of its own);
// this engine adds what makes them many in one: a few network threads shared by all clients
// (one Boost.Asio io_context each, not a thread per client), simulated moving viewers, joins
// over a ramp, churn (leaving and rejoining), and the figures. Asio stays inside the .cpp
// files.
//
// Update latency is measured from the server's publish to the client's apply: SceneState
// carries each field version's publish time, and a brick update names the field version it
// changed at. On one host both sides read the same monotonic clock (sameClock); across hosts
// the offset is estimated as the smallest (arrival - publish) seen, which leaves the minimum
// one-way delay out of the latencies.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "common/result.h"
#include "protocol/client_session.h"

namespace pc::load {

// A class of emulated links: `mbit` Mbit/s for `share` of the clients.
struct LinkClass {
  double mbit = 0;
  double share = 0;
};

// "0.5:0.25,1:0.5,10:0.25" (Mbit/s : share of clients), or an Error naming what is wrong.
Result<std::vector<LinkClass>> parseRateMix(const std::string& text);

struct LoadOptions {
  std::string host = "127.0.0.1";  // an IPv4/IPv6 address or a host name (resolved once)
  std::uint16_t port = 7450;
  // More endpoints of the same field (relays). Every address of every endpoint is asked for its
  // load every loadProbeInterval (PROTOCOL.md "Choosing an endpoint by load"); each session
  // goes to the least loaded (counting the sessions this process opened since the answers), a
  // client whose session fails to the least loaded other one, in order where none answers.
  std::vector<std::pair<std::string, std::uint16_t>> alternates;
  double loadProbeInterval = 0.5;  // s; 0: no load queries, the endpoints in order
  double loadProbeTimeout = 0.2;   // s a probe waits for answers
  std::string token;
  // One token per client instead (client i presents clientTokens[i % size]), as real
  // viewers each hold their own.
  std::vector<std::string> clientTokens;
  // TLS as probecast-client does it (NetClientOptions): a pinned fingerprint, or a CA file
  // (or the system's trust store) and the host name; false only against a server without TLS.
  bool tls = true;
  std::string serverFingerprint;
  std::string caFile;
  int clients = 10;
  int threads = 1;  // network threads shared by all clients
  bool tcpOnly = false;
  double rampSeconds = 1.0;  // first connects spread evenly over this
  // Churn: > 0 ends each session after about this long (+- sessionJitter of it), and the
  // client connects again after rejoinDelay.
  double sessionSeconds = 0;
  double sessionJitter = 0.5;
  double rejoinDelay = 0.05;
  std::uint64_t maxSessions = 0;  // > 0: no new session once this many were started
  double connectTimeout = 5.0;    // s from connect to SessionInfo
  double silenceTimeout = 3.0;    // s without bytes from the server ends a session as an error
  double pollInterval = 0.01;     // s between each thread's pass over its clients
  double poseInterval = ClientSessionOptions{}.poseInterval;  // s between viewer poses
  // The most a SessionInfo may make a client allocate (ClientSessionOptions::maxMirrorBytes):
  // a larger layout ends the session with an error naming both sizes.
  std::uint64_t maxMirrorBytes = ClientSessionOptions{}.maxMirrorBytes;
  double posePeriod = 10.0;  // s per loop of the simulated viewer path
  // A client starves when, in the measured window, it received no datagram for longer than
  // this, or stayed behind the newest announced field version for longer than this, or a
  // session of it older than this plus the sync limit never held every brick.
  double starveSeconds = 2.0;
  double syncLimit = 10.0;
  // It also starves when the server's reports on its stream (protocol version 3) say its held
  // field is worse than minHeldPsnr (the mean error of the window's reports, in dB) or older
  // than maxChangeAge (95% of the reports: the oldest change it does not hold).
  double minHeldPsnr = 40.0;
  double maxChangeAge = 1.0;
  // Emulated bottleneck links (UDP only): each client's datagrams pass a link of its class's
  // rate with a drop-tail queue of linkQueueSeconds at that rate, as a router before a slow
  // link would, before the client reads them. Empty: no link (loopback). Shares are
  // normalised; clients are assigned to classes in index order.
  std::vector<LinkClass> links;
  double linkQueueSeconds = 0.1;
  bool sameClock = true;
  // Receivers keep only the codes of each brick (no decoded field) and share decoded codes
  // between clients (same payload on the same base, same codes); false decodes per client.
  bool keepField = false;
  bool shareDecoding = true;
  std::uint64_t seed = 1;
  // Non-empty: one row per second of the whole run (joins included) is written here as CSV
  // (kSeriesColumns), from start() to stop().
  std::string seriesPath;
};

// Counters for progress lines, readable while the clients run.
struct LoadSnapshot {
  int clients = 0;
  int inSession = 0;  // welcomed, with a receiver
  int synced = 0;     // in a session and holding every brick
  std::uint64_t sessionsStarted = 0, sessionsEnded = 0;
  std::uint64_t errors = 0;
  std::uint64_t newestFieldVersion = 0;  // announced by any SceneState so far
  // Clients in a session per endpoint address ("address:port"), in the order resolved.
  std::vector<std::pair<std::string, int>> perEndpoint;
};

struct Percentiles {
  std::uint64_t count = 0;
  double p50 = 0, p95 = 0, p99 = 0, max = 0, mean = 0;
};
// Of `samples` (reordered); zeros when empty.
Percentiles percentiles(std::vector<float>& samples);

struct ClientReport {
  int index = 0;
  std::uint64_t sessions = 0;  // started in the window
  double sessionSeconds = 0;   // in a session during the window
  std::uint64_t bytesDown = 0, bytesUp = 0;
  double kbitDown = 0, kbitUp = 0;  // per second of the window
  std::uint64_t datagrams = 0, bricksApplied = 0, repairBricks = 0, staleUpdates = 0;
  std::uint64_t gapReports = 0;  // partial updates whose missing fragments were asked for
  std::uint64_t errors = 0;
  double maxDatagramGap = 0;  // s
  double maxStaleness = 0;    // s
  double syncSeconds = -1;    // connect -> every brick held, latest session
  Percentiles latencyMs;
  // From the server's stream reports in the window: the held field's PSNR (mean squared error
  // of the reports, in dB; 0 without reports), the oldest change's age (95th percentile of the
  // reports), the send rate (mean), the quality level (mean).
  std::uint64_t reports = 0;
  double heldPsnrDb = 0, oldestChangeP95 = 0, rateMbit = 0, qualityLevel = 0;
  int linkClass = -1;  // index into LoadOptions::links; -1 without
  double linkMbit = 0;
  std::uint64_t linkDrops = 0;  // datagrams the emulated link's queue dropped
  bool starved = false;
  std::string starvedWhy, lastError;
};

// Figures of one link class (or of all clients).
struct ClassReport {
  double linkMbit = 0;  // 0: no emulated link
  int clients = 0, starved = 0;
  Percentiles latencyMs, kbitPerClient;
  double heldPsnrP5 = 0;       // over the class's clients
  double oldestChangeP95 = 0;  // over the class's clients, of each client's p95
  double linkDropShare = 0;    // of the datagrams that reached the emulated links
  double rateMbitMean = 0;
};

struct LoadReport {
  LoadOptions options;
  double seconds = 0;  // of the measured window
  int clients = 0;
  std::uint64_t sessionsStarted = 0, sessionsEnded = 0;
  Percentiles latencyMs;      // every brick update applied in the window (publish -> apply)
  Percentiles stalenessMs;    // per-client samples every 100 ms (0 while up to date)
  Percentiles kbitPerClient;  // down, over clients
  std::uint64_t unmatchedUpdates = 0;  // applied versions whose publish time never arrived
  std::uint64_t bricksApplied = 0, repairBricks = 0, datagrams = 0, errors = 0;
  std::uint64_t gapReports = 0;
  int starvedClients = 0;
  std::uint64_t decodedPayloads = 0, sharedDecodes = 0, contentMismatches = 0;
  double residentMb = 0;      // this process, at the report
  double decodedFieldMb = 0;  // one decoded field of the server's layout (keepField's cost)
  double brickCodesMb = 0;    // one client's brick codes if not shared
  std::vector<std::string> errorSamples;  // a few distinct error messages
  ClassReport all;                        // every client
  std::vector<ClassReport> classes;       // per LoadOptions::links entry
  std::vector<ClientReport> perClient;
};

// The series' columns: seconds since start(); clients in a session and synced; kbit/s
// received by all clients and by the mean client in a session; update latency percentiles
// (publish -> apply, ms); staleness p95 (ms); the server's reports: oldest change not held,
// p95 (s); gaps: the longest wait for a datagram of any client in a session (ms) and the
// partial updates whose missing fragments were asked for; the held field's PSNR, 5th
// percentile over clients (dB); errors in the second. A figure without samples in a second
// is left empty.
inline const std::vector<std::string> kSeriesColumns = {"time_s",
                                                        "clients",
                                                        "synced",
                                                        "kbit_s_total",
                                                        "kbit_s_per_client",
                                                        "latency_p50_ms",
                                                        "latency_p95_ms",
                                                        "latency_p99_ms",
                                                        "staleness_p95_ms",
                                                        "change_age_p95_s",
                                                        "gap_max_ms",
                                                        "gap_reports",
                                                        "held_psnr_p5_db",
                                                        "errors"};

// What all clients saw over one interval (LoadGenerator::takeInterval).
struct LoadInterval {
  double seconds = 0;
  int inSession = 0, synced = 0;
  std::uint64_t bytesDown = 0, errors = 0, gapReports = 0;
  double maxGapSeconds = 0;
  Percentiles latencyMs, stalenessMs, changeAgeS;
  double heldPsnrP5 = 0;  // 0 without reports
  bool reports = false;
  // The series row of kSeriesColumns, at `time` seconds.
  std::vector<double> seriesRow(double time) const;
};

class LoadGenerator {
 public:
  static Result<std::unique_ptr<LoadGenerator>> create(LoadOptions options);
  ~LoadGenerator();  // stop()
  LoadGenerator(const LoadGenerator&) = delete;
  LoadGenerator& operator=(const LoadGenerator&) = delete;

  // Starts the network threads; clients connect over the ramp.
  void start();
  // Closes every session and joins the threads. Idempotent.
  void stop();
  // Starts the measured window: every figure of report() counts from here (start() begins one).
  void beginWindow();
  // Figures of the window so far. Safe while running and after stop().
  LoadReport report();
  LoadSnapshot snapshot() const;
  // Figures since the previous call (or start()): what one row of the series holds.
  LoadInterval takeInterval();

  struct Impl;

 private:
  explicit LoadGenerator(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// The report as JSON (options, summary, per client) and as a readable table.
std::string reportJson(const LoadReport& report);
std::string reportTable(const LoadReport& report);

}  // namespace pc::load
