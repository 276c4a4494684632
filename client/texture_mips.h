// Mip chains for the scene's 8-bit textures (sRGB colour, or linear data such as normal maps). The
// lighting pass rebuilds surfaces in a compute shader and passes the texture footprint of each
// pixel explicitly (textureGrad), so minified textures are filtered instead of aliasing: the
// path-traced reference averages the texture over each pixel, which a single level-0 tap per sample
// cannot do.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

namespace pc::client {

struct MipChain {
  int levels = 0;
  // Every level's RGBA8 sRGB texels, tightly packed, level 0 (the input) first.
  std::vector<std::uint8_t> rgba;
};

// Number of levels down to 1x1: floor(log2(max(width, height))) + 1.
int mipLevelCount(int width, int height);

// The full chain of a width x height RGBA8 image. Each level halves the one above (sizes
// round down, at least 1); a texel averages its 2x2 parents in linear light (colour decoded
// from sRGB unless `linear`, alpha as stored), the odd last row or column of a level folding
// into its neighbour's average so that no texel of the level above is dropped.
MipChain buildMipChain(int width, int height, std::span<const std::uint8_t> rgba, bool linear);
inline MipChain buildSrgbMipChain(int width, int height, std::span<const std::uint8_t> rgba) {
  return buildMipChain(width, height, rgba, false);
}

}  // namespace pc::client
