// An RGBA canvas that probecast-report draws its plots into: filled rectangles, lines of a
// given thickness and text in the project's 5x7 bitmap font (common/bitmap_font.h), written
// as PNG by common/image.h's writer. Everything drawn is clipped to the canvas.
#pragma once

#include <cstdint>
#include <string_view>
#include <vector>

#include "common/image.h"

namespace pc::report {

struct Rgba {
  std::uint8_t r = 0, g = 0, b = 0, a = 255;
  bool operator==(const Rgba&) const = default;
};

class Canvas {
 public:
  Canvas(int width, int height, Rgba background);
  int width() const { return width_; }
  int height() const { return height_; }
  Rgba at(int x, int y) const;
  // Blends `c` over the pixel by its alpha.
  void blend(int x, int y, Rgba c);
  void fillRect(int x0, int y0, int x1, int y1, Rgba c);  // [x0, x1) x [y0, y1)
  // A line between pixel centres, `thickness` pixels wide.
  void line(double x0, double y0, double x1, double y1, Rgba c, int thickness = 1);
  // Text with its top-left corner at (x, y), each font pixel `scale` x `scale` pixels;
  // vertical: rotated a quarter turn counter-clockwise (read bottom to top), (x, y) then
  // being its bottom-left corner.
  void text(int x, int y, std::string_view s, Rgba c, int scale = 1, bool vertical = false);
  static int textWidth(std::string_view s, int scale = 1);
  static int textHeight(int scale = 1);
  // The opaque image (alpha dropped: the background is opaque).
  Image8 toImage() const;

 private:
  int width_, height_;
  std::vector<Rgba> pixels_;
};

}  // namespace pc::report
