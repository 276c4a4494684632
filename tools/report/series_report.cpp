#include "series_report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>

#include "common/image.h"
#include "line_chart.h"

namespace pc::report {

namespace {

constexpr const char* kTime = "time_s";

// Whether the column exists and holds a value in some row.
bool hasValues(const SeriesTable& t, const std::string& column) {
  const std::vector<double> v = t.values(column);
  return std::any_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); });
}

bool plottable(const SeriesTable& t, const PlotSpec& spec) {
  return std::any_of(spec.columns.begin(), spec.columns.end(),
                     [&](const auto& c) { return hasValues(t, c.first); });
}

std::string escapeHtml(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out.push_back(c);
    }
  }
  return out;
}

std::string number(double v) {
  if (!std::isfinite(v)) return "";
  char buf[32];
  // Four significant digits, never an exponent for the sizes series hold (kbit/s in the tens
  // of thousands).
  if (std::abs(v) >= 1e3 && std::abs(v) < 1e12) {
    std::snprintf(buf, sizeof buf, "%.0f", v);
  } else {
    std::snprintf(buf, sizeof buf, "%.4g", v);
  }
  return buf;
}

// A row of the page's table: a column's mean, p50, p95 and max over the rows with a value.
std::string statsRow(const SeriesTable& t, const std::string& column) {
  std::vector<double> v;
  for (double x : t.values(column)) {
    if (std::isfinite(x)) v.push_back(x);
  }
  if (v.empty()) return "";
  std::sort(v.begin(), v.end());
  double sum = 0;
  for (double x : v) sum += x;
  const auto at = [&](double q) { return v[std::size_t(q * double(v.size() - 1) + 0.5)]; };
  return "<tr><td>" + escapeHtml(column) + "</td><td>" + std::to_string(v.size()) + "</td><td>" +
         number(sum / double(v.size())) + "</td><td>" + number(at(0.5)) + "</td><td>" +
         number(at(0.95)) + "</td><td>" + number(v.back()) + "</td></tr>\n";
}

}  // namespace

const std::vector<PlotSpec>& plotSpecs() {
  static const std::vector<PlotSpec> specs = {
      {"bandwidth",
       "BANDWIDTH RECEIVED",
       "KBIT/S",
       {{"kbit_s_total", "ALL CLIENTS"}, {"kbit_s", "RECEIVED"}}},
      {"bandwidth_per_client",
       "BANDWIDTH PER CLIENT",
       "KBIT/S",
       {{"kbit_s_per_client", "MEAN CLIENT"}}},
      {"latency",
       "UPDATE LATENCY",
       "MS",
       {{"latency_p50_ms", "P50"}, {"latency_p95_ms", "P95"}, {"latency_p99_ms", "P99"}}},
      {"staleness",
       "STALENESS",
       "MS",
       {{"staleness_p95_ms", "P95"}, {"staleness_mean_ms", "MEAN"}, {"staleness_max_ms", "MAX"}}},
      {"psnr", "HELD FIELD PSNR", "DB", {{"held_psnr_p5_db", "P5 OVER CLIENTS"}}},
      {"clients", "CLIENTS", "CLIENTS", {{"clients", "IN A SESSION"}, {"synced", "SYNCED"}}},
      {"gaps", "LONGEST WAIT FOR A DATAGRAM", "MS", {{"gap_max_ms", "MAX OVER CLIENTS"}}},
      {"version_lag", "FIELD VERSION LAG", "VERSIONS", {{"version_lag_max", "MAX"}}},
      {"frame_time", "FRAME TIME", "MS", {{"frame_ms_mean", "MEAN"}, {"frame_ms_max", "MAX"}}},
  };
  return specs;
}

Status checkPlottable(const SeriesTable& table, const std::string& source) {
  if (table.column(kTime) < 0) {
    return Error{source + ": no " + kTime +
                 " column (a series of probecast-loadgen --series or probecast-client --series "
                 "has one)"};
  }
  if (table.rows.empty()) return Error{source + ": no rows after the header"};
  const auto& specs = plotSpecs();
  if (std::none_of(specs.begin(), specs.end(),
                   [&](const PlotSpec& s) { return plottable(table, s); })) {
    std::string known;
    for (const PlotSpec& s : specs) {
      for (const auto& c : s.columns) known += (known.empty() ? "" : ", ") + c.first;
    }
    return Error{source + ": no column to plot with a value (known columns: " + known + ")"};
  }
  return Status::success();
}

Result<ReportFiles> writeReport(const SeriesTable& table, const std::string& source,
                                const std::string& run, const std::filesystem::path& outDir,
                                const ReportOptions& options) {
  if (Status ok = checkPlottable(table, source); !ok) return ok.error();
  std::error_code ec;
  std::filesystem::create_directories(outDir, ec);
  if (ec) return Error{"cannot create the folder " + outDir.string() + ": " + ec.message()};

  ReportFiles files;
  std::string figures, plots;
  const std::vector<double> time = table.values(kTime);
  for (const PlotSpec& spec : plotSpecs()) {
    if (!plottable(table, spec)) continue;
    Chart chart{spec.title, "TIME (S)", spec.yLabel, time, {}};
    for (const auto& [column, label] : spec.columns) {
      if (!hasValues(table, column)) continue;
      chart.lines.push_back({label, table.values(column), lineColor(chart.lines.size())});
      figures += statsRow(table, column);
    }
    const std::string name = run + "_" + spec.name + ".png";
    const Canvas canvas = drawChart(chart, options.width, options.height);
    if (Status w = writePng(outDir / name, canvas.toImage()); !w) return w.error();
    files.pngs.push_back(outDir / name);
    plots += "<h2>" + escapeHtml(spec.title) + "</h2>\n<img src=\"" + escapeHtml(name) +
             "\" width=\"" + std::to_string(options.width) + "\" height=\"" +
             std::to_string(options.height) + "\" alt=\"" + escapeHtml(spec.title) + "\">\n";
  }

  const double seconds = time.empty() ? 0.0 : time.back() - time.front();
  files.html = outDir / (run + ".html");
  std::ofstream html(files.html);
  html << "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>" << escapeHtml(run)
       << "</title>\n<style>body{font-family:sans-serif;margin:2em}table{border-collapse:"
          "collapse}td,th{border:1px solid #ccc;padding:2px 8px;text-align:right}"
          "td:first-child{text-align:left}</style></head>\n<body>\n<h1>"
       << escapeHtml(run) << "</h1>\n<p>" << escapeHtml(source) << ": " << table.rows.size()
       << " rows over " << number(seconds) << " s.</p>\n"
       << "<table><tr><th>column</th><th>rows</th><th>mean</th><th>p50</th><th>p95</th>"
          "<th>max</th></tr>\n"
       << figures << "</table>\n"
       << plots << "</body></html>\n";
  html.close();
  if (!html) return Error{"cannot write " + files.html.string()};
  return files;
}

}  // namespace pc::report
