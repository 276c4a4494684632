// probecast-imgdiff: compares two images and prints PSNR and SSIM, optionally writing a
// false-colour difference image.
//
// Linear inputs (.exr, .pfm) are tone-mapped with the same exposure and the shared tone curve,
// then compared as 8-bit sRGB; their linear PSNR is reported too. PNG inputs are compared as
// stored. Mixed inputs tone-map the linear one and compare in 8 bits.
#include <CLI/CLI.hpp>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "common/image.h"
#include "tools/command_line.h"

namespace {

bool isPng(const std::filesystem::path& p) {
  std::string ext = p.extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  return ext == ".png";
}

// An input as both 8-bit display values and, when it has them, linear values.
struct Input {
  pc::Image8 display;
  pc::Image linear;
  bool hasLinear = false;
};

pc::Result<Input> load(const std::filesystem::path& path, float exposure) {
  Input in;
  if (isPng(path)) {
    auto png = pc::readPng(path);
    if (!png) return png.error();
    in.display = std::move(png.value());
    return in;
  }
  auto img = pc::readImage(path);
  if (!img) return img.error();
  in.linear = std::move(img.value());
  in.display = pc::tonemap(in.linear, exposure);
  in.hasLinear = true;
  return in;
}

std::string formatDb(double v) {
  if (std::isinf(v)) return "inf";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3f", v);
  return buf;
}

// JSON has no infinity: identical images give null, documented in --help.
nlohmann::json jsonNumber(double v) {
  if (!std::isfinite(v)) return nullptr;
  return v;
}

int fail(const std::string& message) {
  std::fprintf(stderr, "probecast-imgdiff: error: %s\n", message.c_str());
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "Compare two images (EXR, PFM or PNG): PSNR on tone-mapped 8-bit sRGB, linear PSNR "
      "(peak = the reference's 99.9th percentile luminance) and SSIM. B is the reference. "
      "Prints a table and FIGURE lines, or JSON with --json (null PSNR = identical)."};
  std::string pathA, pathB, diffPath;
  float exposure = 1.0f;
  std::string jsonPath;
  app.add_option("A", pathA, "test image")->required();
  app.add_option("B", pathB, "reference image")->required();
  app.add_option("--exposure", exposure, "exposure applied to linear inputs before tone mapping")
      ->check(CLI::PositiveNumber);
  app.add_option("--diff", diffPath, "write a false-colour difference PNG here");
  // --json FILE as every tool takes it; bare --json (or --json -) prints the JSON instead of
  // the table, as this tool did before it took a file.
  CLI::Option* json =
      app.add_option("--json", jsonPath,
                     "write the results as one JSON object here (bare or '-': print it instead "
                     "of the table)")
          ->expected(0, 1);
  if (auto code = pc::parseCommandLine(app, argc, argv)) return *code;

  auto a = load(pathA, exposure);
  if (!a) return fail(a.error().message);
  auto b = load(pathB, exposure);
  if (!b) return fail(b.error().message);
  if (a->display.width != b->display.width || a->display.height != b->display.height) {
    return fail("size mismatch: " + pathA + " is " + std::to_string(a->display.width) + "x" +
                std::to_string(a->display.height) + ", " + pathB + " is " +
                std::to_string(b->display.width) + "x" + std::to_string(b->display.height));
  }

  const double psnr8 = pc::psnr8(a->display, b->display);
  const double ssim = pc::ssim8(a->display, b->display);
  const bool linear = a->hasLinear && b->hasLinear;
  const double psnrLin = linear ? pc::psnrLinear(a->linear, b->linear) : 0.0;

  if (!diffPath.empty()) {
    pc::Status s = pc::writePng(diffPath, pc::differenceImage(a->display, b->display));
    if (!s) return fail(s.error().message);
  }

  if (json->count() > 0) {
    nlohmann::json out = {{"a", pathA},
                          {"b", pathB},
                          {"width", a->display.width},
                          {"height", a->display.height},
                          {"exposure", exposure},
                          {"psnr_8bit_db", jsonNumber(psnr8)},
                          {"ssim", ssim}};
    if (linear) out["psnr_linear_db"] = jsonNumber(psnrLin);
    if (!diffPath.empty()) out["diff"] = diffPath;
    if (jsonPath.empty() || jsonPath == "-") {
      std::printf("%s\n", out.dump(2).c_str());
      return 0;
    }
    std::ofstream file(jsonPath);
    file << out.dump(2) << "\n";
    if (!file.flush()) return fail("cannot write " + jsonPath);
  }

  std::printf("A (test)       %s\n", pathA.c_str());
  std::printf("B (reference)  %s\n", pathB.c_str());
  std::printf("size           %d x %d\n", a->display.width, a->display.height);
  if (a->hasLinear || b->hasLinear) std::printf("exposure       %g\n", double(exposure));
  std::printf("\n%-22s %12s\n", "metric", "value");
  std::printf("%-22s %12s dB\n", "PSNR (8-bit sRGB)", formatDb(psnr8).c_str());
  if (linear) std::printf("%-22s %12s dB\n", "PSNR (linear)", formatDb(psnrLin).c_str());
  std::printf("%-22s %12.5f\n", "SSIM (luma, 8x8)", ssim);
  if (!diffPath.empty()) std::printf("difference image: %s\n", diffPath.c_str());
  std::printf("\nFIGURE psnr_8bit %s dB\n", formatDb(psnr8).c_str());
  if (linear) std::printf("FIGURE psnr_linear %s dB\n", formatDb(psnrLin).c_str());
  std::printf("FIGURE ssim %.5f ratio\n", ssim);
  return 0;
}
