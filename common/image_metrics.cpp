// Image comparison metrics: PSNR (8-bit and linear), SSIM and a false-colour difference map.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "image.h"

namespace pc {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

bool sameSize(const Image8& a, const Image8& b) {
  return a.width == b.width && a.height == b.height && a.rgb.size() == b.rgb.size() &&
         a.rgb.size() == std::size_t(a.width) * a.height * 3;
}

double luminance(const glm::vec3& c) { return 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z; }

// The q-quantile (0..1) of `v`, which it reorders.
double quantile(std::vector<double>& v, double q) {
  if (v.empty()) return 0.0;
  std::size_t k = std::min(v.size() - 1, std::size_t(q * double(v.size() - 1) + 0.5));
  std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(k), v.end());
  return v[k];
}

// Rec. 601 luma of 8-bit sRGB values, the usual input of SSIM on colour images.
std::vector<double> luma(const Image8& img) {
  std::vector<double> y(std::size_t(img.width) * img.height);
  for (std::size_t i = 0; i < y.size(); ++i) {
    y[i] = 0.299 * img.rgb[3 * i] + 0.587 * img.rgb[3 * i + 1] + 0.114 * img.rgb[3 * i + 2];
  }
  return y;
}

// Colour ramp of the difference image: black, blue, cyan, green, yellow, red at t = 0, 0.2,
// 0.4, 0.6, 0.8, 1. differenceImage starts any nonzero difference at blue (t = 0.2), so only
// exactly equal pixels are black and small errors stay visible.
glm::vec3 ramp(double t) {
  static const glm::vec3 stops[] = {{0, 0, 0}, {0, 0, 1}, {0, 1, 1},
                                    {0, 1, 0}, {1, 1, 0}, {1, 0, 0}};
  t = std::clamp(t, 0.0, 1.0) * 5.0;
  int i = std::min(int(t), 4);
  float f = float(t - i);
  return stops[i] + (stops[i + 1] - stops[i]) * f;
}

}  // namespace

double psnr8(const Image8& a, const Image8& b) {
  if (!sameSize(a, b) || a.rgb.empty()) return kNaN;
  double sum = 0.0;
  for (std::size_t i = 0; i < a.rgb.size(); ++i) {
    double d = double(a.rgb[i]) - double(b.rgb[i]);
    sum += d * d;
  }
  if (sum == 0.0) return kInf;
  double mse = sum / double(a.rgb.size());
  return 10.0 * std::log10(255.0 * 255.0 / mse);
}

double psnrLinear(const Image& test, const Image& reference) {
  if (test.width != reference.width || test.height != reference.height ||
      test.pixels.size() != reference.pixels.size() || test.pixels.empty()) {
    return kNaN;
  }
  double sum = 0.0;
  for (std::size_t i = 0; i < test.pixels.size(); ++i) {
    glm::dvec3 d = glm::dvec3(test.pixels[i]) - glm::dvec3(reference.pixels[i]);
    sum += glm::dot(d, d);
  }
  if (sum == 0.0) return kInf;
  std::vector<double> lum(reference.pixels.size());
  for (std::size_t i = 0; i < lum.size(); ++i) lum[i] = luminance(reference.pixels[i]);
  double peak = quantile(lum, 0.999);
  // A black (or nearly black) reference has no meaningful peak; fall back to unit radiance
  // so the figure stays finite and comparable across black frames.
  if (!(peak > 1e-6)) peak = 1.0;
  double mse = sum / (3.0 * double(test.pixels.size()));
  return 10.0 * std::log10(peak * peak / mse);
}

double ssim8(const Image8& a, const Image8& b) {
  if (!sameSize(a, b) || a.rgb.empty()) return kNaN;
  constexpr double C1 = (0.01 * 255.0) * (0.01 * 255.0);
  constexpr double C2 = (0.03 * 255.0) * (0.03 * 255.0);
  // 8x8 windows moved 4 pixels at a time; an image smaller than a window is one window.
  const int win = 8, step = 4;
  const int wx = std::min(win, a.width), wy = std::min(win, a.height);
  std::vector<double> ya = luma(a), yb = luma(b);
  double total = 0.0;
  std::int64_t windows = 0;
  auto xs = [&](int size, int w) {
    std::vector<int> starts;
    for (int s = 0; s + w <= size; s += step) starts.push_back(s);
    if (starts.back() + w < size) starts.push_back(size - w);  // cover the last column/row
    return starts;
  };
  const std::vector<int> x0s = xs(a.width, wx), y0s = xs(a.height, wy);
  const double n = double(wx) * wy;
  for (int y0 : y0s) {
    for (int x0 : x0s) {
      double ma = 0.0, mb = 0.0;
      for (int y = y0; y < y0 + wy; ++y) {
        for (int x = x0; x < x0 + wx; ++x) {
          std::size_t i = std::size_t(y) * a.width + x;
          ma += ya[i];
          mb += yb[i];
        }
      }
      ma /= n;
      mb /= n;
      double va = 0.0, vb = 0.0, cov = 0.0;
      for (int y = y0; y < y0 + wy; ++y) {
        for (int x = x0; x < x0 + wx; ++x) {
          std::size_t i = std::size_t(y) * a.width + x;
          double da = ya[i] - ma, db = yb[i] - mb;
          va += da * da;
          vb += db * db;
          cov += da * db;
        }
      }
      va /= n;
      vb /= n;
      cov /= n;
      total +=
          ((2.0 * ma * mb + C1) * (2.0 * cov + C2)) / ((ma * ma + mb * mb + C1) * (va + vb + C2));
      ++windows;
    }
  }
  return total / double(windows);
}

Image8 differenceImage(const Image8& a, const Image8& b) {
  Image8 out;
  if (!sameSize(a, b)) return out;
  out.width = a.width;
  out.height = a.height;
  out.rgb.assign(a.rgb.size(), 0);
  const std::size_t count = std::size_t(a.width) * a.height;
  // Per pixel, the largest channel difference: a change in any channel shows.
  std::vector<double> diff(count);
  for (std::size_t i = 0; i < count; ++i) {
    int m = 0;
    for (int c = 0; c < 3; ++c) m = std::max(m, std::abs(int(a.rgb[3 * i + c]) - b.rgb[3 * i + c]));
    diff[i] = m;
  }
  std::vector<double> sorted = diff;
  double scale = quantile(sorted, 0.99);
  if (scale <= 0.0) scale = *std::max_element(diff.begin(), diff.end());
  if (scale <= 0.0) return out;  // identical: all black
  for (std::size_t i = 0; i < count; ++i) {
    if (diff[i] == 0.0) continue;
    glm::vec3 c = ramp(0.2 + 0.8 * std::min(diff[i] / scale, 1.0));
    out.rgb[3 * i] = static_cast<unsigned char>(std::lround(c.x * 255.0f));
    out.rgb[3 * i + 1] = static_cast<unsigned char>(std::lround(c.y * 255.0f));
    out.rgb[3 * i + 2] = static_cast<unsigned char>(std::lround(c.z * 255.0f));
  }
  return out;
}

double psnrWithoutReferenceNoise(double measuredPsnr, double referenceNoisePsnr) {
  if (!std::isfinite(referenceNoisePsnr) || referenceNoisePsnr <= 0) return measuredPsnr;
  const double measured = std::pow(10.0, -measuredPsnr / 10.0);
  const double noise = std::pow(10.0, -referenceNoisePsnr / 10.0);
  if (!(measured > 1.25 * noise)) return std::numeric_limits<double>::quiet_NaN();
  return -10.0 * std::log10(measured - noise);
}

}  // namespace pc
