// Image files (PNG, EXR, PFM round trips and error messages), metrics on known inputs, and the
// probecast-imgdiff tool's exit codes.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <random>
#include <string>

#include "common/image.h"
#include "shaders/interop/tonemap.h"

namespace fs = std::filesystem;

namespace {

// A scratch folder per test, removed afterwards.
class ImageTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           ("pc_test_image_" + std::to_string(::getpid()) + "_" + info->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path path(const std::string& name) const { return dir_ / name; }
  fs::path dir_;
};

pc::Image randomImage(int w, int h, unsigned seed, float scale = 4.0f) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, scale);
  pc::Image img(w, h);
  for (auto& p : img.pixels) p = glm::vec3(u(rng), u(rng), u(rng));
  return img;
}

pc::Image8 randomImage8(int w, int h, unsigned seed) {
  std::mt19937 rng(seed);
  pc::Image8 img;
  img.width = w;
  img.height = h;
  img.rgb.resize(std::size_t(w) * h * 3);
  for (auto& v : img.rgb) v = static_cast<unsigned char>(rng() & 0xff);
  return img;
}

void writeBytes(const fs::path& p, const std::string& bytes) {
  std::ofstream f(p, std::ios::binary);
  f.write(bytes.data(), std::streamsize(bytes.size()));
}

std::string readBytes(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

void expectSame(const pc::Image& a, const pc::Image& b) {
  ASSERT_EQ(a.width, b.width);
  ASSERT_EQ(a.height, b.height);
  for (std::size_t i = 0; i < a.pixels.size(); ++i) {
    ASSERT_EQ(a.pixels[i], b.pixels[i]) << "pixel " << i;
  }
}

}  // namespace

TEST(Tonemap, MatchesSharedCurve) {
  pc::Image img(4, 1);
  img.at(0, 0) = glm::vec3(0.0f);
  img.at(1, 0) = glm::vec3(0.18f);
  img.at(2, 0) = glm::vec3(1.0f, 0.5f, 0.25f);
  img.at(3, 0) = glm::vec3(1000.0f);
  pc::Image8 t = pc::tonemap(img, 2.0f);
  ASSERT_EQ(t.rgb.size(), 12u);
  EXPECT_EQ(t.rgb[0], 0);
  EXPECT_EQ(t.rgb[9], 255);
  for (int x = 0; x < 4; ++x) {
    glm::vec3 v = pc::gpu::pcTonemap(img.at(x, 0), 2.0f);
    EXPECT_EQ(t.rgb[3 * x], std::lround(v.x * 255.0f));
    EXPECT_EQ(t.rgb[3 * x + 1], std::lround(v.y * 255.0f));
    EXPECT_EQ(t.rgb[3 * x + 2], std::lround(v.z * 255.0f));
  }
}

TEST_F(ImageTest, PngRoundTrip) {
  pc::Image8 img = randomImage8(37, 19, 1);
  ASSERT_TRUE(pc::writePng(path("a.png"), img).ok());
  auto back = pc::readPng(path("a.png"));
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->width, 37);
  EXPECT_EQ(back->height, 19);
  EXPECT_EQ(back->rgb, img.rgb);

  // readImage decodes the same file to linear values.
  auto lin = pc::readImage(path("a.png"));
  ASSERT_TRUE(lin.ok()) << lin.error().message;
  EXPECT_NEAR(lin->at(3, 2).y, pc::gpu::pcSrgbDecode(img.rgb[(2 * 37 + 3) * 3 + 1] / 255.0f),
              1e-6f);
}

TEST_F(ImageTest, ExrRoundTripIsExact) {
  pc::Image img = randomImage(33, 21, 2, 100.0f);
  ASSERT_TRUE(pc::writeExr(path("a.exr"), img).ok());
  auto back = pc::readImage(path("a.exr"));
  ASSERT_TRUE(back.ok()) << back.error().message;
  expectSame(img, *back);
}

TEST_F(ImageTest, PfmRoundTripAndLayout) {
  pc::Image img = randomImage(5, 3, 3);
  ASSERT_TRUE(pc::writePfm(path("a.pfm"), img).ok());
  auto back = pc::readImage(path("a.pfm"));
  ASSERT_TRUE(back.ok()) << back.error().message;
  expectSame(img, *back);

  // Header, little-endian scale, and rows bottom to top.
  std::string bytes = readBytes(path("a.pfm"));
  const std::string header = "PF\n5 3\n-1.0\n";
  ASSERT_EQ(bytes.substr(0, header.size()), header);
  ASSERT_EQ(bytes.size(), header.size() + 5 * 3 * 12);
  float first;
  std::memcpy(&first, bytes.data() + header.size(), 4);
  EXPECT_EQ(first, img.at(0, 2).x);  // bottom-left pixel comes first
}

TEST_F(ImageTest, PfmBigEndianAndGrey) {
  // A greyscale big-endian file as other tools write it: 2x1, values 0.5 and 2.
  std::string bytes = "Pf\n2 1\n1.0\n";
  const unsigned char px[] = {0x3f, 0x00, 0x00, 0x00, 0x40, 0x00, 0x00, 0x00};
  bytes.append(reinterpret_cast<const char*>(px), sizeof px);
  writeBytes(path("g.pfm"), bytes);
  auto img = pc::readImage(path("g.pfm"));
  ASSERT_TRUE(img.ok()) << img.error().message;
  EXPECT_EQ(img->at(0, 0), glm::vec3(0.5f));
  EXPECT_EQ(img->at(1, 0), glm::vec3(2.0f));
}

TEST_F(ImageTest, ErrorsNameFileAndProblem) {
  auto missing = pc::readImage(path("nope.exr"));
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find("nope.exr"), std::string::npos);
  EXPECT_NE(missing.error().message.find("not found"), std::string::npos);

  pc::Image img = randomImage(8, 8, 4);
  ASSERT_TRUE(pc::writePfm(path("t.pfm"), img).ok());
  std::string bytes = readBytes(path("t.pfm"));
  writeBytes(path("t.pfm"), bytes.substr(0, bytes.size() - 7));
  auto truncated = pc::readImage(path("t.pfm"));
  ASSERT_FALSE(truncated.ok());
  EXPECT_NE(truncated.error().message.find("t.pfm"), std::string::npos);
  EXPECT_NE(truncated.error().message.find("truncated"), std::string::npos);

  writeBytes(path("h.pfm"), "PF\n-3 2\n-1.0\n");
  EXPECT_FALSE(pc::readImage(path("h.pfm")).ok());
  writeBytes(path("m.pfm"), "P6\n2 2\n255\n");
  EXPECT_FALSE(pc::readImage(path("m.pfm")).ok());

  ASSERT_TRUE(pc::writeExr(path("t.exr"), img).ok());
  bytes = readBytes(path("t.exr"));
  writeBytes(path("t.exr"), bytes.substr(0, bytes.size() / 2));
  auto badExr = pc::readImage(path("t.exr"));
  ASSERT_FALSE(badExr.ok());
  EXPECT_NE(badExr.error().message.find("t.exr"), std::string::npos);

  writeBytes(path("bad.png"), "not a png at all");
  auto badPng = pc::readPng(path("bad.png"));
  ASSERT_FALSE(badPng.ok());
  EXPECT_NE(badPng.error().message.find("bad.png"), std::string::npos);

  writeBytes(path("x.tga"), "whatever");
  auto unsupported = pc::readImage(path("x.tga"));
  ASSERT_FALSE(unsupported.ok());
  EXPECT_NE(unsupported.error().message.find("unsupported"), std::string::npos);

  EXPECT_FALSE(pc::writePng(path("no/such/dir/a.png"), randomImage8(2, 2, 1)).ok());
  EXPECT_FALSE(pc::writePfm(path("no/such/dir/a.pfm"), img).ok());
  EXPECT_FALSE(pc::writeExr(path("no/such/dir/a.exr"), img).ok());
}

TEST(Metrics, IdenticalImages) {
  pc::Image8 a = randomImage8(40, 30, 5);
  EXPECT_EQ(pc::psnr8(a, a), std::numeric_limits<double>::infinity());
  EXPECT_EQ(pc::ssim8(a, a), 1.0);
  pc::Image lin = randomImage(40, 30, 6);
  EXPECT_EQ(pc::psnrLinear(lin, lin), std::numeric_limits<double>::infinity());
  pc::Image8 d = pc::differenceImage(a, a);
  ASSERT_EQ(d.rgb.size(), a.rgb.size());
  for (unsigned char v : d.rgb) ASSERT_EQ(v, 0);
}

TEST(Metrics, KnownNoisePsnr) {
  // Every value off by exactly 5: MSE 25, PSNR = 10 log10(255^2 / 25) = 34.151 dB.
  pc::Image8 a = randomImage8(64, 48, 7), b = a;
  for (std::size_t i = 0; i < a.rgb.size(); ++i) {
    a.rgb[i] = static_cast<unsigned char>(std::clamp(int(a.rgb[i]), 5, 250));
    b.rgb[i] = static_cast<unsigned char>(a.rgb[i] + ((i % 2) ? 5 : -5));
  }
  EXPECT_NEAR(pc::psnr8(a, b), 10.0 * std::log10(255.0 * 255.0 / 25.0), 1e-9);

  // Gaussian noise of sigma 8 (8-bit levels, clipped rarely at mid-grey): about 30.05 dB.
  pc::Image8 g, n;
  g.width = n.width = 256;
  g.height = n.height = 256;
  g.rgb.assign(256 * 256 * 3, 128);
  n.rgb.resize(g.rgb.size());
  std::mt19937 rng(8);
  std::normal_distribution<double> noise(0.0, 8.0);
  for (std::size_t i = 0; i < n.rgb.size(); ++i) {
    n.rgb[i] = static_cast<unsigned char>(std::clamp(std::lround(128.0 + noise(rng)), 0L, 255L));
  }
  // Rounding adds 1/12 to the variance.
  EXPECT_NEAR(pc::psnr8(n, g), 10.0 * std::log10(255.0 * 255.0 / (64.0 + 1.0 / 12.0)), 0.1);
}

// A test image with an error of its own, scored against a noisy reference and against the
// noise-free one: taking the reference's noise (known from its two halves) out of the first
// recovers the second.
TEST(Metrics, ReferenceNoiseIsTakenOutOfTheMeasure) {
  pc::Image8 truth, test, reference;
  truth.width = test.width = reference.width = 256;
  truth.height = test.height = reference.height = 256;
  truth.rgb.assign(256 * 256 * 3, 128);
  test.rgb.resize(truth.rgb.size());
  reference.rgb.resize(truth.rgb.size());
  std::mt19937 rng(11);
  std::normal_distribution<double> error(0.0, 4.0), noise(0.0, 6.0);
  auto level = [](double v) {
    return static_cast<unsigned char>(std::clamp(std::lround(v), 0L, 255L));
  };
  for (std::size_t i = 0; i < truth.rgb.size(); ++i) {
    test.rgb[i] = level(128.0 + error(rng));
    reference.rgb[i] = level(128.0 + noise(rng));
  }
  const double noisePsnr = pc::psnr8(reference, truth);
  const double measured = pc::psnr8(test, reference);
  const double estimate = pc::psnrWithoutReferenceNoise(measured, noisePsnr);
  EXPECT_LT(measured, pc::psnr8(test, truth) - 3.0);  // the noise dominates the raw measure
  EXPECT_NEAR(estimate, pc::psnr8(test, truth), 0.15);
  // Within 1 dB of the noise: not judged.
  EXPECT_TRUE(std::isnan(pc::psnrWithoutReferenceNoise(30.0, 30.5)));
  // A noise-free reference (infinite or unknown noise PSNR) leaves the measure as it is.
  EXPECT_EQ(pc::psnrWithoutReferenceNoise(27.5, std::numeric_limits<double>::infinity()), 27.5);
}

TEST(Image, BoxDownsampleAveragesEachBlockInLinearLight) {
  pc::Image fine(4, 2);
  for (int y = 0; y < 2; ++y)
    for (int x = 0; x < 4; ++x) fine.at(x, y) = glm::vec3(float(x + 4 * y), 1.0f, 0.0f);
  pc::Image coarse = pc::boxDownsample(fine, 2);
  ASSERT_EQ(coarse.width, 2);
  ASSERT_EQ(coarse.height, 1);
  EXPECT_FLOAT_EQ(coarse.at(0, 0).x, (0 + 1 + 4 + 5) / 4.0f);
  EXPECT_FLOAT_EQ(coarse.at(1, 0).x, (2 + 3 + 6 + 7) / 4.0f);
  EXPECT_FLOAT_EQ(coarse.at(1, 0).y, 1.0f);
  EXPECT_EQ(pc::boxDownsample(fine, 1).pixels, fine.pixels);
}

TEST(Metrics, LinearPsnrUsesReferencePeak) {
  // Reference luminance 2 everywhere: peak 2; error 0.2 per channel: MSE 0.04 -> 20 dB.
  pc::Image ref(64, 64), test(64, 64);
  for (auto& p : ref.pixels) p = glm::vec3(2.0f);
  for (auto& p : test.pixels) p = glm::vec3(2.2f);
  EXPECT_NEAR(pc::psnrLinear(test, ref), 20.0, 1e-4);
  // A firefly in the reference (matched by the test image) does not move the peak.
  ref.pixels[0] = glm::vec3(1e6f);
  test.pixels[0] = glm::vec3(1e6f);
  EXPECT_NEAR(pc::psnrLinear(test, ref), 20.0, 0.1);
}

TEST(Metrics, SsimOrdersDistortions) {
  pc::Image8 a = randomImage8(64, 64, 9), small = a, large = a;
  std::mt19937 rng(10);
  for (std::size_t i = 0; i < a.rgb.size(); ++i) {
    int s = int(rng() % 5) - 2, l = int(rng() % 61) - 30;
    small.rgb[i] = static_cast<unsigned char>(std::clamp(int(a.rgb[i]) + s, 0, 255));
    large.rgb[i] = static_cast<unsigned char>(std::clamp(int(a.rgb[i]) + l, 0, 255));
  }
  double s1 = pc::ssim8(a, small), s2 = pc::ssim8(a, large);
  EXPECT_LT(s1, 1.0);
  EXPECT_GT(s1, s2);
  EXPECT_GT(s2, 0.0);
  // Tiny images are one window.
  pc::Image8 t = randomImage8(3, 2, 11);
  EXPECT_EQ(pc::ssim8(t, t), 1.0);
}

TEST(Metrics, SizeMismatch) {
  pc::Image8 a = randomImage8(4, 4, 1), b = randomImage8(4, 5, 1);
  EXPECT_TRUE(std::isnan(pc::psnr8(a, b)));
  EXPECT_TRUE(std::isnan(pc::ssim8(a, b)));
  EXPECT_TRUE(pc::differenceImage(a, b).rgb.empty());
}

TEST(Metrics, DifferenceImageColours) {
  pc::Image8 a = randomImage8(10, 10, 12), b = a;
  b.rgb[3 * 17 + 1] ^= 0x40;  // one pixel changed: it is the largest difference, so red
  pc::Image8 d = pc::differenceImage(a, b);
  ASSERT_EQ(d.rgb.size(), a.rgb.size());
  EXPECT_EQ(d.rgb[3 * 17], 255);
  EXPECT_EQ(d.rgb[3 * 17 + 1], 0);
  EXPECT_EQ(d.rgb[3 * 17 + 2], 0);
  EXPECT_EQ(d.rgb[0] + d.rgb[1] + d.rgb[2], 0);
}

// ---- probecast-imgdiff ------------------------------------------------------------------------

namespace {

struct RunResult {
  int status = -1;
  std::string output;
};

struct PipeCloser {
  void operator()(std::FILE* f) const { ::pclose(f); }
};

RunResult run(const std::string& args) {
  RunResult r;
  const std::string cmd = std::string(PC_BUILD_DIR) + "/bin/probecast-imgdiff " + args + " 2>&1";
  std::FILE* p = ::popen(cmd.c_str(), "r");
  if (!p) return r;
  char buf[512];
  std::size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, p)) > 0) r.output.append(buf, n);
  int status = ::pclose(p);
  r.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

}  // namespace

TEST_F(ImageTest, ImgdiffTool) {
  if (!fs::exists(fs::path(PC_BUILD_DIR) / "bin/probecast-imgdiff")) {
    GTEST_SKIP() << "probecast-imgdiff not built";
  }
  pc::Image a = randomImage(32, 24, 13), b = a;
  b.at(5, 5) += glm::vec3(0.5f);
  ASSERT_TRUE(pc::writeExr(path("a.exr"), a).ok());
  ASSERT_TRUE(pc::writePfm(path("b.pfm"), b).ok());
  ASSERT_TRUE(pc::writeExr(path("small.exr"), randomImage(8, 8, 14)).ok());
  const std::string A = path("a.exr").string(), B = path("b.pfm").string();

  RunResult same = run(A + " " + A);
  EXPECT_EQ(same.status, 0) << same.output;
  EXPECT_NE(same.output.find("FIGURE psnr_8bit inf dB"), std::string::npos) << same.output;
  EXPECT_NE(same.output.find("FIGURE ssim 1.00000"), std::string::npos) << same.output;

  RunResult diff = run(A + " " + B + " --exposure 0.5 --diff " + path("d.png").string());
  EXPECT_EQ(diff.status, 0) << diff.output;
  EXPECT_NE(diff.output.find("FIGURE psnr_linear"), std::string::npos) << diff.output;
  EXPECT_TRUE(fs::exists(path("d.png")));

  RunResult json = run(A + " " + B + " --json");
  EXPECT_EQ(json.status, 0) << json.output;
  EXPECT_NE(json.output.find("\"psnr_8bit_db\""), std::string::npos) << json.output;
  EXPECT_EQ(json.output.find("FIGURE"), std::string::npos) << json.output;

  // --json FILE, as the other tools take it: the JSON in the file, the table on stdout.
  RunResult jsonFile = run(A + " " + B + " --json " + path("r.json").string());
  EXPECT_EQ(jsonFile.status, 0) << jsonFile.output;
  EXPECT_NE(jsonFile.output.find("FIGURE psnr_8bit"), std::string::npos) << jsonFile.output;
  std::ifstream written(path("r.json"));
  const std::string text{std::istreambuf_iterator<char>(written), {}};
  EXPECT_NE(text.find("\"psnr_8bit_db\""), std::string::npos) << text;

  RunResult mismatch = run(A + " " + path("small.exr").string());
  EXPECT_NE(mismatch.status, 0);
  EXPECT_NE(mismatch.output.find("size mismatch"), std::string::npos) << mismatch.output;

  RunResult missing = run(A + " " + path("missing.exr").string());
  EXPECT_NE(missing.status, 0);
  EXPECT_NE(missing.output.find("missing.exr"), std::string::npos) << missing.output;

  writeBytes(path("junk.png"), "junk");
  RunResult junk = run(path("junk.png").string() + " " + path("junk.png").string());
  EXPECT_NE(junk.status, 0);
  EXPECT_NE(junk.output.find("junk.png"), std::string::npos) << junk.output;
}
