#include "overlay_text.h"

#include <cctype>

#include "common/bitmap_font.h"

namespace pc::client {

static_assert(kFontRows == gpu::PC_FONT_ROWS && kFontColumns == gpu::PC_FONT_COLUMNS);

gpu::OverlayText makeOverlayText(const std::vector<std::string>& lines) {
  gpu::OverlayText o{};
  for (const FontGlyph& g : fontGlyphs()) {
    const int index = int(static_cast<unsigned char>(g.code)) - gpu::PC_FONT_FIRST;
    for (int r = 0; r < gpu::PC_FONT_ROWS; ++r) o.glyphs[index * gpu::PC_FONT_ROWS + r] = g.rows[r];
  }
  for (std::size_t l = 0; l < lines.size() && l < std::size_t(gpu::PC_OVERLAY_MAX_LINES); ++l) {
    for (std::size_t c = 0; c < lines[l].size() && c < std::size_t(gpu::PC_OVERLAY_COLUMNS); ++c) {
      unsigned char ch = static_cast<unsigned char>(lines[l][c]);
      // The font's only lowercase glyph is the 'x' of sizes.
      if (ch != 'x') ch = static_cast<unsigned char>(std::toupper(ch));
      o.text[l * gpu::PC_OVERLAY_COLUMNS + c] = ch;
    }
  }
  return o;
}

}  // namespace pc::client
