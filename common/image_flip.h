// LDR-FLIP (Andersson et al., "FLIP: A Difference Evaluator for Alternating Images", HPG 2020):
// a perceptual per-pixel error between two 8-bit sRGB images, in [0, 1], that models what a
// viewer sees when flipping between them at a given viewing distance. PSNR and SSIM miss what
// matters in renders (an edge lost, a blotch on a flat wall); FLIP weighs colour differences
// after the eye's contrast sensitivity and adds the edges and points that differ.
#pragma once

#include <vector>

#include "image.h"

namespace pc {

// Pixels per degree of visual angle: FLIP's default observer, a 0.7 m wide 4K monitor seen
// from 0.7 m: 3840 px per radian near the centre of view, 67.02 px per degree.
inline constexpr double kFlipDefaultPixelsPerDegree = 0.7 * 3840.0 / 0.7 * 3.14159265358979 / 180.0;

struct FlipResult {
  int width = 0, height = 0;
  std::vector<float> error;  // per pixel, row 0 at the top, each in [0, 1]
  double mean = 0.0;         // the figure FLIP reports: the mean of `error`
};

// FLIP of `test` against `reference` (sizes must match; otherwise `mean` is NaN and `error`
// empty). Symmetric in its arguments, 0 for identical images.
FlipResult flip(const Image8& test, const Image8& reference,
                double pixelsPerDegree = kFlipDefaultPixelsPerDegree);

// The error map as an image: FLIP's magma colour ramp (black-purple at 0, pale yellow at 1).
Image8 flipErrorImage(const FlipResult& result);

}  // namespace pc
