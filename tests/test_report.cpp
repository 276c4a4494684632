// probecast-report: plots drawn from a series CSV decode as PNGs of the asked size, with the
// lines where the values put them, tick labels drawn, and an HTML page naming every plot; a
// CSV that cannot be plotted ends it with exit code 1 and a message saying why. Also its tick
// rules and the canvas's text (tools/report/, compiled into this test).
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "common/image.h"
#include "test_child_process.h"
#include "tools/report/line_chart.h"

namespace pc::report {
namespace {

namespace fs = std::filesystem;

struct ToolRun {
  int code = -1;
  std::string output;
};

std::string readText(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

ToolRun runReport(std::vector<std::string> args, const fs::path& dir) {
  args.insert(args.begin(), std::string(PC_BUILD_DIR) + "/bin/probecast-report");
  const fs::path log = dir / "report.log";
  fs::remove(log);
  pc::test::Child child(args, log);
  for (int i = 0; i < 600 && !child.exited(); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_TRUE(child.exited()) << "probecast-report did not end";
  return {child.exited() ? child.exitCode() : -1, readText(log)};
}

fs::path freshDir(const std::string& name) {
  const fs::path dir = fs::path(PC_BUILD_DIR) / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

void writeText(const fs::path& path, const std::string& text) { std::ofstream(path) << text; }

// A loadgen-like series of 20 s: bandwidth rising 100 kbit/s a second, latency p95 constant at
// 50 ms but not measured at 10 s, the held field's PSNR from 40 to 45 dB.
std::string loadSeries() {
  std::string csv =
      "time_s,clients,synced,kbit_s_total,kbit_s_per_client,latency_p50_ms,latency_p95_ms,"
      "latency_p99_ms,staleness_p95_ms,held_psnr_p5_db,errors\n";
  for (int t = 1; t <= 20; ++t) {
    const std::string latency = t == 10 ? "," : "20,50";
    csv += std::to_string(t) + ",10,10," + std::to_string(100 * t) + "," + std::to_string(10 * t) +
           "," + latency + ",80,120," + std::to_string(40.0 + 0.25 * t) + ",0\n";
  }
  return csv;
}

constexpr Rgba kFirstLine{31, 119, 180, 255};  // lineColor(0)

bool isColor(const Image8& image, int x, int y, Rgba c) {
  const unsigned char* p = &image.rgb[3 * (std::size_t(y) * std::size_t(image.width) + x)];
  return p[0] == c.r && p[1] == c.g && p[2] == c.b;
}

// The mean row of the pixels of colour `c` in column x of the plot area; -1 without any.
double rowOf(const Image8& image, int x, Rgba c, const PlotArea& a) {
  double sum = 0;
  int n = 0;
  for (int y = a.y0; y <= a.y1; ++y) {
    if (isColor(image, x, y, c)) sum += y, ++n;
  }
  return n ? sum / n : -1.0;
}

TEST(Report, PlotsAndPageOfALoadSeries) {
  const fs::path dir = freshDir("test-report");
  writeText(dir / "run.csv", loadSeries());
  const ToolRun r = runReport({(dir / "run.csv").string(), "--out", (dir / "out").string(),
                               "--width", "400", "--height", "220"},
                              dir);
  ASSERT_EQ(r.code, 0) << r.output;

  const PlotArea a = plotArea(400, 220);
  for (const char* plot :
       {"bandwidth", "bandwidth_per_client", "latency", "staleness", "psnr", "clients"}) {
    const fs::path png = dir / "out" / (std::string("run_") + plot + ".png");
    auto image = readPng(png);
    ASSERT_TRUE(image.ok()) << plot << ": " << image.error().message;
    EXPECT_EQ(image->width, 400) << plot;
    EXPECT_EQ(image->height, 220) << plot;
    // Tick labels and the axis label under the plot area: ink on the white margin.
    int ink = 0;
    for (int y = a.y1 + 6; y < 220; ++y) {
      for (int x = 0; x < 400; ++x) ink += isColor(*image, x, y, {40, 40, 40, 255});
    }
    EXPECT_GT(ink, 50) << plot << ": no labels under the plot";
  }
  // Plots of columns the series lacks are not drawn.
  EXPECT_FALSE(fs::exists(dir / "out" / "run_frame_time.png"));
  EXPECT_FALSE(fs::exists(dir / "out" / "run_version_lag.png"));

  // Bandwidth rises over time: its line, in every column of the plot's left part, is lower on
  // the image at 25% of the width than at 55% (the legend covers the top right).
  auto bandwidth = readPng(dir / "out" / "run_bandwidth.png");
  ASSERT_TRUE(bandwidth.ok());
  const int early = a.x0 + (a.x1 - a.x0) / 4, late = a.x0 + (a.x1 - a.x0) * 55 / 100;
  const double earlyRow = rowOf(*bandwidth, early, kFirstLine, a);
  const double lateRow = rowOf(*bandwidth, late, kFirstLine, a);
  ASSERT_GE(earlyRow, 0) << "no bandwidth line at x=" << early;
  ASSERT_GE(lateRow, 0) << "no bandwidth line at x=" << late;
  EXPECT_GT(earlyRow, lateRow + 20);
  // Constant latency p50 (20 ms, the first line): the same row wherever it is drawn, with a
  // gap where the second of 10 s has no value.
  auto latency = readPng(dir / "out" / "run_latency.png");
  ASSERT_TRUE(latency.ok());
  const double row1 = rowOf(*latency, early, kFirstLine, a);
  const double row2 = rowOf(*latency, a.x0 + (a.x1 - a.x0) * 3 / 4, kFirstLine, a);
  ASSERT_GE(row1, 0);
  EXPECT_NEAR(row1, row2, 1.0);
  const int atTen = int(std::lround(a.x0 + (10.0 - 0.0) / 20.0 * (a.x1 - a.x0)));
  EXPECT_LT(rowOf(*latency, atTen, kFirstLine, a), 0) << "a line drawn across the missing value";

  // The page names every plot written, and each exists.
  const std::string html = readText(dir / "out" / "run.html");
  int images = 0;
  for (std::size_t at = html.find("<img src=\""); at != std::string::npos;
       at = html.find("<img src=\"", at + 1)) {
    const std::size_t start = at + 10, end = html.find('"', start);
    const std::string name = html.substr(start, end - start);
    EXPECT_TRUE(fs::exists(dir / "out" / name)) << name;
    ++images;
  }
  EXPECT_EQ(images, 6);
  EXPECT_NE(html.find("src=\"run_psnr.png\""), std::string::npos);
  EXPECT_NE(html.find("latency_p95_ms"), std::string::npos);  // the figures' table
}

TEST(Report, CsvsThatCannotBePlottedExitOneSayingWhy) {
  const fs::path dir = freshDir("test-report-bad");
  const auto expectFailure = [&](const std::string& name, const std::string& csv,
                                 const std::string& why) {
    writeText(dir / name, csv);
    const ToolRun r = runReport({(dir / name).string(), "--out", (dir / "out").string()}, dir);
    EXPECT_EQ(r.code, 1) << name << ": " << r.output;
    EXPECT_NE(r.output.find(why), std::string::npos) << name << ": " << r.output;
    EXPECT_NE(r.output.find(name), std::string::npos) << name << ": the file is not named";
  };
  expectFailure("no_time.csv", "clients,kbit_s_total\n1,2\n", "no time_s column");
  expectFailure("word.csv", "time_s,kbit_s_total\n1,2\n2,fast\n",
                "word.csv:3: 'fast' in column kbit_s_total is not a number");
  expectFailure("short_row.csv", "time_s,kbit_s_total\n1,2\n2\n", "1 fields, the header names 2");
  expectFailure("nothing.csv", "time_s,colour\n1,2\n", "no column to plot");
  expectFailure("empty.csv", "time_s,kbit_s_total\n", "no rows");
  const ToolRun missing =
      runReport({(dir / "missing.csv").string(), "--out", (dir / "out").string()}, dir);
  EXPECT_EQ(missing.code, 1);
  EXPECT_NE(missing.output.find("missing.csv"), std::string::npos) << missing.output;
  EXPECT_FALSE(fs::exists(dir / "out" / "word.html"));
}

TEST(Report, TicksAreRoundAndCoverTheRange) {
  EXPECT_EQ(niceTicks(0, 10, 5), (std::vector<double>{0, 2, 4, 6, 8, 10}));
  EXPECT_EQ(niceTicks(3, 97, 4), (std::vector<double>{0, 50, 100}));
  const std::vector<double> small = niceTicks(0.12, 0.93, 5);
  EXPECT_LE(small.front(), 0.12);
  EXPECT_GE(small.back(), 0.93);
  EXPECT_NEAR(small[1] - small[0], 0.2, 1e-12);
  EXPECT_EQ(niceTicks(5, 5, 5).size(), 6u);  // a flat series still gets an axis
  EXPECT_EQ(tickLabel(0.25, 0.05), "0.25");
  EXPECT_EQ(tickLabel(1500, 500), "1500");
  EXPECT_EQ(tickLabel(2.5e6, 5e5), "2.5e+06");
}

TEST(Report, CanvasTextUsesTheBitmapFont) {
  Canvas c(40, 12, {255, 255, 255, 255});
  c.text(1, 1, "1", {0, 0, 0, 255});
  // The font's '1': a column of 7 at x = 1 + 2, its foot 3 wide; nothing right of the glyph.
  for (int y = 1; y < 8; ++y) EXPECT_EQ(c.at(3, y), (Rgba{0, 0, 0, 255})) << y;
  EXPECT_EQ(c.at(2, 7), (Rgba{0, 0, 0, 255}));
  EXPECT_EQ(c.at(4, 7), (Rgba{0, 0, 0, 255}));
  for (int y = 0; y < 12; ++y) EXPECT_EQ(c.at(7, y), (Rgba{255, 255, 255, 255}));
  EXPECT_EQ(Canvas::textWidth("12", 2), 22);
  // Lowercase reads as capitals; a character the font lacks is a blank.
  Canvas lower(20, 10, {255, 255, 255, 255}), upper(20, 10, {255, 255, 255, 255});
  lower.text(0, 0, "ab", {0, 0, 0, 255});
  upper.text(0, 0, "AB", {0, 0, 0, 255});
  EXPECT_EQ(lower.toImage().rgb, upper.toImage().rgb);
}

}  // namespace
}  // namespace pc::report
