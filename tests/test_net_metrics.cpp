// The server's observability: Prometheus text from MetricsText, the /metrics endpoint of a
// real server scraped over a plain socket while a client comes and goes, its health and
// readiness probes, the fixed ports a container publishes, and the log line formats (text
// key=value and JSON).
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <ctime>
#include <limits>
#include <map>
#include <memory>
#include <sstream>

#include "common/log.h"
#include "test_net_support.h"

namespace pc::nettest {
namespace {

struct HttpResponse {
  int status = 0;
  std::string headers, body;
};

// One HTTP/1.1 request over a plain socket; the server closes after answering.
std::optional<HttpResponse> httpGet(std::uint16_t port, const std::string& target,
                                    const std::string& method = "GET",
                                    const std::string& headers = "") {
  namespace asio = boost::asio;
  asio::io_context io;
  asio::ip::tcp::socket socket(io);
  boost::system::error_code ec;
  socket.connect({asio::ip::make_address("127.0.0.1"), port}, ec);
  if (ec) return std::nullopt;
  const std::string request = method + " " + target +
                              " HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n" + headers +
                              "\r\n";
  asio::write(socket, asio::buffer(request), ec);
  if (ec) return std::nullopt;
  std::string raw;
  std::array<char, 4096> chunk{};
  while (true) {
    const std::size_t n = socket.read_some(asio::buffer(chunk), ec);
    raw.append(chunk.data(), n);
    if (ec) break;  // eof once the answer is complete
  }
  const std::size_t split = raw.find("\r\n\r\n");
  if (split == std::string::npos || raw.compare(0, 9, "HTTP/1.1 ") != 0) return std::nullopt;
  HttpResponse r;
  r.status = std::stoi(raw.substr(9, 3));
  r.headers = raw.substr(0, split);
  r.body = raw.substr(split + 4);
  return r;
}

// Samples by their full name with labels ("probecast_disconnects_total{cause=\"flood\"}"),
// checking the exposition format on the way: every sample's family has exactly one HELP and
// one TYPE line, before its samples.
struct Scrape {
  std::map<std::string, double> samples;
  std::map<std::string, std::string> types;
  double operator[](const std::string& key) const {
    auto it = samples.find(key);
    EXPECT_NE(it, samples.end()) << "no sample " << key;
    return it == samples.end() ? -1.0 : it->second;
  }
};

Scrape parseMetrics(const std::string& text) {
  Scrape s;
  std::map<std::string, int> helps;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    if (line.rfind("# HELP ", 0) == 0) {
      ++helps[line.substr(7, line.find(' ', 7) - 7)];
      continue;
    }
    if (line.rfind("# TYPE ", 0) == 0) {
      const std::string rest = line.substr(7);
      const std::string name = rest.substr(0, rest.find(' '));
      EXPECT_EQ(s.types.count(name), 0u) << "two TYPE lines for " << name;
      s.types[name] = rest.substr(rest.find(' ') + 1);
      continue;
    }
    const std::size_t space = line.rfind(' ');
    const std::string key = line.substr(0, space);
    std::string family = key.substr(0, key.find('{'));
    // A histogram's samples (name_bucket, name_sum, name_count) belong to its family.
    for (const char* suffix : {"_bucket", "_sum", "_count"}) {
      const std::string stem =
          family.substr(0, family.size() - std::min(family.size(), std::strlen(suffix)));
      if (family == stem + suffix && s.types.count(stem) && s.types[stem] == "histogram") {
        family = stem;
        break;
      }
    }
    EXPECT_EQ(helps[family], 1) << "HELP lines for " << family;
    EXPECT_EQ(s.types.count(family), 1u) << "no TYPE before " << key;
    EXPECT_EQ(s.samples.count(key), 0u) << "duplicate sample " << key;
    s.samples[key] = std::stod(line.substr(space + 1));
  }
  return s;
}

Scrape scrape(std::uint16_t port) {
  auto r = httpGet(port, "/metrics");
  EXPECT_TRUE(r.has_value());
  if (!r) return {};
  EXPECT_EQ(r->status, 200);
  EXPECT_NE(r->headers.find("text/plain; version=0.0.4"), std::string::npos);
  return parseMetrics(r->body);
}

TEST(NetMetrics, TextFormatGroupsFamiliesAndEscapesLabels) {
  MetricsText m;
  m.counter("x_total", "Things.", 3, {{"cause", "a"}});
  m.gauge("y", "A level.", 0.25);
  m.counter("x_total", "Things.", 4, {{"cause", "quote\" back\\ nl\n"}});
  EXPECT_EQ(m.str(),
            "# HELP x_total Things.\n"
            "# TYPE x_total counter\n"
            "x_total{cause=\"a\"} 3\n"
            "x_total{cause=\"quote\\\" back\\\\ nl\\n\"} 4\n"
            "# HELP y A level.\n"
            "# TYPE y gauge\n"
            "y 0.25\n");
}

// A client of the test server, trusting its certificate.
client::NetClientOptions clientOf(const TestServer& server) {
  client::NetClientOptions co;
  co.port = server.port();
  co.serverFingerprint = server.fingerprint();
  co.token = kToken;
  return co;
}

TEST(NetMetrics, EndpointFollowsClientsAndCounters) {
  NetServerOptions o;
  o.metricsPort = 0;  // any free port
  TestServer server(-1.0, o);
  const std::uint16_t port = server.net().metricsPort();
  ASSERT_NE(port, 0);
  server.net().setExtraMetrics(
      [&server](MetricsText& m) { appendFieldLoopMetrics(m, server.loop().stats()); });

  const Scrape before = scrape(port);
  EXPECT_EQ(before["probecast_clients"], 0.0);
  EXPECT_EQ(before.types.at("probecast_clients"), "gauge");
  EXPECT_EQ(before.types.at("probecast_sent_bytes_total"), "counter");
  EXPECT_EQ(before.types.at("probecast_disconnects_total"), "counter");
  EXPECT_EQ(before["probecast_disconnects_total{cause=\"flood\"}"], 0.0);
  EXPECT_EQ(before["probecast_sessions_rejected_total{cause=\"server_full\"}"], 0.0);
  EXPECT_EQ(before.types.at("probecast_updates_resent_total"), "counter");
  EXPECT_EQ(before.types.at("probecast_fragments_repaired_total"), "counter");
  EXPECT_EQ(before.types.at("probecast_field_tracer_failures_total"), "counter");
  EXPECT_EQ(before["probecast_field_tracer_failures_total"], 0.0);
  EXPECT_EQ(before["probecast_field_tracer_info{tracer=\"embree\"}"], 1.0);

  std::uint64_t sentWhileConnected = 0;
  {
    client::FieldMirror mirror;
    client::NetClient client(mirror, clientOf(server));
    client.start();
    ASSERT_TRUE(waitFor([&] { return client.stats().synced; }, 20.0));
    const Scrape during = scrape(port);
    EXPECT_EQ(during["probecast_clients"], 1.0);
    EXPECT_EQ(during["probecast_sessions_total"], 1.0);
    EXPECT_GT(during["probecast_sent_bytes_total"], before["probecast_sent_bytes_total"]);
    EXPECT_GT(during["probecast_datagrams_sent_total"], 0.0);
    EXPECT_GT(during["probecast_received_messages_total"], 1.0);  // hello and acks
    EXPECT_GT(during["probecast_field_version"], 0.0);
    EXPECT_GT(during["probecast_encodes_total"], 0.0);
    EXPECT_GT(during["probecast_encode_seconds_total"], 0.0);
    // The field thread's figures, once its first update (after the client synced) is done.
    ASSERT_TRUE(waitFor([&] { return scrape(port)["probecast_field_updates_total"] > 0; }, 10.0));
    const Scrape updated = scrape(port);
    // The update's total is its own metric, not a pass: summing the passes counts it once.
    EXPECT_GT(updated["probecast_field_last_update_seconds"], 0.0);
    EXPECT_EQ(updated.samples.count("probecast_field_last_pass_seconds{pass=\"total\"}"), 0u);
    EXPECT_GT(updated["probecast_field_last_pass_seconds{pass=\"trace\"}"], 0.0);
    EXPECT_GT(updated["probecast_field_update_seconds_total"], 0.0);
    EXPECT_GT(updated["probecast_field_ticks_total"], 0.0);
    // Counters only grow: a later scrape has sent more (the field never freezes).
    ASSERT_TRUE(waitFor(
        [&] {
          return scrape(port)["probecast_sent_bytes_total"] > during["probecast_sent_bytes_total"];
        },
        5.0));
    sentWhileConnected = std::uint64_t(scrape(port)["probecast_sent_bytes_total"]);
    std::printf("while connected: %llu bytes sent, field version %.0f\n",
                (unsigned long long)sentWhileConnected, during["probecast_field_version"]);

    // A malformed message from another client shows up under its cause.
    RawPeer bad(server.port());
    std::vector<std::uint8_t> junk(64, 0xAB);
    junk[0] = 60, junk[1] = junk[2] = junk[3] = 0;
    bad.send(junk);
    EXPECT_TRUE(bad.closedByServer());
  }
  ASSERT_TRUE(waitFor([&] { return scrape(port)["probecast_clients"] == 0.0; }, 5.0));
  const Scrape after = scrape(port);
  EXPECT_EQ(after["probecast_disconnects_total{cause=\"malformed\"}"], 1.0);
  EXPECT_EQ(after["probecast_rejected_messages_total{cause=\"malformed\"}"], 1.0);
  EXPECT_EQ(after["probecast_disconnects_total{cause=\"client_closed\"}"], 1.0);
  EXPECT_EQ(after["probecast_connections_accepted_total"], 2.0);
  EXPECT_GE(after["probecast_sent_bytes_total"], double(sentWhileConnected));

  // Only /metrics is served, and only to GET and HEAD.
  auto missing = httpGet(port, "/other");
  ASSERT_TRUE(missing.has_value());
  EXPECT_EQ(missing->status, 404);
  auto post = httpGet(port, "/metrics", "POST");
  ASSERT_TRUE(post.has_value());
  EXPECT_EQ(post->status, 405);
}

// A histogram family of a scrape: its buckets by upper bound (+Inf last), sum and count.
struct ScrapedHistogram {
  std::vector<std::pair<double, double>> buckets;  // (le, cumulative count), by le
  double sum = -1, count = -1;
};

ScrapedHistogram histogramOf(const Scrape& s, const std::string& name) {
  ScrapedHistogram h;
  const std::string prefix = name + "_bucket{le=\"";
  for (const auto& [key, value] : s.samples) {
    if (key.rfind(prefix, 0) != 0) continue;
    const std::string le = key.substr(prefix.size(), key.size() - prefix.size() - 2);
    h.buckets.emplace_back(le == "+Inf" ? std::numeric_limits<double>::infinity() : std::stod(le),
                           value);
  }
  std::sort(h.buckets.begin(), h.buckets.end());
  h.sum = s[name + "_sum"];
  h.count = s[name + "_count"];
  return h;
}

// What every histogram must be: buckets cumulative (never fewer at a larger bound), the last
// one +Inf and equal to the count.
void expectWellFormed(const ScrapedHistogram& h, const std::string& name) {
  ASSERT_GE(h.buckets.size(), 2u) << name;
  EXPECT_TRUE(std::isinf(h.buckets.back().first)) << name << ": no +Inf bucket";
  for (std::size_t i = 1; i < h.buckets.size(); ++i)
    EXPECT_LE(h.buckets[i - 1].second, h.buckets[i].second) << name << " le=" << h.buckets[i].first;
  EXPECT_EQ(h.buckets.back().second, h.count) << name;
  EXPECT_GE(h.sum, 0.0) << name;
}

TEST(NetMetrics, TextFormatWritesHistogramsCumulatively) {
  Histogram h({0.1, 1.0});
  for (double v : {0.05, 0.5, 0.5, 7.0}) h.observe(v);
  MetricsText m;
  m.histogram("t_seconds", "Times.", h, {{"k", "v"}});
  EXPECT_EQ(m.str(),
            "# HELP t_seconds Times.\n"
            "# TYPE t_seconds histogram\n"
            "t_seconds_bucket{k=\"v\",le=\"0.1\"} 1\n"
            "t_seconds_bucket{k=\"v\",le=\"1\"} 3\n"
            "t_seconds_bucket{k=\"v\",le=\"+Inf\"} 4\n"
            "t_seconds_sum{k=\"v\"} 8.05\n"
            "t_seconds_count{k=\"v\"} 4\n");
}

// Latency, encode time and send-queue delay as histograms that grow while a client streams;
// the build and the process described beside them.
TEST(NetMetrics, HistogramsGrowWhileAClientStreams) {
  NetServerOptions o;
  o.metricsPort = 0;
  o.buildInfo = BuildInfo{"9.8.7", "abc1234-dirty", "Test"};
  TestServer server(-1.0, o);
  const std::uint16_t port = server.net().metricsPort();
  const char* kNames[] = {"probecast_update_latency_seconds", "probecast_encode_duration_seconds",
                          "probecast_send_queue_delay_seconds"};

  const Scrape idle = scrape(port);
  for (const char* name : kNames) {
    EXPECT_EQ(idle.types.at(name), "histogram") << name;
    expectWellFormed(histogramOf(idle, name), name);
  }
  EXPECT_EQ(idle["probecast_build_info{version=\"9.8.7\",revision=\"abc1234-dirty\","
                 "build_type=\"Test\"}"],
            1.0);
  // This process is the server: its figures are plausible for it.
  EXPECT_GT(idle["process_resident_memory_bytes"], 1e6);
  EXPECT_GT(idle["process_virtual_memory_bytes"], idle["process_resident_memory_bytes"]);
  EXPECT_GT(idle["process_cpu_seconds_total"], 0.0);  // the warm-up bake ran
  EXPECT_GE(idle["process_open_fds"], 3.0);
  const double now = double(std::time(nullptr));
  EXPECT_LE(idle["process_start_time_seconds"], now + 1);
  EXPECT_GT(idle["process_start_time_seconds"], now - 24 * 3600);
  EXPECT_EQ(idle.types.at("process_cpu_seconds_total"), "counter");

  client::FieldMirror mirror;
  client::NetClient client(mirror, clientOf(server));
  client.start();
  ASSERT_TRUE(waitFor([&] { return client.stats().synced; }, 20.0));
  const Scrape first = scrape(port);
  // The field changes 10 times a second: more updates reach the client, more latencies.
  ASSERT_TRUE(waitFor(
      [&] {
        return scrape(port)["probecast_update_latency_seconds_count"] >
               first["probecast_update_latency_seconds_count"];
      },
      10.0));
  const Scrape later = scrape(port);
  for (const char* name : kNames) {
    const ScrapedHistogram a = histogramOf(first, name), b = histogramOf(later, name);
    expectWellFormed(a, name);
    expectWellFormed(b, name);
    EXPECT_GT(b.count, 0.0) << name;
    EXPECT_GE(b.count, a.count) << name;
    EXPECT_GE(b.sum, a.sum) << name;
    // Counters per bucket: no bucket ever loses observations.
    for (std::size_t i = 0; i < a.buckets.size() && i < b.buckets.size(); ++i)
      EXPECT_GE(b.buckets[i].second, a.buckets[i].second) << name;
    std::printf("%s: %.0f observations, mean %.3f ms\n", name, b.count,
                b.count > 0 ? b.sum / b.count * 1e3 : 0.0);
  }
  EXPECT_GT(later["probecast_send_queue_delay_seconds_count"],
            idle["probecast_send_queue_delay_seconds_count"]);
  EXPECT_GT(later["process_cpu_seconds_total"], idle["process_cpu_seconds_total"]);
}

// A field of one small volume, for servers that are created and never started.
Field smallLayout() {
  return Field::create({ProbeVolume{glm::vec3(0.0f), 1.0f, glm::ivec3(4)}}, FieldSettings{});
}

NetServerOptions unstartedOptions(const char* bind, std::uint16_t metricsPort) {
  NetServerOptions o;
  o.bindAddress = bind;
  o.port = 0;
  o.tokenKeys = {testKeys().verify};
  o.tls.devSelfSigned = true;
  o.metricsPort = metricsPort;
  return o;
}

TEST(NetMetrics, MetricsPortThatIsTakenIsAnError) {
  NetServerOptions o;
  o.metricsPort = 0;
  TestServer first(-1.0, o);
  FieldHub hub(smallLayout());
  auto second = NetServer::create(hub, unstartedOptions("127.0.0.1", first.net().metricsPort()));
  ASSERT_FALSE(second.ok());
  std::printf("error: %s\n", second.error().message.c_str());
  EXPECT_NE(second.error().message.find("metrics"), std::string::npos);
}

// --udp-port: the UDP socket is bound where asked (a container publishes that port), and a
// port another socket holds is an error naming it.
TEST(NetMetrics, UdpPortIsTheOneAskedAndATakenOneIsAnError) {
  namespace asio = boost::asio;
  asio::io_context io;
  asio::ip::udp::socket probe(io, asio::ip::udp::endpoint(asio::ip::make_address("127.0.0.1"), 0));
  const std::uint16_t free = probe.local_endpoint().port();
  probe.close();
  FieldHub hub(smallLayout());
  NetServerOptions o = unstartedOptions("127.0.0.1", 0);
  o.udpPort = free;
  auto first = NetServer::create(hub, o);
  ASSERT_TRUE(first.ok()) << first.error().message;
  EXPECT_EQ((*first)->udpPort(), free);
  FieldHub other(smallLayout());
  auto second = NetServer::create(other, o);
  ASSERT_FALSE(second.ok());
  EXPECT_NE(second.error().message.find("UDP socket on 127.0.0.1:" + std::to_string(free)),
            std::string::npos)
      << second.error().message;
}

TEST(NetMetrics, ScrapableWhileIdleSocketsAreOpen) {
  NetServerOptions o;
  o.metricsPort = 0;
  TestServer server(-1.0, o);
  const std::uint16_t port = server.net().metricsPort();
  // Sockets that connect and never send a request: as many as the endpoint holds at once,
  // then as many again (each new one takes the place of the oldest idle one).
  std::vector<std::unique_ptr<RawPeer>> idle;
  // Plain TCP: the metrics endpoint speaks HTTP.
  for (int i = 0; i < 32; ++i) idle.push_back(std::make_unique<RawPeer>(port, 0, nullptr, false));
  for (int round = 0; round < 3; ++round) {
    const Scrape s = scrape(port);
    EXPECT_EQ(s["probecast_clients"], 0.0) << "round " << round;
    for (int i = 0; i < 16; ++i) idle.push_back(std::make_unique<RawPeer>(port, 0, nullptr, false));
  }
  // A slow request (half a request line) is one more idle socket, and does not block either.
  RawPeer slow(port, 0, nullptr, false);
  slow.send({'G', 'E', 'T', ' '});
  EXPECT_EQ(scrape(port)["probecast_clients"], 0.0);
}

TEST(NetMetrics, BearerTokenIsRequiredWhenSet) {
  NetServerOptions o;
  o.metricsPort = 0;
  o.metricsToken = "s3cret-metrics";
  TestServer server(-1.0, o);
  const std::uint16_t port = server.net().metricsPort();
  for (const std::string& header : {std::string(), std::string("Authorization: Bearer wrong\r\n"),
                                    std::string("Authorization: Bearer s3cret-metricsX\r\n"),
                                    std::string("Authorization: Basic s3cret-metrics\r\n")}) {
    auto r = httpGet(port, "/metrics", "GET", header);
    ASSERT_TRUE(r.has_value());
    EXPECT_EQ(r->status, 401) << header;
    EXPECT_EQ(r->body.find("probecast_"), std::string::npos) << "figures leaked";
  }
  auto ok = httpGet(port, "/metrics", "GET", "Authorization: Bearer s3cret-metrics\r\n");
  ASSERT_TRUE(ok.has_value());
  EXPECT_EQ(ok->status, 200);
  EXPECT_NE(ok->body.find("probecast_clients"), std::string::npos);
}

// Orchestrators' probes: /healthz answers while the endpoint runs, /readyz follows the
// server's readiness; neither asks for the token that /metrics asks for.
TEST(NetMetrics, HealthAndReadinessAnswerWithoutTheToken) {
  auto ready = std::make_shared<std::atomic<bool>>(false);
  NetServerOptions o;
  o.metricsPort = 0;
  o.metricsToken = "s3cret-metrics";
  o.ready = [ready] { return ready->load(); };
  TestServer server(-1.0, o);
  const std::uint16_t port = server.net().metricsPort();
  const auto status = [&](const std::string& target, const std::string& method = "GET") {
    auto r = httpGet(port, target, method);
    return r ? r->status : -1;
  };
  EXPECT_EQ(status("/healthz"), 200);
  EXPECT_EQ(status("/readyz"), 503);
  ready->store(true);
  EXPECT_EQ(status("/readyz"), 200);
  EXPECT_EQ(status("/readyz", "HEAD"), 200);
  ready->store(false);
  EXPECT_EQ(status("/readyz"), 503);
  // Only GET and HEAD are probes; the figures still need the token.
  EXPECT_EQ(status("/healthz", "POST"), 401);
  EXPECT_EQ(status("/metrics"), 401);
  auto body = httpGet(port, "/healthz");
  ASSERT_TRUE(body.has_value());
  EXPECT_EQ(body->body, "ok\n");
  EXPECT_EQ(body->body.find("probecast_"), std::string::npos);
}

// Without a readiness callback (the field server), a running endpoint is ready.
TEST(NetMetrics, ReadyByDefault) {
  NetServerOptions o;
  o.metricsPort = 0;
  TestServer server(-1.0, o);
  auto r = httpGet(server.net().metricsPort(), "/readyz");
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->status, 200);
  auto missing = httpGet(server.net().metricsPort(), "/other");
  ASSERT_TRUE(missing.has_value());
  EXPECT_EQ(missing->status, 404);
}

TEST(NetMetrics, EndpointListensOnLoopbackByDefault) {
  // The session port on every address; the metrics, without --metrics-bind, on 127.0.0.1.
  FieldHub hub(smallLayout());
  auto server = NetServer::create(hub, unstartedOptions("0.0.0.0", 0));
  ASSERT_TRUE(server.ok()) << server.error().message;
  namespace asio = boost::asio;
  const auto reachable = [](const char* address, std::uint16_t port) {
    asio::io_context io;
    asio::ip::tcp::socket socket(io);
    boost::system::error_code ec;
    socket.connect({asio::ip::make_address(address), port}, ec);
    return !ec;
  };
  EXPECT_TRUE(reachable("127.0.0.2", (*server)->port()));
  EXPECT_TRUE(reachable("127.0.0.1", (*server)->metricsPort()));
  EXPECT_FALSE(reachable("127.0.0.2", (*server)->metricsPort()));
}

TEST(Log, UntrustedStringsAreQuotedEscapedAndCut) {
  EXPECT_EQ(quoteUntrusted("plain name"), "\"plain name\"");
  EXPECT_EQ(quoteUntrusted("a\"b\\c"), "\"a\\\"b\\\\c\"");
  EXPECT_EQ(quoteUntrusted("x\x1b[2J\r\ny\tz\x7f"), "\"x\\x1b[2J\\r\\ny\\tz\\x7f\"");
  // Not UTF-8 (a stray byte, a cut sequence, an overlong '/'), C1 controls and bidirectional
  // overrides are escaped; other UTF-8 passes.
  EXPECT_EQ(quoteUntrusted("\xff\xc3"), "\"\\xff\\xc3\"");
  EXPECT_EQ(quoteUntrusted("\xc0\xaf"), "\"\\xc0\\xaf\"");
  EXPECT_EQ(quoteUntrusted("\xc2\x9b"
                           "31m"),
            "\"\\u009b31m\"");
  EXPECT_EQ(quoteUntrusted("\xe2\x80\xae"
                           "abc"),
            "\"\\u202eabc\"");
  EXPECT_EQ(quoteUntrusted("caf\xc3\xa9"), "\"caf\xc3\xa9\"");
  // For a log field: the same escapes, no quotes, cut without a marker.
  EXPECT_EQ(escapeUntrusted("a\x1b\"b", 6), "a\\x1b");
  // Cut after maxBytes of output, never inside an escape, with the count left out.
  const std::string huge(4u << 20, '\n');
  const std::string quoted = quoteUntrusted(huge, 200);
  std::string expected = "\"";
  for (int i = 0; i < 100; ++i) expected += "\\n";
  expected += "\"...(" + std::to_string((4u << 20) - 100) + " more bytes)";
  EXPECT_EQ(quoted, expected);
}

TEST(Log, LinesStayOneLineWhateverTheyCarry) {
  // Text: a message with a line break and an escape sequence stays one line.
  const std::string text = formatLogLine(LogFormat::Text, "t", LogLevel::Warn,
                                         "bad\n[t] [error] forged\x1b[0m", {{"k", "v\xff"}});
  EXPECT_EQ(text, "[t] [warn] bad\\x0a[t] [error] forged\\x1b[0m k=\"v\\ufffd\"");
  // JSON: bytes that are not UTF-8 become U+FFFD, DEL and C1 controls are escaped.
  const std::string json =
      formatLogLine(LogFormat::Json, "t", LogLevel::Info, "m", {{"name", "a\xff\x7f\xc2\x9b"}});
  EXPECT_EQ(json,
            "{\"ts\":\"t\",\"level\":\"info\",\"msg\":\"m\",\"name\":\"a\\ufffd\\u007f\\u009b\"}");
}

TEST(Log, TextLinesCarryFieldsAsKeyValue) {
  const std::string line = formatLogLine(
      LogFormat::Text, "2024-05-01 12:00:00.000", LogLevel::Warn, "client disconnected",
      {{"session", 42}, {"peer", "127.0.0.1:5000"}, {"detail", "no write progress"}});
  EXPECT_EQ(line,
            "[2024-05-01 12:00:00.000] [warn] client disconnected session=42 "
            "peer=127.0.0.1:5000 detail=\"no write progress\"");
}

TEST(Log, JsonLinesAreOneEscapedObject) {
  const std::string line =
      formatLogLine(LogFormat::Json, "2024-05-01T10:00:00.000Z", LogLevel::Info, "say \"hi\"",
                    {{"session", 7}, {"name", "a\\b\nc"}, {"seconds", 1.5}});
  EXPECT_EQ(line,
            "{\"ts\":\"2024-05-01T10:00:00.000Z\",\"level\":\"info\",\"msg\":\"say \\\"hi\\\"\","
            "\"session\":7,\"name\":\"a\\\\b\\nc\",\"seconds\":1.500000}");
}

TEST(Log, LevelAndFormatNamesParse) {
  EXPECT_EQ(parseLogLevel("warn"), LogLevel::Warn);
  EXPECT_EQ(parseLogLevel("debug"), LogLevel::Debug);
  EXPECT_FALSE(parseLogLevel("loud").has_value());
  EXPECT_EQ(parseLogFormat("json"), LogFormat::Json);
  EXPECT_FALSE(parseLogFormat("xml").has_value());
}

}  // namespace
}  // namespace pc::nettest
