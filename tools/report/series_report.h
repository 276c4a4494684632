// probecast-report's pages: from a series CSV (probecast-loadgen --series, probecast-client
// --series) the plots its columns allow (bandwidth, latency percentiles, staleness, held-field
// PSNR, ...) as PNG files and one HTML page that shows them with the run's figures.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "common/result.h"
#include "common/series_csv.h"

namespace pc::report {

// One plot: drawn when the series has at least one of its columns with a value.
struct PlotSpec {
  std::string name;   // the PNG's name after the run's: <run>_<name>.png
  std::string title;  // on the plot and the page
  std::string yLabel;
  std::vector<std::pair<std::string, std::string>> columns;  // (column, legend label)
};
const std::vector<PlotSpec>& plotSpecs();

struct ReportOptions {
  int width = 720, height = 300;  // of each plot, pixels
};

struct ReportFiles {
  std::filesystem::path html;
  std::vector<std::filesystem::path> pngs;
};

// Checks that `table` can be plotted: rows, a time_s column and a column of some plot.
// The error says what is missing, after `source` (the CSV's name).
Status checkPlottable(const SeriesTable& table, const std::string& source);

// Writes <run>_<plot>.png for every plot the table allows and <run>.html into `outDir`.
Result<ReportFiles> writeReport(const SeriesTable& table, const std::string& source,
                                const std::string& run, const std::filesystem::path& outDir,
                                const ReportOptions& options);

}  // namespace pc::report
