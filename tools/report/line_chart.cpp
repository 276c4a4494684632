#include "line_chart.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace pc::report {

namespace {

constexpr Rgba kBackground{255, 255, 255, 255};
constexpr Rgba kInk{40, 40, 40, 255};
constexpr Rgba kGrid{225, 225, 225, 255};
constexpr int kTitleScale = 2;

// The finite range of the chart's values; nothing finite: {NaN, NaN}.
std::pair<double, double> rangeOf(const std::vector<double>& values) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (double v : values) {
    if (!std::isfinite(v)) continue;
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  if (lo > hi) return {std::nan(""), std::nan("")};
  return {lo, hi};
}

}  // namespace

PlotArea plotArea(int width, int height) {
  // Left: the y tick labels and the vertical y label; top: the title; bottom: the x tick
  // labels and the x label.
  return {78, 34, width - 16, height - 40};
}

std::vector<double> niceTicks(double lo, double hi, int target) {
  if (!(hi > lo)) hi = lo + 1.0;
  const double rough = (hi - lo) / std::max(1, target);
  const double power = std::pow(10.0, std::floor(std::log10(rough)));
  double step = power;
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    step = m * power;
    if (step >= rough) break;
  }
  std::vector<double> ticks;
  const double first = std::floor(lo / step) * step;
  for (int i = 0; i < 100; ++i) {
    const double t = first + i * step;
    ticks.push_back(std::abs(t) < step * 1e-9 ? 0.0 : t);
    if (t >= hi - step * 1e-9) break;
  }
  return ticks;
}

std::string tickLabel(double value, double step) {
  char buf[32];
  const double magnitude = std::max(std::abs(value), step);
  if (magnitude >= 1e6 || (magnitude < 1e-3 && value != 0.0)) {
    std::snprintf(buf, sizeof buf, "%.2g", value);
  } else {
    const int decimals = std::clamp(int(std::ceil(-std::log10(step) - 1e-9)), 0, 3);
    std::snprintf(buf, sizeof buf, "%.*f", decimals, value);
  }
  return buf;
}

Rgba lineColor(std::size_t index) {
  static constexpr Rgba kColors[] = {{31, 119, 180, 255}, {214, 39, 40, 255},   {44, 160, 44, 255},
                                     {255, 127, 14, 255}, {148, 103, 189, 255}, {140, 86, 75, 255}};
  return kColors[index % std::size(kColors)];
}

Canvas drawChart(const Chart& chart, int width, int height) {
  Canvas c(width, height, kBackground);
  const PlotArea a = plotArea(width, height);
  c.text((width - Canvas::textWidth(chart.title, kTitleScale)) / 2, 8, chart.title, kInk,
         kTitleScale);

  std::vector<double> ys;
  for (const ChartLine& l : chart.lines) ys.insert(ys.end(), l.y.begin(), l.y.end());
  auto [xLo, xHi] = rangeOf(chart.x);
  auto [yLo, yHi] = rangeOf(ys);
  if (std::isnan(xLo)) xLo = 0, xHi = 1;
  if (std::isnan(yLo)) yLo = 0, yHi = 1;
  // Quantities that cannot go below zero read best from zero; PSNR-like ones start near
  // their values.
  if (yLo > 0 && yLo < 0.5 * yHi) yLo = 0;
  const std::vector<double> xTicks = niceTicks(xLo, xHi, 8);
  const std::vector<double> yTicks = niceTicks(yLo, yHi, 5);
  xLo = std::min(xLo, xTicks.front()), xHi = std::max(xHi, xTicks.back());
  yLo = std::min(yLo, yTicks.front()), yHi = std::max(yHi, yTicks.back());
  const auto px = [&](double x) { return a.x0 + (x - xLo) / (xHi - xLo) * (a.x1 - a.x0); };
  const auto py = [&](double y) { return a.y1 - (y - yLo) / (yHi - yLo) * (a.y1 - a.y0); };

  // Grid and ticks with their labels, then the axes over them.
  const double xStep = xTicks.size() > 1 ? xTicks[1] - xTicks[0] : 1.0;
  const double yStep = yTicks.size() > 1 ? yTicks[1] - yTicks[0] : 1.0;
  for (double t : xTicks) {
    const int x = int(std::lround(px(t)));
    c.line(x, a.y0, x, a.y1, kGrid);
    c.line(x, a.y1, x, a.y1 + 4, kInk);
    const std::string label = tickLabel(t, xStep);
    c.text(x - Canvas::textWidth(label) / 2, a.y1 + 8, label, kInk);
  }
  for (double t : yTicks) {
    const int y = int(std::lround(py(t)));
    c.line(a.x0, y, a.x1, y, kGrid);
    c.line(a.x0 - 4, y, a.x0, y, kInk);
    const std::string label = tickLabel(t, yStep);
    c.text(a.x0 - 8 - Canvas::textWidth(label), y - Canvas::textHeight() / 2, label, kInk);
  }
  c.line(a.x0, a.y0, a.x0, a.y1, kInk);
  c.line(a.x0, a.y1, a.x1, a.y1, kInk);
  c.text((a.x0 + a.x1 - Canvas::textWidth(chart.xLabel)) / 2, height - 14, chart.xLabel, kInk);
  c.text(8, (a.y0 + a.y1 + Canvas::textWidth(chart.yLabel)) / 2, chart.yLabel, kInk, 1, true);

  // The lines: segments between consecutive finite points; a point alone is a dot.
  for (const ChartLine& l : chart.lines) {
    const std::size_t n = std::min(l.y.size(), chart.x.size());
    const auto finite = [&](std::size_t i) {
      return i < n && std::isfinite(l.y[i]) && std::isfinite(chart.x[i]);
    };
    for (std::size_t i = 0; i < n; ++i) {
      if (!finite(i)) continue;
      const double x = px(chart.x[i]), y = py(l.y[i]);
      if (finite(i + 1)) {
        c.line(x, y, px(chart.x[i + 1]), py(l.y[i + 1]), l.color, 2);
      } else if (i == 0 || !finite(i - 1)) {
        c.fillRect(int(x) - 1, int(y) - 1, int(x) + 2, int(y) + 2, l.color);
      }
    }
  }

  // The legend, top right inside the plot, on a white box over the lines.
  int legendWidth = 0;
  for (const ChartLine& l : chart.lines)
    legendWidth = std::max(legendWidth, Canvas::textWidth(l.label));
  const int rowHeight = Canvas::textHeight() + 6;
  const int boxWidth = legendWidth + 34, boxHeight = int(chart.lines.size()) * rowHeight + 6;
  const int bx = a.x1 - boxWidth - 6, by = a.y0 + 6;
  c.fillRect(bx, by, bx + boxWidth, by + boxHeight, {255, 255, 255, 230});
  for (std::size_t i = 0; i < chart.lines.size(); ++i) {
    const int y = by + 6 + int(i) * rowHeight;
    c.line(bx + 6, y + 3, bx + 22, y + 3, chart.lines[i].color, 2);
    c.text(bx + 28, y, chart.lines[i].label, kInk);
  }
  return c;
}

}  // namespace pc::report
