// Server metrics in the Prometheus text exposition format (version 0.0.4), and a small HTTP
// endpoint that serves them: GET /metrics on its own thread (Boost.Beast, which stays inside
// net_metrics.cpp), with /healthz and /readyz for orchestrators' probes. The endpoint renders
// through a callback on every scrape, so it holds no copy of the server's state and needs no lock
// of its own.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "common/histogram.h"
#include "common/result.h"

namespace pc {

// Collects samples by family (one metric name with its HELP and TYPE lines) and writes them
// grouped, each family once, in the order first seen.
class MetricsText {
 public:
  using Labels = std::vector<std::pair<std::string, std::string>>;
  // Counters only go up (names end in _total); gauges go both ways.
  void counter(const std::string& name, const std::string& help, double value, Labels labels = {});
  void gauge(const std::string& name, const std::string& help, double value, Labels labels = {});
  // A histogram family: name_bucket{le="..."} (cumulative, ending with le="+Inf"), name_sum
  // and name_count.
  void histogram(const std::string& name, const std::string& help, const Histogram& h,
                 Labels labels = {});
  std::string str() const;

 private:
  struct Family {
    std::string name, help, type;
    // Sample names beside the family's (name_bucket, name_sum); empty: the family's.
    std::vector<std::tuple<std::string, Labels, double>> samples;
  };
  void add(const std::string& name, const std::string& help, const char* type, double value,
           Labels labels);
  Family& family(const std::string& name, const std::string& help, const char* type);
  std::vector<Family> families_;
};

// The process's own figures from /proc/self, under the names Prometheus' client libraries
// give them: process_cpu_seconds_total, process_resident_memory_bytes,
// process_virtual_memory_bytes, process_open_fds, process_max_fds and
// process_start_time_seconds (Unix time). Figures /proc does not give are left out.
void appendProcessMetrics(MetricsText& out);

struct MetricsHttpOptions {
  std::string bindAddress = "127.0.0.1";
  std::uint16_t port = 0;  // 0: any free port (see MetricsHttpServer::port)
  // Non-empty: a request must carry `Authorization: Bearer <token>` (compared in constant
  // time), else it gets 401.
  std::string bearerToken;
  // GET /healthz answers 200 while the endpoint's thread runs (the process is alive); GET
  // /readyz answers 200 when `ready` returns true (empty: always), else 503. Neither asks for
  // the bearer token: a kubelet's probe carries no secret, and the answers tell nothing but
  // "ok" or "not ready". Called on the endpoint's thread.
  std::function<bool()> ready;
  // A scraper gets this long to send its request and read the answer. Requests are small
  // (GET): headers are capped at 8 KiB and bodies at 0. Connections are served concurrently;
  // with maxConnections open, a new one takes the place of the oldest still awaiting its
  // request, so idle or slow sockets delay a scraper by nothing but their own places.
  double requestTimeout = 5.0;
  std::size_t maxConnections = 32;
};

class MetricsHttpServer {
 public:
  // Binds the port and starts the thread. `render` runs on that thread for every GET /metrics.
  static Result<std::unique_ptr<MetricsHttpServer>> create(MetricsHttpOptions options,
                                                           std::function<std::string()> render);
  ~MetricsHttpServer();  // stops the thread, closes every connection
  MetricsHttpServer(const MetricsHttpServer&) = delete;
  MetricsHttpServer& operator=(const MetricsHttpServer&) = delete;
  std::uint16_t port() const;
  std::uint64_t scrapes() const;

  struct Impl;

 private:
  explicit MetricsHttpServer(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace pc
