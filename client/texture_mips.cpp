#include "texture_mips.h"

#include <algorithm>
#include <cmath>

#include "common/scene.h"

namespace pc::client {
namespace {

std::uint8_t encodeSrgb(float linear) {
  const float v = std::clamp(linear, 0.0f, 1.0f);
  const float s = v <= 0.0031308f ? v * 12.92f : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
  return std::uint8_t(std::lround(s * 255.0f));
}

std::uint8_t encodeLinear(float v) {
  return std::uint8_t(std::lround(std::clamp(v, 0.0f, 1.0f) * 255.0f));
}

// The source rows (or columns) that destination row `d` of a level of `dst` rows averages:
// 2d and 2d+1, plus 2d+2 for the last row when the source has an odd count.
struct Span {
  int first, count;
};
Span parents(int d, int src, int dst) {
  if (src == 1) return {0, 1};
  const int count = (d == dst - 1 && src % 2 == 1) ? 3 : 2;
  return {2 * d, count};
}

}  // namespace

int mipLevelCount(int width, int height) {
  int levels = 1;
  for (int size = std::max(width, height); size > 1; size /= 2) ++levels;
  return levels;
}

MipChain buildMipChain(int width, int height, std::span<const std::uint8_t> rgba, bool linear) {
  MipChain chain;
  chain.levels = mipLevelCount(width, height);
  chain.rgba.assign(rgba.begin(), rgba.begin() + std::size_t(width) * height * 4);
  const auto& decode = srgbDecodeTable();
  std::size_t srcOffset = 0;
  int w = width, h = height;
  for (int level = 1; level < chain.levels; ++level) {
    const int dw = std::max(1, w / 2), dh = std::max(1, h / 2);
    const std::size_t dstOffset = chain.rgba.size();
    chain.rgba.resize(dstOffset + std::size_t(dw) * dh * 4);
    for (int y = 0; y < dh; ++y) {
      const Span rows = parents(y, h, dh);
      for (int x = 0; x < dw; ++x) {
        const Span cols = parents(x, w, dw);
        float sum[4] = {0, 0, 0, 0};
        for (int sy = rows.first; sy < rows.first + rows.count; ++sy) {
          for (int sx = cols.first; sx < cols.first + cols.count; ++sx) {
            const std::uint8_t* p = &chain.rgba[srcOffset + (std::size_t(sy) * w + sx) * 4];
            for (int c = 0; c < 3; ++c) sum[c] += linear ? float(p[c]) / 255.0f : decode[p[c]];
            sum[3] += float(p[3]) / 255.0f;
          }
        }
        const float inv = 1.0f / float(rows.count * cols.count);
        std::uint8_t* q = &chain.rgba[dstOffset + (std::size_t(y) * dw + x) * 4];
        for (int c = 0; c < 3; ++c)
          q[c] = linear ? encodeLinear(sum[c] * inv) : encodeSrgb(sum[c] * inv);
        q[3] = encodeLinear(sum[3] * inv);
      }
    }
    srcOffset = dstOffset;
    w = dw;
    h = dh;
  }
  return chain;
}

}  // namespace pc::client
