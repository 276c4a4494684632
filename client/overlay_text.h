// Overlay text for the windowed client: a 5x7 bitmap font and the lines of text, packed into
// the OverlayText buffer that the tone-mapping shader draws from (shaders/interop/client_frame.h).
#pragma once

#include <string>
#include <vector>

#include "shaders/interop/client_frame.h"

namespace pc::client {

// Fills the glyph table and the text (lowercase letters are drawn as capitals; characters the
// font lacks as blanks; lines beyond PC_OVERLAY_MAX_LINES or columns beyond
// PC_OVERLAY_COLUMNS are cut).
gpu::OverlayText makeOverlayText(const std::vector<std::string>& lines);

}  // namespace pc::client
