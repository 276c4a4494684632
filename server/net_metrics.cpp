#include "net_metrics.h"

#include <sys/resource.h>
#include <unistd.h>

#include <atomic>
#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <list>
#include <optional>
#include <sstream>
#include <thread>

#include "common/constant_time.h"
#include "common/log.h"

namespace pc {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
using asio::ip::tcp;

namespace {

// Label values escape backslash, quote and newline (the exposition format's rule).
std::string escapeLabel(const std::string& v) {
  std::string out;
  for (const char c : v) {
    if (c == '\\') {
      out += "\\\\";
    } else if (c == '"') {
      out += "\\\"";
    } else if (c == '\n') {
      out += "\\n";
    } else {
      out.push_back(c);
    }
  }
  return out;
}

std::string formatValue(double v) {
  if (std::isnan(v)) return "NaN";
  if (std::isinf(v)) return v > 0 ? "+Inf" : "-Inf";
  // Integral values (counters of bytes, versions) print exactly, up to 2^53.
  if (v == std::floor(v) && std::fabs(v) < 9.007199254740992e15) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.0f", v);
    return buf;
  }
  // The shortest text that reads back as the same double: 9 significant digits would round
  // a Unix time (process_start_time_seconds) to 10 s.
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

}  // namespace

void MetricsText::counter(const std::string& name, const std::string& help, double value,
                          Labels labels) {
  add(name, help, "counter", value, std::move(labels));
}

void MetricsText::gauge(const std::string& name, const std::string& help, double value,
                        Labels labels) {
  add(name, help, "gauge", value, std::move(labels));
}

void MetricsText::histogram(const std::string& name, const std::string& help, const Histogram& h,
                            Labels labels) {
  Family& f = family(name, help, "histogram");
  const auto& bounds = h.bounds();
  for (std::size_t i = 0; i <= bounds.size(); ++i) {
    Labels l = labels;
    l.emplace_back("le", i < bounds.size() ? formatValue(bounds[i]) : "+Inf");
    f.samples.emplace_back(name + "_bucket", std::move(l), double(h.cumulative(i)));
  }
  f.samples.emplace_back(name + "_sum", labels, h.sum());
  f.samples.emplace_back(name + "_count", std::move(labels), double(h.count()));
}

MetricsText::Family& MetricsText::family(const std::string& name, const std::string& help,
                                         const char* type) {
  for (Family& f : families_) {
    if (f.name == name) return f;
  }
  families_.push_back(Family{name, help, type, {}});
  return families_.back();
}

void MetricsText::add(const std::string& name, const std::string& help, const char* type,
                      double value, Labels labels) {
  family(name, help, type).samples.emplace_back(name, std::move(labels), value);
}

std::string MetricsText::str() const {
  std::string out;
  for (const Family& f : families_) {
    out += "# HELP " + f.name + " " + f.help + "\n";
    out += "# TYPE " + f.name + " " + f.type + "\n";
    for (const auto& [sample, labels, value] : f.samples) {
      out += sample;
      if (!labels.empty()) {
        out.push_back('{');
        for (std::size_t i = 0; i < labels.size(); ++i) {
          if (i > 0) out.push_back(',');
          out += labels[i].first + "=\"" + escapeLabel(labels[i].second) + "\"";
        }
        out.push_back('}');
      }
      out += " " + formatValue(value) + "\n";
    }
  }
  return out;
}

namespace {

// /proc/self/stat's fields after the command name (which may hold spaces and parentheses, so
// the fields are counted from its last ')'): [0] is field 3, the state.
std::vector<std::string> procSelfStat() {
  std::ifstream in("/proc/self/stat");
  const std::string stat((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::size_t close = stat.rfind(')');
  std::vector<std::string> fields;
  if (close == std::string::npos) return fields;
  std::istringstream rest(stat.substr(close + 1));
  for (std::string f; rest >> f;) fields.push_back(f);
  return fields;
}

// The boot time, Unix seconds, by today's wall clock: now less the time since boot. /proc/stat's
// btime is fixed at boot, and a wall clock stepped since (NTP, a resumed VM) would put the
// process's start seconds away from the time the scraper compares it with.
double bootTime() {
  timespec real{}, boot{};
  if (clock_gettime(CLOCK_REALTIME, &real) != 0 || clock_gettime(CLOCK_BOOTTIME, &boot) != 0)
    return 0;
  return (double(real.tv_sec) - double(boot.tv_sec)) +
         (double(real.tv_nsec) - double(boot.tv_nsec)) * 1e-9;
}

}  // namespace

void appendProcessMetrics(MetricsText& m) {
  const std::vector<std::string> f = procSelfStat();
  // Fields 14, 15 (utime, stime: clock ticks), 22 (starttime: ticks after boot), 23 (vsize:
  // bytes), 24 (rss: pages); index = field - 3.
  const auto field = [&f](int n) {
    return std::size_t(n - 3) < f.size() ? std::strtod(f[std::size_t(n - 3)].c_str(), nullptr)
                                         : -1.0;
  };
  const double ticks = double(sysconf(_SC_CLK_TCK));
  if (field(15) >= 0) {
    m.counter("process_cpu_seconds_total", "User and system CPU time of the process, seconds.",
              (field(14) + field(15)) / ticks);
  }
  if (field(24) >= 0) {
    m.gauge("process_resident_memory_bytes", "Resident memory of the process, bytes.",
            field(24) * double(sysconf(_SC_PAGESIZE)));
  }
  if (field(23) >= 0) {
    m.gauge("process_virtual_memory_bytes", "Virtual memory of the process, bytes.", field(23));
  }
  std::error_code ec;
  std::size_t fds = 0;
  for (auto it = std::filesystem::directory_iterator("/proc/self/fd", ec);
       !ec && it != std::filesystem::directory_iterator(); it.increment(ec)) {
    ++fds;
  }
  if (!ec) m.gauge("process_open_fds", "Open file descriptors of the process.", double(fds));
  rlimit limit{};
  if (getrlimit(RLIMIT_NOFILE, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY) {
    m.gauge("process_max_fds", "The process's limit on open file descriptors.",
            double(limit.rlim_cur));
  }
  const double boot = bootTime();
  if (boot > 0 && field(22) >= 0) {
    m.gauge("process_start_time_seconds", "Start time of the process, Unix time in seconds.",
            boot + field(22) / ticks);
  }
}

class MetricsConnection;

struct MetricsHttpServer::Impl {
  Impl(MetricsHttpOptions o, std::function<std::string()> r)
      : options(std::move(o)), render(std::move(r)), acceptor(io) {}
  void acceptNext();
  // Closes the oldest connection still awaiting its request; false when there is none.
  bool dropOldestIdle();

  MetricsHttpOptions options;
  std::function<std::string()> render;
  // Declared before io: connections still pending when io is destroyed count themselves out.
  std::size_t connections = 0;  // io thread only
  // Every connection in accept order (the oldest first); io thread only.
  std::list<std::weak_ptr<MetricsConnection>> open;
  std::atomic<std::uint64_t> scrapes{0}, unauthorized{0}, dropped{0};
  std::uint16_t port = 0;
  asio::io_context io;
  tcp::acceptor acceptor;
  std::thread thread;
};

namespace {

bool authorized(const http::request<http::empty_body>& request, const std::string& token) {
  if (token.empty()) return true;
  constexpr std::string_view kScheme = "Bearer ";
  const auto field = request[http::field::authorization];
  const std::string_view value(field.data(), field.size());
  if (value.size() < kScheme.size() || value.substr(0, kScheme.size()) != kScheme) return false;
  return sameSecret(value.substr(kScheme.size()), token);
}

}  // namespace

// One scrape: read a request, answer it, close. Keep-alive is not offered, so a connection
// holds nothing between scrapes.
class MetricsConnection : public std::enable_shared_from_this<MetricsConnection> {
 public:
  MetricsConnection(MetricsHttpServer::Impl& server, tcp::socket socket)
      : server_(server), stream_(std::move(socket)) {
    ++server_.connections;
  }
  ~MetricsConnection() { --server_.connections; }

  void start() {
    parser_.emplace();
    parser_->header_limit(8 * 1024);
    parser_->body_limit(0);
    stream_.expires_after(std::chrono::duration_cast<std::chrono::steady_clock::duration>(
        std::chrono::duration<double>(server_.options.requestTimeout)));
    auto self = shared_from_this();
    http::async_read(stream_, buffer_, *parser_,
                     [self](beast::error_code ec, std::size_t) { self->onRead(ec); });
  }
  bool awaitingRequest() const { return !answered_; }
  // Ends the connection: its pending operation completes with an error and lets go of it.
  void drop() {
    answered_ = true;
    stream_.close();
  }

 private:
  void onRead(beast::error_code ec) {
    if (ec || answered_) return;  // timeout, dropped, oversized or malformed, or the peer left
    answered_ = true;
    const auto& request = parser_->get();
    response_.version(request.version());
    response_.keep_alive(false);
    response_.set(http::field::server, "probecast");
    response_.set(http::field::content_type, "text/plain; charset=utf-8");
    const bool probe = request.target() == "/healthz" || request.target() == "/readyz";
    const bool readable =
        request.method() == http::verb::get || request.method() == http::verb::head;
    if (probe && readable) {
      // Orchestrators' probes, answered without the token (MetricsHttpOptions::ready).
      const bool ready =
          request.target() == "/healthz" || !server_.options.ready || server_.options.ready();
      response_.result(ready ? http::status::ok : http::status::service_unavailable);
      response_.body() = ready ? "ok\n" : "not ready\n";
    } else if (!authorized(request, server_.options.bearerToken)) {
      // Before the target is even looked at: an unauthorized client learns nothing.
      ++server_.unauthorized;
      response_.result(http::status::unauthorized);
      response_.set(http::field::www_authenticate, "Bearer");
      response_.body() = "unauthorized\n";
    } else if (request.target() != "/metrics" && !probe) {
      response_.result(http::status::not_found);
      response_.body() = "not found: /metrics, /healthz and /readyz are served\n";
    } else if (!readable) {
      response_.result(http::status::method_not_allowed);
      response_.set(http::field::allow, "GET, HEAD");
      response_.body() = "method not allowed\n";
    } else {
      response_.result(http::status::ok);
      response_.set(http::field::content_type, "text/plain; version=0.0.4; charset=utf-8");
      response_.body() = server_.render();
      ++server_.scrapes;
    }
    response_.prepare_payload();
    if (request.method() == http::verb::head) response_.body().clear();
    auto self = shared_from_this();
    http::async_write(stream_, response_, [self](beast::error_code, std::size_t) {
      beast::error_code ignored;
      self->stream_.socket().shutdown(tcp::socket::shutdown_send, ignored);
    });
  }

  MetricsHttpServer::Impl& server_;
  beast::tcp_stream stream_;
  beast::flat_buffer buffer_{16 * 1024};
  std::optional<http::request_parser<http::empty_body>> parser_;
  http::response<http::string_body> response_;
  bool answered_ = false;
};

bool MetricsHttpServer::Impl::dropOldestIdle() {
  for (auto it = open.begin(); it != open.end();) {
    auto connection = it->lock();
    it = open.erase(it);
    if (connection && connection->awaitingRequest()) {
      connection->drop();
      ++dropped;
      return true;
    }
  }
  return false;
}

void MetricsHttpServer::Impl::acceptNext() {
  acceptor.async_accept([this](beast::error_code ec, tcp::socket socket) {
    if (ec == asio::error::operation_aborted) return;
    if (!ec) {
      std::erase_if(open, [](const auto& c) { return c.expired(); });
      // Full: the oldest connection that has not sent its request yet makes room (an idle or
      // slow socket, not a scrape being answered). None: this one is closed, and a scraper
      // that retries gets in once the others are done.
      if (connections >= options.maxConnections && !dropOldestIdle()) {
        beast::error_code ignored;
        socket.close(ignored);
      } else {
        auto connection = std::make_shared<MetricsConnection>(*this, std::move(socket));
        open.push_back(connection);
        connection->start();
      }
    }
    acceptNext();
  });
}

MetricsHttpServer::MetricsHttpServer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

MetricsHttpServer::~MetricsHttpServer() {
  // Pending scrapes are dropped with the io_context: their handlers (and sockets) are
  // destroyed without running.
  impl_->io.stop();
  if (impl_->thread.joinable()) impl_->thread.join();
}

Result<std::unique_ptr<MetricsHttpServer>> MetricsHttpServer::create(
    MetricsHttpOptions options, std::function<std::string()> render) {
  auto impl = std::make_unique<Impl>(std::move(options), std::move(render));
  Impl& s = *impl;
  beast::error_code ec;
  const auto address = asio::ip::make_address(s.options.bindAddress, ec);
  if (ec)
    return Error{"metrics: bad bind address '" + s.options.bindAddress + "': " + ec.message()};
  const tcp::endpoint endpoint(address, s.options.port);
  s.acceptor.open(endpoint.protocol(), ec);
  if (!ec) s.acceptor.set_option(tcp::acceptor::reuse_address(true), ec);
  if (!ec) s.acceptor.bind(endpoint, ec);
  if (!ec) s.acceptor.listen(asio::socket_base::max_listen_connections, ec);
  if (ec) {
    return Error{"metrics: cannot listen on " + s.options.bindAddress + ":" +
                 std::to_string(s.options.port) + ": " + ec.message()};
  }
  s.port = s.acceptor.local_endpoint().port();
  s.acceptNext();
  s.thread = std::thread([&s] { s.io.run(); });
  return std::unique_ptr<MetricsHttpServer>(new MetricsHttpServer(std::move(impl)));
}

std::uint16_t MetricsHttpServer::port() const { return impl_->port; }
std::uint64_t MetricsHttpServer::scrapes() const { return impl_->scrapes.load(); }

}  // namespace pc
