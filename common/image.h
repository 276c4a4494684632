// Linear RGB float images, their files (tone-mapped PNG; linear EXR and PFM) and the metrics
// that compare renderers (PSNR on tone-mapped 8-bit sRGB and on linear radiance, SSIM).
#pragma once

#include <filesystem>
#include <glm/glm.hpp>
#include <vector>

#include "result.h"

namespace pc {

struct Image {
  int width = 0, height = 0;
  std::vector<glm::vec3> pixels;  // linear radiance, row 0 at the top
  Image() = default;
  Image(int w, int h) : width(w), height(h), pixels(std::size_t(w) * h, glm::vec3(0.0f)) {}
  glm::vec3& at(int x, int y) { return pixels[std::size_t(y) * width + x]; }
  const glm::vec3& at(int x, int y) const { return pixels[std::size_t(y) * width + x]; }
};

// 8-bit sRGB after exposure and the shared tone curve (shaders/interop/tonemap.h).
struct Image8 {
  int width = 0, height = 0;
  std::vector<unsigned char> rgb;
};
Image8 tonemap(const Image& image, float exposure);
// Each k x k block of `image` averaged into one pixel (a box filter in linear radiance, as a
// renderer integrates a pixel's footprint); the size must be a multiple of k.
Image boxDownsample(const Image& image, int k);

Status writePng(const std::filesystem::path& path, const Image8& image);
Status writePng(const std::filesystem::path& path, const Image& image, float exposure);
Status writeExr(const std::filesystem::path& path, const Image& image);
Status writePfm(const std::filesystem::path& path, const Image& image);
// Linear images from .exr/.pfm; a .png is decoded from sRGB to linear [0,1] values.
Result<Image> readImage(const std::filesystem::path& path);
Result<Image8> readPng(const std::filesystem::path& path);

// PSNR in dB (infinite for identical images; sizes must match).
double psnr8(const Image8& a, const Image8& b);
// The PSNR a test image is expected to have against the reference's noise-free limit. The
// reference's own noise is independent of the test image's error and has zero mean, so its mean
// square adds to the measured one: E[MSE] = MSE(test, truth) + MSE(reference, truth), and the
// second term (known from two half-sample renders) is taken away. NaN where the measured error is
// under 1.25 times the noise's (within 1 dB of it): the reference is too noisy to judge.
double psnrWithoutReferenceNoise(double measuredPsnr, double referenceNoisePsnr);
// Linear PSNR with peak = the reference's 99.9th percentile luminance (robust to fireflies).
double psnrLinear(const Image& test, const Image& reference);
// Mean SSIM on the luma of the tone-mapped images (8x8 windows, standard constants).
double ssim8(const Image8& a, const Image8& b);
// False-colour map of |a - b| per pixel (black = equal, blue..red = larger), scaled so the
// 99th percentile difference is red.
Image8 differenceImage(const Image8& a, const Image8& b);

}  // namespace pc
