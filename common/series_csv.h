// Time series as CSV files: a header line naming the columns, then one row of numbers per
// sample (probecast-loadgen --series, probecast-client --series; read by probecast-report).
// A value that was not measured in a row (no latency sample in that second) is an empty
// field, read back as NaN. Rows are flushed as they are written, so a series of a run that
// was stopped early holds every row until then.
#pragma once

#include <cstddef>
#include <filesystem>
#include <fstream>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "result.h"

namespace pc {

class SeriesWriter {
 public:
  // Creates (truncates) the file and writes the header.
  static Result<std::unique_ptr<SeriesWriter>> create(const std::filesystem::path& path,
                                                      std::vector<std::string> columns);
  // One row: as many values as columns (NaN: not measured).
  Status write(std::span<const double> values);
  const std::filesystem::path& path() const { return path_; }

 private:
  SeriesWriter(std::filesystem::path path, std::size_t columns)
      : path_(std::move(path)), columns_(columns) {}
  std::filesystem::path path_;
  std::size_t columns_;
  std::ofstream out_;
};

struct SeriesTable {
  std::vector<std::string> columns;
  std::vector<std::vector<double>> rows;  // each as many values as columns
  // The column's index, or -1 when the series has none of that name.
  int column(const std::string& name) const;
  // The column's values over the rows (empty when it has none).
  std::vector<double> values(const std::string& name) const;
};

// Reads a series; an Error names the file, the line and what is wrong with it (no header, a
// row with more or fewer fields than the header, a field that is not a number).
Result<SeriesTable> readSeries(const std::filesystem::path& path);

}  // namespace pc
