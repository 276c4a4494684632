// The quality harness's outputs: one table of every scene measured (markdown and JSON) and an
// image grid with one row per scene (reference | probe-lit | client | FLIP error of each).
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "common/image.h"
#include "common/result.h"

namespace pc::bench {

// One image's scores against the reference.
struct Scores {
  double psnr = 0, ssim = 0, flip = 0;
  double psnrNoiseFree = 0;  // psnrWithoutReferenceNoise (common/image.h); NaN: unjudged
};

struct QualityRow {
  std::string scene;    // slug
  std::string file;     // the scene file as given
  std::string error;    // set when the scene could not be measured; the rest is then empty
  std::string volumes;  // "sidecar" or "auto"
  int probes = 0, cascades = 0;
  float spacing = 0;  // finest cascade
  // Irradiance bytes per probe at 16 bits (fieldBytesPerProbe), and with depth and occlusion.
  double bytesPerProbe = 0, bytesPerProbeWithVisibility = 0;
  Scores probeLit;
  std::optional<Scores> client;  // unset when no client render was made
  std::string clientNote;        // why not, when unset
  double referenceNoisePsnr = 0, bakeSeconds = 0, referenceSeconds = 0;
  // Images for the grid (tone-mapped): empty where missing.
  Image8 reference, probeLitImage, clientImage, probeLitFlip, clientFlip;
};

struct QualityRun {
  std::string command, machine, date;
  int width = 0, height = 0, spp = 0, updates = 0;
  double pixelsPerDegree = 0;
};

// quality.md, quality.json and grid.png in `dir`.
Status writeQualityReport(const std::filesystem::path& dir, const QualityRun& run,
                          const std::vector<QualityRow>& rows);

// The grid: per row of rows with images, reference | probe-lit | client | FLIP probe-lit |
// FLIP client, 4 grey pixels between cells; a missing image is a dark grey cell.
Image8 qualityGrid(const std::vector<QualityRow>& rows);

}  // namespace pc::bench
