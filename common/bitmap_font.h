// A 5x7 bitmap font: digits, capitals, the punctuation that overlays and plots print, and the
// 'x' of sizes. The client's text overlay (client/overlay_text.cpp) uploads it for its shader;
// probecast-report draws its axis labels with it.
#pragma once

#include <cstdint>
#include <span>

namespace pc {

inline constexpr int kFontColumns = 5, kFontRows = 7;

struct FontGlyph {
  char code;
  std::uint8_t rows[kFontRows];  // top row first; bit 4 is the leftmost column
};

// Every glyph the font has.
std::span<const FontGlyph> fontGlyphs();
// The glyph drawn for `c`: lowercase letters other than 'x' as capitals; nullptr where the
// font has none (drawn as a blank).
const FontGlyph* fontGlyph(char c);

}  // namespace pc
