// A line chart of time series: axes with ticks and labels, one line per series (NaN values
// break a line; a value alone between gaps is a dot), a legend, a title. Drawn into a
// Canvas (plot_canvas.h).
#pragma once

#include <string>
#include <vector>

#include "plot_canvas.h"

namespace pc::report {

struct ChartLine {
  std::string label;
  std::vector<double> y;  // one per Chart::x; NaN: not measured
  Rgba color;
};

struct Chart {
  std::string title, xLabel, yLabel;
  std::vector<double> x;
  std::vector<ChartLine> lines;
};

// The plot area of a chart of this size: where the data is drawn (x0, y0 top-left).
struct PlotArea {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
};
PlotArea plotArea(int width, int height);

Canvas drawChart(const Chart& chart, int width, int height);

// Round tick values (1, 2 or 5 times a power of ten apart) covering [lo, hi]: about `target`
// of them, the first <= lo and the last >= hi.
std::vector<double> niceTicks(double lo, double hi, int target);
// A tick's label: as few decimals as the step needs ("0.25", "1500", "2.5e+06").
std::string tickLabel(double value, double step);

// The colours lines take in turn.
Rgba lineColor(std::size_t index);

}  // namespace pc::report
