#include "resume_state.h"

#include <zstd.h>

#include <numeric>
#include <string>

#include "protocol/brick_precision.h"

namespace pc {

namespace {

constexpr int kVersionBytes = 8;
// Few bytes, compressed once per session: a fast level does as well as a slow one.
constexpr int kResumeZstdLevel = 3;

Error fail(const std::string& what) { return Error{"resume: " + what}; }

}  // namespace

ResumeMsg resumeMessage(std::uint64_t sceneHash, std::uint64_t epoch, const HeldBricks& held) {
  ResumeMsg m;
  m.sceneHash = sceneHash;
  m.fieldEpoch = epoch;
  std::size_t bricks = 0;
  for (const auto& cascade : held) bricks += cascade.size();
  m.brickCount = std::uint32_t(bricks);
  // Byte planes: byte j of brick i at j * bricks + i.
  std::vector<std::uint8_t> planes(bricks * kVersionBytes);
  std::size_t i = 0;
  for (int k = 0; k < int(held.size()); ++k) {
    for (std::uint32_t b = 0; b < held[k].size(); ++b, ++i) {
      const HeldBrick& h = held[k][b];
      for (int j = 0; j < kVersionBytes; ++j)
        planes[std::size_t(j) * bricks + i] = std::uint8_t(h.version >> (8 * j));
      if (h.version != 0 && h.precision != 0)
        m.precisions.push_back(BrickPrecisionMsg{k, b, h.precision});
    }
  }
  m.versions.resize(ZSTD_compressBound(planes.size()));
  const std::size_t n = ZSTD_compress(m.versions.data(), m.versions.size(), planes.data(),
                                      planes.size(), kResumeZstdLevel);
  // Compressing into a buffer of the bound cannot fail; an empty claim holds nothing if it did.
  if (ZSTD_isError(n)) return ResumeMsg{sceneHash, epoch, 0, {}, {}};
  m.versions.resize(n);
  return m;
}

Result<HeldBricks> heldBricksOf(const ResumeMsg& m,
                                const std::vector<std::size_t>& bricksPerCascade) {
  const std::size_t bricks =
      std::accumulate(bricksPerCascade.begin(), bricksPerCascade.end(), std::size_t(0));
  if (m.brickCount != bricks) {
    return fail("claims " + std::to_string(m.brickCount) + " bricks; the field has " +
                std::to_string(bricks));
  }
  const std::size_t raw = bricks * kVersionBytes;
  // The announced size is checked before anything is allocated or decompressed.
  const unsigned long long announced =
      ZSTD_getFrameContentSize(m.versions.data(), m.versions.size());
  if (announced == ZSTD_CONTENTSIZE_ERROR || announced == ZSTD_CONTENTSIZE_UNKNOWN)
    return fail("versions are not a zstd frame stating its size");
  if (announced != raw) {
    return fail("versions announce " + std::to_string(announced) + " bytes, expected " +
                std::to_string(raw) + " (8 per brick)");
  }
  std::vector<std::uint8_t> planes(raw);
  const std::size_t n =
      ZSTD_decompress(planes.data(), planes.size(), m.versions.data(), m.versions.size());
  if (ZSTD_isError(n)) return fail(std::string("versions: ") + ZSTD_getErrorName(n));
  if (n != raw) {
    return fail("versions decompress to " + std::to_string(n) + " bytes, expected " +
                std::to_string(raw));
  }
  HeldBricks held(bricksPerCascade.size());
  std::size_t i = 0;
  for (std::size_t k = 0; k < bricksPerCascade.size(); ++k) {
    held[k].resize(bricksPerCascade[k]);
    for (HeldBrick& h : held[k]) {
      for (int j = 0; j < kVersionBytes; ++j)
        h.version |= std::uint64_t(planes[std::size_t(j) * bricks + i]) << (8 * j);
      ++i;
    }
  }
  for (const BrickPrecisionMsg& p : m.precisions) {
    if (p.cascade < 0 || std::size_t(p.cascade) >= held.size() ||
        p.brick >= held[std::size_t(p.cascade)].size()) {
      return fail("precision of brick " + std::to_string(p.brick) + " of cascade " +
                  std::to_string(p.cascade) + ", outside the field");
    }
    if (p.precision < 0 || p.precision > kMaxPrecision) {
      return fail("precision level " + std::to_string(p.precision) + " (the coarsest is " +
                  std::to_string(kMaxPrecision) + ")");
    }
    held[std::size_t(p.cascade)][p.brick].precision = p.precision;
  }
  return held;
}

}  // namespace pc
