// LDR-FLIP (common/image_flip.h) on inputs whose value can be worked out by hand: identical
// images, flat colours (where only the colour pipeline speaks and the filters leave a flat
// image as it is), an edge that moves, and noise of growing strength.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "common/image_flip.h"

namespace {

pc::Image8 flat(int w, int h, unsigned char r, unsigned char g, unsigned char b) {
  pc::Image8 img;
  img.width = w;
  img.height = h;
  img.rgb.resize(std::size_t(w) * h * 3);
  for (std::size_t i = 0; i < img.rgb.size(); i += 3) {
    img.rgb[i] = r;
    img.rgb[i + 1] = g;
    img.rgb[i + 2] = b;
  }
  return img;
}

// A horizontal ramp with some colour, so that every pipeline has something to see.
pc::Image8 ramp(int w, int h) {
  pc::Image8 img = flat(w, h, 0, 0, 0);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      unsigned char* p = &img.rgb[(std::size_t(y) * w + x) * 3];
      p[0] = static_cast<unsigned char>(40 + 160 * x / (w - 1));
      p[1] = static_cast<unsigned char>(120 + 60 * y / (h - 1));
      p[2] = 90;
    }
  return img;
}

pc::Image8 noisy(const pc::Image8& img, double sigma, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, sigma);
  pc::Image8 out = img;
  for (unsigned char& c : out.rgb)
    c = static_cast<unsigned char>(std::clamp(c + n(rng), 0.0, 255.0));
  return out;
}

// CIELAB L* of an sRGB grey code (a* = b* = 0 for greys, relative to the white).
double greyLightness(int code) {
  const double c = code / 255.0;
  const double y = c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
  const double d = 6.0 / 29.0;
  const double f = y > d * d * d ? std::cbrt(y) : y / (3 * d * d) + 4.0 / 29.0;
  return 116.0 * f - 16.0;
}

// FLIP's largest colour distance: HyAB between Hunt-adjusted sRGB green and blue, from their
// published CIELAB values (D65): green L 87.735 a -86.183 b 83.179, blue L 32.303 a 79.197
// b -107.864; the Hunt adjustment scales a and b by L / 100.
double cmax() {
  const double gL = 87.735, ga = -86.183 * 0.87735, gb = 83.179 * 0.87735;
  const double bL = 32.303, ba = 79.197 * 0.32303, bb = -107.864 * 0.32303;
  return std::pow(std::abs(gL - bL) + std::hypot(ga - ba, gb - bb), 0.7);
}

// The colour pipeline's remapping of a HyAB distance to [0, 1].
double colourError(double hyab) {
  const double e = std::pow(hyab, 0.7), c = cmax(), pc = 0.4 * c;
  return e < pc ? 0.95 / pc * e : 0.95 + (e - pc) / (c - pc) * 0.05;
}

TEST(ImageFlip, IdenticalImagesScoreZero) {
  const pc::Image8 a = noisy(ramp(48, 32), 20.0, 1);
  const pc::FlipResult r = pc::flip(a, a);
  EXPECT_EQ(r.mean, 0.0);
  ASSERT_EQ(r.error.size(), 48u * 32u);
  for (float e : r.error) ASSERT_EQ(e, 0.0f);
}

TEST(ImageFlip, BlackAgainstWhiteIsTheColourPipelinesValue) {
  // Flat images: the filters return them unchanged and no edges or points differ, so FLIP is
  // the remapped HyAB distance of black and white, |100 - 0| (neither has chroma).
  const pc::FlipResult r = pc::flip(flat(32, 24, 255, 255, 255), flat(32, 24, 0, 0, 0));
  EXPECT_NEAR(r.mean, colourError(100.0), 1e-3);
  EXPECT_GT(r.mean, 0.95);  // past p_c * c_max: among the largest errors FLIP gives
}

TEST(ImageFlip, NearbyGreysScaleLinearlyBelowTheKnee) {
  // Two greys differ only in L*; a small HyAB distance maps to 0.95 / (p_c c_max) of it.
  for (int step : {4, 10, 25}) {
    const pc::FlipResult r =
        pc::flip(flat(24, 24, 128 + step, 128 + step, 128 + step), flat(24, 24, 128, 128, 128));
    EXPECT_NEAR(r.mean, colourError(greyLightness(128 + step) - greyLightness(128)), 2e-3)
        << "step " << step;
  }
}

TEST(ImageFlip, BlueAgainstGreenIsNearTheMaximum) {
  // c_max is the HyAB distance of exactly these two, so FLIP is 1.
  const pc::FlipResult r = pc::flip(flat(16, 16, 0, 255, 0), flat(16, 16, 0, 0, 255));
  EXPECT_NEAR(r.mean, 1.0, 2e-3);
}

TEST(ImageFlip, SymmetricAndSizeChecked) {
  const pc::Image8 a = ramp(40, 30), b = noisy(a, 12.0, 7);
  EXPECT_NEAR(pc::flip(a, b).mean, pc::flip(b, a).mean, 1e-6);
  EXPECT_TRUE(std::isnan(pc::flip(a, ramp(40, 31)).mean));
  EXPECT_TRUE(pc::flip(a, ramp(40, 31)).error.empty());
}

TEST(ImageFlip, GrowsWithNoise) {
  const pc::Image8 ref = ramp(64, 48);
  double previous = 0.0;
  for (double sigma : {1.0, 3.0, 8.0, 20.0, 50.0}) {
    const double e = pc::flip(noisy(ref, sigma, 3), ref).mean;
    EXPECT_GT(e, previous) << "sigma " << sigma;
    previous = e;
  }
  EXPECT_LT(previous, 1.0);
}

TEST(ImageFlip, MovedEdgeShowsAlongTheEdgeOnly) {
  // A dark/light step one column apart: the error is where the edge is, and nothing farther
  // than the filters reach (10 pixels for the colour filters, 9 for the edge detector at the
  // default 67 px per degree).
  const int w = 80, h = 20;
  pc::Image8 ref = flat(w, h, 40, 40, 40), test = ref;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      if (x >= 40) std::fill_n(&ref.rgb[(std::size_t(y) * w + x) * 3], 3, 200);
      if (x >= 41) std::fill_n(&test.rgb[(std::size_t(y) * w + x) * 3], 3, 200);
    }
  const pc::FlipResult r = pc::flip(test, ref);
  const auto at = [&](int x) { return r.error[std::size_t(h / 2) * w + x]; };
  EXPECT_GT(at(40), 0.2f);
  EXPECT_GT(at(38), 0.0f);
  EXPECT_EQ(at(10), 0.0f);
  EXPECT_EQ(at(70), 0.0f);
}

TEST(ImageFlip, FartherViewersSeeLessNoise) {
  // More pixels per degree: fine noise falls past the eye's contrast sensitivity.
  const pc::Image8 ref = ramp(64, 48), test = noisy(ref, 15.0, 5);
  const double nearView = pc::flip(test, ref, 20.0).mean;
  const double defaultView = pc::flip(test, ref).mean;
  const double farView = pc::flip(test, ref, 200.0).mean;
  EXPECT_GT(nearView, defaultView);
  EXPECT_GT(defaultView, farView);
}

TEST(ImageFlip, ErrorImageUsesTheMagmaRamp) {
  pc::FlipResult r;
  r.width = 3;
  r.height = 1;
  r.error = {0.0f, 0.5f, 1.0f};
  const pc::Image8 img = pc::flipErrorImage(r);
  ASSERT_EQ(img.rgb.size(), 9u);
  EXPECT_LT(img.rgb[0] + img.rgb[1] + img.rgb[2], 10);  // near black
  EXPECT_GT(img.rgb[3], img.rgb[5]);                    // red-purple in the middle
  EXPECT_GT(img.rgb[6] + img.rgb[7], 2 * 240);          // pale yellow at 1
  EXPECT_GT(img.rgb[6] + img.rgb[7] + img.rgb[8], img.rgb[3] + img.rgb[4] + img.rgb[5]);
}

}  // namespace
