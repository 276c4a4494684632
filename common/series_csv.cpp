#include "series_csv.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>

namespace pc {

namespace {

std::vector<std::string> splitFields(const std::string& line) {
  std::vector<std::string> fields;
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = line.find(',', start);
    fields.push_back(line.substr(start, comma - start));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return fields;
}

}  // namespace

Result<std::unique_ptr<SeriesWriter>> SeriesWriter::create(const std::filesystem::path& path,
                                                           std::vector<std::string> columns) {
  std::unique_ptr<SeriesWriter> w(new SeriesWriter(path, columns.size()));
  w->out_.open(path, std::ios::trunc);
  if (!w->out_) return Error{"cannot write the series file " + path.string()};
  for (std::size_t i = 0; i < columns.size(); ++i) w->out_ << (i ? "," : "") << columns[i];
  w->out_ << "\n" << std::flush;
  if (!w->out_) return Error{"cannot write the series file " + path.string()};
  return w;
}

Status SeriesWriter::write(std::span<const double> values) {
  if (values.size() != columns_) {
    return Error{"series " + path_.string() + ": a row of " + std::to_string(values.size()) +
                 " values for " + std::to_string(columns_) + " columns"};
  }
  std::string line;
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (i) line.push_back(',');
    if (std::isfinite(values[i])) {
      char buf[32];
      // Ten significant digits: counters (bytes received) stay exact into the gigabytes.
      std::snprintf(buf, sizeof buf, "%.10g", values[i]);
      line += buf;
    }
  }
  out_ << line << "\n" << std::flush;
  if (!out_) return Error{"cannot write the series file " + path_.string()};
  return Status::success();
}

int SeriesTable::column(const std::string& name) const {
  for (std::size_t i = 0; i < columns.size(); ++i) {
    if (columns[i] == name) return int(i);
  }
  return -1;
}

std::vector<double> SeriesTable::values(const std::string& name) const {
  const int c = column(name);
  std::vector<double> out;
  if (c < 0) return out;
  for (const auto& row : rows) out.push_back(row[std::size_t(c)]);
  return out;
}

Result<SeriesTable> readSeries(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) return Error{"cannot read the series file " + path.string()};
  SeriesTable t;
  std::string line;
  if (!std::getline(in, line) || line.empty())
    return Error{path.string() + ": no header line (expected column names, e.g. time_s,...)"};
  t.columns = splitFields(line);
  for (const std::string& c : t.columns) {
    if (c.empty()) return Error{path.string() + ":1: an empty column name in the header"};
  }
  for (int number = 2; std::getline(in, line); ++number) {
    if (line.empty()) continue;
    const std::vector<std::string> fields = splitFields(line);
    const std::string where = path.string() + ":" + std::to_string(number) + ": ";
    if (fields.size() != t.columns.size()) {
      return Error{where + std::to_string(fields.size()) + " fields, the header names " +
                   std::to_string(t.columns.size())};
    }
    std::vector<double> row;
    for (std::size_t i = 0; i < fields.size(); ++i) {
      if (fields[i].empty()) {
        row.push_back(std::numeric_limits<double>::quiet_NaN());
        continue;
      }
      char* end = nullptr;
      const double v = std::strtod(fields[i].c_str(), &end);
      if (end != fields[i].c_str() + fields[i].size() || !std::isfinite(v)) {
        return Error{where + "'" + fields[i].substr(0, 40) + "' in column " + t.columns[i] +
                     " is not a number"};
      }
      row.push_back(v);
    }
    t.rows.push_back(std::move(row));
  }
  return t;
}

}  // namespace pc
