#include "plot_canvas.h"

#include <algorithm>
#include <cmath>

#include "common/bitmap_font.h"

namespace pc::report {

namespace {

constexpr int kGlyphAdvance = kFontColumns + 1;  // a blank column between characters

}  // namespace

Canvas::Canvas(int width, int height, Rgba background)
    : width_(std::max(1, width)),
      height_(std::max(1, height)),
      pixels_(std::size_t(width_) * std::size_t(height_), background) {}

Rgba Canvas::at(int x, int y) const {
  if (x < 0 || y < 0 || x >= width_ || y >= height_) return {};
  return pixels_[std::size_t(y) * std::size_t(width_) + std::size_t(x)];
}

void Canvas::blend(int x, int y, Rgba c) {
  if (x < 0 || y < 0 || x >= width_ || y >= height_) return;
  Rgba& p = pixels_[std::size_t(y) * std::size_t(width_) + std::size_t(x)];
  const auto mix = [a = int(c.a)](std::uint8_t over, std::uint8_t under) {
    return std::uint8_t((int(over) * a + int(under) * (255 - a) + 127) / 255);
  };
  p = {mix(c.r, p.r), mix(c.g, p.g), mix(c.b, p.b), 255};
}

void Canvas::fillRect(int x0, int y0, int x1, int y1, Rgba c) {
  for (int y = std::max(0, y0); y < std::min(height_, y1); ++y) {
    for (int x = std::max(0, x0); x < std::min(width_, x1); ++x) blend(x, y, c);
  }
}

void Canvas::line(double x0, double y0, double x1, double y1, Rgba c, int thickness) {
  // Steps of at most half a pixel along the longer axis, a square of `thickness` at each:
  // simple, and exact enough for plots of a few thousand points.
  const double length = std::max(std::abs(x1 - x0), std::abs(y1 - y0));
  const int steps = std::max(1, int(std::ceil(length * 2.0)));
  const int half = (thickness - 1) / 2;
  int lastX = INT32_MIN, lastY = INT32_MIN;
  for (int i = 0; i <= steps; ++i) {
    const double t = double(i) / steps;
    const int x = int(std::lround(x0 + (x1 - x0) * t)) - half;
    const int y = int(std::lround(y0 + (y1 - y0) * t)) - half;
    if (x == lastX && y == lastY) continue;
    lastX = x, lastY = y;
    for (int dy = 0; dy < thickness; ++dy) {
      for (int dx = 0; dx < thickness; ++dx) {
        if (x + dx < 0 || y + dy < 0 || x + dx >= width_ || y + dy >= height_) continue;
        pixels_[std::size_t(y + dy) * std::size_t(width_) + std::size_t(x + dx)] = c;
      }
    }
  }
}

void Canvas::text(int x, int y, std::string_view s, Rgba c, int scale, bool vertical) {
  for (std::size_t i = 0; i < s.size(); ++i) {
    const FontGlyph* g = fontGlyph(s[i]);
    if (!g) continue;
    const int origin = int(i) * kGlyphAdvance * scale;
    for (int row = 0; row < kFontRows; ++row) {
      for (int col = 0; col < kFontColumns; ++col) {
        if (!(g->rows[row] & (1 << (kFontColumns - 1 - col)))) continue;
        // Horizontal: column right, row down. Vertical: column up, row right.
        const int px = vertical ? x + row * scale : x + origin + col * scale;
        const int py = vertical ? y - origin - (col + 1) * scale : y + row * scale;
        fillRect(px, py, px + scale, py + scale, c);
      }
    }
  }
}

int Canvas::textWidth(std::string_view s, int scale) {
  return s.empty() ? 0 : (int(s.size()) * kGlyphAdvance - 1) * scale;
}

int Canvas::textHeight(int scale) { return kFontRows * scale; }

Image8 Canvas::toImage() const {
  Image8 image;
  image.width = width_;
  image.height = height_;
  image.rgb.reserve(pixels_.size() * 3);
  for (const Rgba& p : pixels_) image.rgb.insert(image.rgb.end(), {p.r, p.g, p.b});
  return image;
}

}  // namespace pc::report
