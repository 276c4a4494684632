// LDR-FLIP, following the paper's two pipelines:
//  colour:  sRGB -> linear RGB -> XYZ -> YyCxCz (linear opponent space) -> contrast sensitivity
//           filters per channel -> linear RGB, clamped -> CIELAB -> Hunt adjustment -> HyAB
//           distance, raised to q_c and remapped to [0, 1] against the largest distance (green
//           against blue);
//  feature: the normalized Yy channel's edges (first Gaussian derivative) and points (second
//           derivative), the larger difference of their magnitudes, raised to q_f;
//  and combines them as deltaE_c ^ (1 - deltaE_f).
// Filters read past the image edge as the edge pixel (replicate), as the reference code does.
// Every filter here is a sum of separable Gaussians, so each runs as two 1D passes; the result
// equals the 2D kernels' convolution.
#include "image_flip.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace pc {

namespace {

constexpr double kPi = 3.14159265358979323846;

// The paper's constants.
constexpr double kQc = 0.7, kQf = 0.5, kPc = 0.4, kPt = 0.95;
constexpr double kFeatureWidth = 0.082;  // degrees: peak to trough of the edge detector

struct Plane {
  int width = 0, height = 0;
  std::vector<float> v;
  float at(int x, int y) const {
    x = std::clamp(x, 0, width - 1);
    y = std::clamp(y, 0, height - 1);
    return v[std::size_t(y) * width + x];
  }
};

// Correlates `in` with the separable kernel kx (along x) times ky (along y), both of odd size
// centred on their middle tap.
Plane separable(const Plane& in, const std::vector<double>& kx, const std::vector<double>& ky) {
  const int rx = int(kx.size() / 2), ry = int(ky.size() / 2);
  Plane tmp{in.width, in.height, std::vector<float>(in.v.size())};
  for (int y = 0; y < in.height; ++y)
    for (int x = 0; x < in.width; ++x) {
      double s = 0.0;
      for (int i = -rx; i <= rx; ++i) s += kx[i + rx] * in.at(x + i, y);
      tmp.v[std::size_t(y) * in.width + x] = float(s);
    }
  Plane out{in.width, in.height, std::vector<float>(in.v.size())};
  for (int y = 0; y < in.height; ++y)
    for (int x = 0; x < in.width; ++x) {
      double s = 0.0;
      for (int j = -ry; j <= ry; ++j) s += ky[j + ry] * tmp.at(x, y + j);
      out.v[std::size_t(y) * in.width + x] = float(s);
    }
  return out;
}

// sRGB primaries, D65 white: linear RGB to XYZ and back.
const glm::dmat3& rgbToXyz() {
  // glm is column-major: each glm::dvec3 below is a column (the XYZ of one primary).
  static const glm::dmat3 m(glm::dvec3(0.4123908, 0.2126390, 0.0193308),
                            glm::dvec3(0.3575843, 0.7151687, 0.1191948),
                            glm::dvec3(0.1804808, 0.0721923, 0.9505322));
  return m;
}
const glm::dmat3& xyzToRgb() {
  static const glm::dmat3 m = glm::inverse(rgbToXyz());
  return m;
}
// The XYZ of linear RGB white, which both YyCxCz and CIELAB are relative to.
const glm::dvec3& white() {
  static const glm::dvec3 w = rgbToXyz() * glm::dvec3(1.0);
  return w;
}

double srgbToLinear(double c) {
  return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}

// YyCxCz: CIELAB without its cube root, so that it is linear in XYZ and can be filtered.
glm::dvec3 xyzToYcxcz(glm::dvec3 xyz) {
  const glm::dvec3 n = xyz / white();
  return {116.0 * n.y - 16.0, 500.0 * (n.x - n.y), 200.0 * (n.y - n.z)};
}
glm::dvec3 ycxczToXyz(glm::dvec3 c) {
  const double y = (c.x + 16.0) / 116.0;
  return glm::dvec3(y + c.y / 500.0, y, y - c.z / 200.0) * white();
}

glm::dvec3 linearRgbToHuntLab(glm::dvec3 rgb) {
  const glm::dvec3 n = rgbToXyz() * rgb / white();
  constexpr double d = 6.0 / 29.0;
  auto f = [&](double t) { return t > d * d * d ? std::cbrt(t) : t / (3.0 * d * d) + 4.0 / 29.0; };
  const double fx = f(n.x), fy = f(n.y), fz = f(n.z);
  const double L = 116.0 * fy - 16.0;
  // Hunt effect: chroma is perceived lower at low luminance, so a and b are scaled by L/100.
  return {L, 0.01 * L * 500.0 * (fx - fy), 0.01 * L * 200.0 * (fy - fz)};
}

// HyAB: city-block in lightness, Euclidean in the chroma plane (better for large differences
// than Euclidean CIELAB distance).
double hyab(glm::dvec3 a, glm::dvec3 b) {
  return std::abs(a.x - b.x) + std::hypot(a.y - b.y, a.z - b.z);
}

// A normalized 1D Gaussian exp(-pi^2 x^2 / b) over x = i / ppd, |i| <= radius.
std::vector<double> csfGaussian(double b, double ppd, int radius, double* unnormalizedSum) {
  std::vector<double> k(2 * radius + 1);
  double sum = 0.0;
  for (int i = -radius; i <= radius; ++i) {
    const double x = i / ppd;
    sum += k[i + radius] = std::exp(-kPi * kPi * x * x / b);
  }
  for (double& w : k) w /= sum;
  *unnormalizedSum = sum;
  return k;
}

// The contrast sensitivity filter of one channel: a1 sqrt(pi/b1) G(b1) + a2 sqrt(pi/b2) G(b2),
// normalized to sum 1 over the 2D kernel, applied as two separable passes.
Plane csfFilter(const Plane& in, double a1, double b1, double a2, double b2, double ppd,
                int radius) {
  double s1 = 0.0, s2 = 0.0;
  const std::vector<double> g1 = csfGaussian(b1, ppd, radius, &s1);
  const std::vector<double> g2 = csfGaussian(b2, ppd, radius, &s2);
  // Each term's share of the 2D kernel's sum (a Gaussian's 2D sum is its 1D sum squared).
  const double w1 = a1 * std::sqrt(kPi / b1) * s1 * s1, w2 = a2 * std::sqrt(kPi / b2) * s2 * s2;
  Plane out = separable(in, g1, g1);
  if (w2 > 0.0) {
    const Plane second = separable(in, g2, g2);
    for (std::size_t i = 0; i < out.v.size(); ++i)
      out.v[i] = float((w1 * out.v[i] + w2 * second.v[i]) / (w1 + w2));
  }
  return out;
}

// Edge (first derivative) or point (second derivative) detector along x, as a pair of 1D
// kernels: the derivative along x with its positive and negative taps each summing to +-1, and
// a Gaussian along y summing to 1 (the 2D kernel's normalization, factored).
struct Detector {
  std::vector<double> derivative, gaussian;
};
Detector detector(bool edge, double ppd) {
  const double sd = 0.5 * kFeatureWidth * ppd;
  const int radius = int(std::ceil(3.0 * sd));
  Detector d{std::vector<double>(2 * radius + 1), std::vector<double>(2 * radius + 1)};
  double gsum = 0.0, pos = 0.0, neg = 0.0;
  for (int i = -radius; i <= radius; ++i) {
    const double g = std::exp(-double(i * i) / (2.0 * sd * sd));
    const double k = edge ? -i * g : (double(i * i) / (sd * sd) - 1.0) * g;
    d.gaussian[i + radius] = g;
    d.derivative[i + radius] = k;
    gsum += g;
    (k > 0 ? pos : neg) += k;
  }
  for (double& g : d.gaussian) g /= gsum;
  for (double& k : d.derivative) k = k > 0 ? k / pos : (k < 0 ? k / -neg : 0.0);
  return d;
}

// Magnitude of the detector's response along x and y at every pixel.
Plane featureMagnitude(const Plane& y, const Detector& d) {
  const Plane gx = separable(y, d.derivative, d.gaussian);
  const Plane gy = separable(y, d.gaussian, d.derivative);
  Plane out{y.width, y.height, std::vector<float>(y.v.size())};
  for (std::size_t i = 0; i < out.v.size(); ++i) out.v[i] = std::hypot(gx.v[i], gy.v[i]);
  return out;
}

struct Prepared {
  Plane hunt[3];  // Hunt-adjusted L*a*b* of the filtered image
  Plane luma;     // normalized Yy (relative luminance, 0..1) of the unfiltered image
};

Prepared prepare(const Image8& img, double ppd) {
  const int w = img.width, h = img.height;
  const std::size_t n = std::size_t(w) * h;
  Plane opp[3];
  for (Plane& p : opp) p = Plane{w, h, std::vector<float>(n)};
  Prepared out;
  out.luma = Plane{w, h, std::vector<float>(n)};
  for (std::size_t i = 0; i < n; ++i) {
    glm::dvec3 rgb;
    for (int c = 0; c < 3; ++c) rgb[c] = srgbToLinear(img.rgb[3 * i + c] / 255.0);
    const glm::dvec3 o = xyzToYcxcz(rgbToXyz() * rgb);
    for (int c = 0; c < 3; ++c) opp[c].v[i] = float(o[c]);
    out.luma.v[i] = float((o.x + 16.0) / 116.0);
  }
  // The CSFs (a1, b1, a2, b2 per channel) from the paper; every channel's kernel has the radius
  // of the widest one.
  const int radius = int(std::ceil(3.0 * std::sqrt(0.04 / (2.0 * kPi * kPi)) * ppd));
  const Plane fy = csfFilter(opp[0], 1.0, 0.0047, 0.0, 1e-5, ppd, radius);
  const Plane fx = csfFilter(opp[1], 1.0, 0.0053, 0.0, 1e-5, ppd, radius);
  const Plane fz = csfFilter(opp[2], 34.1, 0.04, 13.5, 0.025, ppd, radius);
  for (Plane& p : out.hunt) p = Plane{w, h, std::vector<float>(n)};
  for (std::size_t i = 0; i < n; ++i) {
    const glm::dvec3 rgb = glm::clamp(xyzToRgb() * ycxczToXyz({fy.v[i], fx.v[i], fz.v[i]}),
                                      glm::dvec3(0.0), glm::dvec3(1.0));
    const glm::dvec3 lab = linearRgbToHuntLab(rgb);
    for (int c = 0; c < 3; ++c) out.hunt[c].v[i] = float(lab[c]);
  }
  return out;
}

}  // namespace

FlipResult flip(const Image8& test, const Image8& reference, double ppd) {
  FlipResult r;
  const std::size_t n = std::size_t(test.width) * std::max(test.height, 0);
  if (test.width != reference.width || test.height != reference.height || n == 0 ||
      test.rgb.size() != 3 * n || reference.rgb.size() != 3 * n || !(ppd > 0.0)) {
    r.mean = std::numeric_limits<double>::quiet_NaN();
    return r;
  }
  r.width = test.width;
  r.height = test.height;
  const Prepared a = prepare(test, ppd), b = prepare(reference, ppd);
  const double cmax =
      std::pow(hyab(linearRgbToHuntLab({0.0, 1.0, 0.0}), linearRgbToHuntLab({0.0, 0.0, 1.0})), kQc);
  const double pccmax = kPc * cmax;
  const Detector edge = detector(true, ppd), point = detector(false, ppd);
  const Plane ea = featureMagnitude(a.luma, edge), eb = featureMagnitude(b.luma, edge);
  const Plane pa = featureMagnitude(a.luma, point), pb = featureMagnitude(b.luma, point);
  r.error.resize(n);
  double sum = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double dc = std::pow(hyab({a.hunt[0].v[i], a.hunt[1].v[i], a.hunt[2].v[i]},
                                    {b.hunt[0].v[i], b.hunt[1].v[i], b.hunt[2].v[i]}),
                               kQc);
    // Small differences spread over [0, pt], the rest compressed into (pt, 1].
    const double colour =
        dc < pccmax ? kPt / pccmax * dc : kPt + (dc - pccmax) / (cmax - pccmax) * (1.0 - kPt);
    const double feature = std::max(std::abs(ea.v[i] - eb.v[i]), std::abs(pa.v[i] - pb.v[i]));
    const double df = std::pow(feature / std::sqrt(2.0), kQf);
    const double e = std::clamp(std::pow(colour, 1.0 - df), 0.0, 1.0);
    r.error[i] = float(e);
    sum += e;
  }
  r.mean = sum / double(n);
  return r;
}

Image8 flipErrorImage(const FlipResult& result) {
  // Magma at t = 0, 1/8, ..., 1, interpolated linearly between stops.
  static const glm::vec3 stops[] = {
      {0.001f, 0.000f, 0.014f}, {0.113f, 0.065f, 0.277f}, {0.317f, 0.072f, 0.485f},
      {0.513f, 0.125f, 0.508f}, {0.716f, 0.215f, 0.475f}, {0.904f, 0.306f, 0.396f},
      {0.987f, 0.535f, 0.383f}, {0.996f, 0.755f, 0.525f}, {0.987f, 0.991f, 0.750f}};
  Image8 out;
  out.width = result.width;
  out.height = result.height;
  out.rgb.resize(result.error.size() * 3);
  for (std::size_t i = 0; i < result.error.size(); ++i) {
    const float t = std::clamp(result.error[i], 0.0f, 1.0f) * 8.0f;
    const int k = std::min(int(t), 7);
    const glm::vec3 c = glm::mix(stops[k], stops[k + 1], t - float(k));
    for (int ch = 0; ch < 3; ++ch)
      out.rgb[3 * i + ch] = static_cast<unsigned char>(std::lround(c[ch] * 255.0f));
  }
  return out;
}

}  // namespace pc
