#include "quality_report.h"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>

namespace pc::bench {

namespace fs = std::filesystem;

namespace {

constexpr int kGap = 4;
constexpr unsigned char kGapGrey = 128, kMissingGrey = 40;

// JSON has no infinity: identical images (PSNR inf) are written as null.
nlohmann::json number(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); }

nlohmann::json scoresJson(const Scores& s) {
  return {{"psnr", number(s.psnr)},
          {"psnr_noise_free_estimate", number(s.psnrNoiseFree)},
          {"ssim", number(s.ssim)},
          {"flip", number(s.flip)}};
}

std::string cell(double v, const char* format) {
  if (std::isinf(v)) return "inf";
  if (std::isnan(v)) return "-";
  char buf[32];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

// A table cell may not hold a '|'; error messages may.
std::string escaped(std::string s) {
  for (char& c : s)
    if (c == '|' || c == '\n') c = '/';
  return s;
}

void blit(Image8& dst, const Image8& src, int x0, int y0, int w, int h) {
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) {
        const bool have = src.width == w && src.height == h;
        dst.rgb[((std::size_t(y0 + y) * dst.width) + x0 + x) * 3 + c] =
            have ? src.rgb[(std::size_t(y) * w + x) * 3 + c] : kMissingGrey;
      }
}

}  // namespace

Image8 qualityGrid(const std::vector<QualityRow>& rows) {
  Image8 grid;
  int w = 0, h = 0, count = 0;
  for (const QualityRow& r : rows) {
    if (r.reference.rgb.empty()) continue;
    w = std::max(w, r.reference.width);
    h = std::max(h, r.reference.height);
    ++count;
  }
  if (count == 0) return grid;
  grid.width = 5 * w + 4 * kGap;
  grid.height = count * h + (count - 1) * kGap;
  grid.rgb.assign(std::size_t(grid.width) * grid.height * 3, kGapGrey);
  int row = 0;
  for (const QualityRow& r : rows) {
    if (r.reference.rgb.empty()) continue;
    const Image8* cells[5] = {&r.reference, &r.probeLitImage, &r.clientImage, &r.probeLitFlip,
                              &r.clientFlip};
    for (int c = 0; c < 5; ++c) blit(grid, *cells[c], c * (w + kGap), row * (h + kGap), w, h);
    ++row;
  }
  return grid;
}

Status writeQualityReport(const fs::path& dir, const QualityRun& run,
                          const std::vector<QualityRow>& rows) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return Error{dir.string() + ": cannot create: " + ec.message()};

  nlohmann::json json;
  json["command"] = run.command;
  json["machine"] = run.machine;
  json["date"] = run.date;
  json["width"] = run.width;
  json["height"] = run.height;
  json["spp"] = run.spp;
  json["updates"] = run.updates;
  json["flip_pixels_per_degree"] = run.pixelsPerDegree;
  json["grid_columns"] = {"reference", "probe_lit", "client", "flip_probe_lit", "flip_client"};
  json["scenes"] = nlohmann::json::array();
  for (const QualityRow& r : rows) {
    nlohmann::json j{{"scene", r.scene}, {"file", r.file}};
    if (!r.error.empty()) {
      j["error"] = r.error;
    } else {
      j["volumes"] = r.volumes;
      j["probes"] = r.probes;
      j["cascades"] = r.cascades;
      j["finest_spacing"] = r.spacing;
      j["probe_lit"] = scoresJson(r.probeLit);
      j["client"] = r.client ? scoresJson(*r.client) : nlohmann::json();
      if (!r.client) j["client_note"] = r.clientNote;
      j["reference_noise_psnr"] = number(r.referenceNoisePsnr);
      j["bake_seconds"] = r.bakeSeconds;
      j["reference_seconds"] = r.referenceSeconds;
    }
    json["scenes"].push_back(std::move(j));
  }
  {
    std::ofstream out(dir / "quality.json");
    out << json.dump(2) << "\n";
    if (!out) return Error{(dir / "quality.json").string() + ": cannot write"};
  }

  std::ofstream md(dir / "quality.md");
  md << "Quality against the path-traced reference: `" << run.command << "`, " << run.machine
     << ", " << run.date << ". " << run.width << "x" << run.height << ", " << run.spp
     << " reference paths per pixel, " << run.updates
     << " bake updates. PSNR on tone-mapped 8-bit sRGB (dB), SSIM, LDR-FLIP (mean, 0 = equal, "
     << cell(run.pixelsPerDegree, "%.1f") << " pixels per degree).\n\n";
  md << "| scene | volumes | probes | spacing | probe-lit PSNR | noise-free est. | SSIM | FLIP | "
        "client PSNR | noise-free est. | SSIM | FLIP | ref noise dB | bake s | ref s |\n";
  md << "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const QualityRow& r : rows) {
    if (!r.error.empty()) {
      md << "| " << r.scene << " | error: " << escaped(r.error) << " |||||||||||||\n";
      continue;
    }
    md << "| " << r.scene << " | " << r.volumes << " | " << r.probes << " | "
       << cell(r.spacing, "%.3g") << " | " << cell(r.probeLit.psnr, "%.2f") << " | "
       << cell(r.probeLit.psnrNoiseFree, "%.2f") << " | " << cell(r.probeLit.ssim, "%.3f") << " | "
       << cell(r.probeLit.flip, "%.4f") << " | ";
    if (r.client) {
      md << cell(r.client->psnr, "%.2f") << " | " << cell(r.client->psnrNoiseFree, "%.2f") << " | "
         << cell(r.client->ssim, "%.3f") << " | " << cell(r.client->flip, "%.4f") << " | ";
    } else {
      md << "n/a (" << r.clientNote << ") | | | | ";
    }
    md << cell(r.referenceNoisePsnr, "%.1f") << " | " << cell(r.bakeSeconds, "%.1f") << " | "
       << cell(r.referenceSeconds, "%.1f") << " |\n";
  }
  md << "\n`grid.png`: one row per scene in the table's order (errors left out): reference | "
        "probe-lit | client | FLIP error of probe-lit | FLIP error of client (magma: black 0, "
        "yellow 1).\n";
  if (!md) return Error{(dir / "quality.md").string() + ": cannot write"};
  const Image8 grid = qualityGrid(rows);
  if (!grid.rgb.empty()) return writePng(dir / "grid.png", grid);
  return Status::success();
}

}  // namespace pc::bench
