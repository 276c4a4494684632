// The load report as JSON and as a table.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <nlohmann/json.hpp>

#include "load_generator.h"

namespace pc::load {

namespace {

nlohmann::json toJson(const Percentiles& p) {
  return {{"count", p.count}, {"p50", p.p50}, {"p95", p.p95},
          {"p99", p.p99},     {"max", p.max}, {"mean", p.mean}};
}

nlohmann::json toJson(const ClassReport& c) {
  return {{"link_mbit", c.linkMbit},
          {"clients", c.clients},
          {"starved", c.starved},
          {"latency_ms", toJson(c.latencyMs)},
          {"kbit_per_client", toJson(c.kbitPerClient)},
          {"held_psnr_db_p5", c.heldPsnrP5},
          {"oldest_change_s_p95", c.oldestChangeP95},
          {"link_drop_share", c.linkDropShare},
          {"rate_mbit_mean", c.rateMbitMean}};
}

std::string format(const char* fmt, auto... args) {
  char line[512];
  std::snprintf(line, sizeof line, fmt, args...);
  return line;
}

}  // namespace

Result<std::vector<LinkClass>> parseRateMix(const std::string& text) {
  std::vector<LinkClass> out;
  std::size_t at = 0;
  while (at <= text.size()) {
    const std::size_t comma = std::min(text.find(',', at), text.size());
    const std::string item = text.substr(at, comma - at);
    const std::size_t colon = item.find(':');
    LinkClass c;
    char* end = nullptr;
    const std::string rate = item.substr(0, colon);
    c.mbit = std::strtod(rate.c_str(), &end);
    bool ok = colon != std::string::npos && end && *end == 0 && !rate.empty();
    if (ok) {
      const std::string share = item.substr(colon + 1);
      c.share = std::strtod(share.c_str(), &end);
      ok = end && *end == 0 && !share.empty();
    }
    if (!ok || !(c.mbit > 0) || !(c.share > 0) || !std::isfinite(c.mbit) || !std::isfinite(c.share))
      return Error{"rate mix: '" + item + "' is not MBIT:SHARE with both above 0 (e.g. 1:0.5)"};
    out.push_back(c);
    at = comma + 1;
  }
  if (out.empty()) return Error{"rate mix: empty"};
  return out;
}

std::string reportJson(const LoadReport& r) {
  const LoadOptions& o = r.options;
  nlohmann::json j;
  j["options"] = {{"host", o.host},
                  {"port", o.port},
                  {"clients", o.clients},
                  {"threads", o.threads},
                  {"tcp_only", o.tcpOnly},
                  {"ramp_s", o.rampSeconds},
                  {"session_s", o.sessionSeconds},
                  {"max_sessions", o.maxSessions},
                  {"starve_s", o.starveSeconds},
                  {"same_clock", o.sameClock},
                  {"keep_field", o.keepField},
                  {"share_decoding", o.shareDecoding},
                  {"min_held_psnr_db", o.minHeldPsnr},
                  {"max_change_age_s", o.maxChangeAge},
                  {"link_queue_s", o.linkQueueSeconds}};
  nlohmann::json links = nlohmann::json::array();
  for (const LinkClass& l : o.links) links.push_back({{"mbit", l.mbit}, {"share", l.share}});
  j["options"]["links"] = std::move(links);
  j["window_s"] = r.seconds;
  j["sessions_started"] = r.sessionsStarted;
  j["latency_ms"] = toJson(r.latencyMs);
  j["staleness_ms"] = toJson(r.stalenessMs);
  j["kbit_per_client"] = toJson(r.kbitPerClient);
  j["unmatched_updates"] = r.unmatchedUpdates;
  j["bricks_applied"] = r.bricksApplied;
  j["repair_bricks"] = r.repairBricks;
  j["gap_reports"] = r.gapReports;
  j["datagrams"] = r.datagrams;
  j["errors"] = r.errors;
  j["error_samples"] = r.errorSamples;
  j["starved_clients"] = r.starvedClients;
  j["all"] = toJson(r.all);
  nlohmann::json classes = nlohmann::json::array();
  for (const ClassReport& c : r.classes) classes.push_back(toJson(c));
  j["classes"] = std::move(classes);
  j["decoding"] = {{"decoded", r.decodedPayloads},
                   {"shared", r.sharedDecodes},
                   {"content_mismatches", r.contentMismatches}};
  j["memory_mb"] = {{"loadgen_resident", r.residentMb},
                    {"decoded_field_per_client_if_kept", r.decodedFieldMb},
                    {"brick_codes_per_client_if_not_shared", r.brickCodesMb}};
  nlohmann::json clients = nlohmann::json::array();
  for (const ClientReport& c : r.perClient) {
    clients.push_back({{"index", c.index},
                       {"sessions", c.sessions},
                       {"session_s", c.sessionSeconds},
                       {"bytes_down", c.bytesDown},
                       {"bytes_up", c.bytesUp},
                       {"kbit_down", c.kbitDown},
                       {"kbit_up", c.kbitUp},
                       {"datagrams", c.datagrams},
                       {"bricks_applied", c.bricksApplied},
                       {"repair_bricks", c.repairBricks},
                       {"gap_reports", c.gapReports},
                       {"stale_updates", c.staleUpdates},
                       {"errors", c.errors},
                       {"last_error", c.lastError},
                       {"max_datagram_gap_s", c.maxDatagramGap},
                       {"max_staleness_s", c.maxStaleness},
                       {"sync_s", c.syncSeconds},
                       {"latency_ms", toJson(c.latencyMs)},
                       {"reports", c.reports},
                       {"held_psnr_db", c.heldPsnrDb},
                       {"oldest_change_s_p95", c.oldestChangeP95},
                       {"rate_mbit", c.rateMbit},
                       {"quality_level", c.qualityLevel},
                       {"link_class", c.linkClass},
                       {"link_mbit", c.linkMbit},
                       {"link_drops", c.linkDrops},
                       {"starved", c.starved},
                       {"starved_why", c.starvedWhy}});
  }
  j["clients"] = std::move(clients);
  return j.dump(1) + "\n";
}

std::string reportTable(const LoadReport& r) {
  std::string s;
  s += format("%d clients (%s), %.1f s window, %llu sessions started\n", r.clients,
              r.options.tcpOnly ? "TCP only" : "UDP datagrams", r.seconds,
              (unsigned long long)r.sessionsStarted);
  s += format("%-28s %10s %10s %10s %10s %10s\n", "", "p50", "p95", "p99", "max", "samples");
  auto row = [&](const char* name, const Percentiles& p) {
    s += format("%-28s %10.2f %10.2f %10.2f %10.2f %10llu\n", name, p.p50, p.p95, p.p99, p.max,
                (unsigned long long)p.count);
  };
  row("update latency (ms)", r.latencyMs);
  row("staleness (ms)", r.stalenessMs);
  row("down per client (kbit/s)", r.kbitPerClient);
  s += format(
      "bricks applied %llu, repairs %llu, gap reports %llu, datagrams %llu, unmatched updates "
      "%llu\n",
      (unsigned long long)r.bricksApplied, (unsigned long long)r.repairBricks,
      (unsigned long long)r.gapReports, (unsigned long long)r.datagrams,
      (unsigned long long)r.unmatchedUpdates);
  s += format("errors %llu, starved clients %d\n", (unsigned long long)r.errors, r.starvedClients);
  s += format("%-10s %7s %7s %9s %9s %9s %11s %9s %9s\n", "link", "clients", "starved", "p99 ms",
              "kbit p50", "rate Mb/s", "held p5 dB", "age p95 s", "drops %");
  auto classRow = [&](const char* name, const ClassReport& c) {
    s += format("%-10s %7d %7d %9.1f %9.1f %9.3f %11.2f %9.3f %9.2f\n", name, c.clients, c.starved,
                c.latencyMs.p99, c.kbitPerClient.p50, c.rateMbitMean, c.heldPsnrP5,
                c.oldestChangeP95, 100.0 * c.linkDropShare);
  };
  classRow("all", r.all);
  for (const ClassReport& c : r.classes) classRow(format("%g Mbit/s", c.linkMbit).c_str(), c);
  for (const std::string& e : r.errorSamples) s += "  error: " + e + "\n";
  int shown = 0;
  for (const ClientReport& c : r.perClient) {
    if (c.starved && shown++ < 5)
      s += format("  client %d starved: %s\n", c.index, c.starvedWhy.c_str());
  }
  s += format("decoding: %llu payloads decoded, %llu shared, %llu content mismatches\n",
              (unsigned long long)r.decodedPayloads, (unsigned long long)r.sharedDecodes,
              (unsigned long long)r.contentMismatches);
  s += format(
      "memory: loadgen resident %.1f MB (%.2f MB per client); a decoded field would be "
      "%.2f MB per client, unshared brick codes %.2f MB\n",
      r.residentMb, r.residentMb / std::max(1, r.clients), r.decodedFieldMb, r.brickCodesMb);
  return s;
}

}  // namespace pc::load
