// probecast-report: plots of a run's time series. Reads series CSVs (probecast-loadgen
// --series, probecast-client --series) and writes, per CSV, PNG plots of the figures it holds
// (bandwidth, latency percentiles, staleness, held-field PSNR, ...) and one HTML page showing
// them (tools/report/). Drawn here, with no plotting library.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "common/series_csv.h"
#include "tools/command_line.h"
#include "tools/report/series_report.h"

namespace {

int fail(const std::string& message) {
  std::fprintf(stderr, "probecast-report: error: %s\n", message.c_str());
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "Plot time series of a run: for each SERIES.csv (probecast-loadgen --series, "
      "probecast-client --series), PNG plots of the columns it has (bandwidth, latency "
      "percentiles, staleness, held-field PSNR, clients, gaps, version lag, frame time) and "
      "an HTML page showing them, named after the CSV: <name>_<plot>.png, <name>.html. Exit "
      "0 done, 1 a CSV that cannot be plotted (missing, no time_s column, a field that is not "
      "a number, nothing to plot) or an output not written."};
  std::vector<std::string> inputs;
  std::string outDir = "report";
  pc::report::ReportOptions options;
  app.add_option("SERIES", inputs, "series CSV files")->required();
  app.add_option("--out", outDir, "folder for the plots and pages");
  app.add_option("--width", options.width, "plot width, pixels")->check(CLI::Range(240, 4096));
  app.add_option("--height", options.height, "plot height, pixels")->check(CLI::Range(160, 4096));
  if (auto code = pc::parseCommandLine(app, argc, argv)) return *code;

  for (const std::string& input : inputs) {
    auto table = pc::readSeries(input);
    if (!table) return fail(table.error().message);
    const std::string run = std::filesystem::path(input).stem().string();
    auto files = pc::report::writeReport(*table, input, run, outDir, options);
    if (!files) return fail(files.error().message);
    for (const auto& png : files->pngs) std::printf("wrote %s\n", png.c_str());
    std::printf("wrote %s\n", files->html.c_str());
  }
  return 0;
}
