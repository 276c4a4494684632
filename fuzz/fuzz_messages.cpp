// Session messages (protocol/session_messages.h): decodeMessage on any bytes returns a message
// or an Error, never crashes. A decoded message survives re-encoding unchanged, and goes
// through what a peer does with it next (the hello check, the client's mirror field built from
// the layout message, the scene state applied to the built-in scene, a resume claim read as a
// field of the bricks it claims, an edit checked and applied to the built-in scene).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <variant>

#include "common/scene.h"
#include "common/scene_edits.h"
#include "fuzz_support.h"
#include "protocol/resume_state.h"
#include "protocol/session_messages.h"

namespace {

using namespace pc;

// mirrorField lays out every slot the message asks for (about 4 KiB of atlases per slot) and
// accepts up to 4M slots; see docs/FUZZING.md. Larger layouts are not built here so that the
// fuzzer's memory limit keeps catching allocations the decoders themselves make.
constexpr std::int64_t kMaxMirrorSlots = std::int64_t(1) << 16;

std::int64_t slotCount(const SessionInfoMsg& info) {
  std::int64_t slots = 0;
  for (const gpu::CascadeDesc& c : info.cascades) {
    const std::int64_t x = c.counts.x, y = c.counts.y, z = c.counts.z;
    if (x < 1 || y < 1 || z < 1 || x > 1024 || y > 1024 || z > 1024) return 0;  // rejected
    slots += (x + 3) * (y + 3) * (z + 3);
  }
  return slots;
}

void useMessage(const SessionMessage& m) {
  if (const auto* hello = std::get_if<HelloMsg>(&m)) {
    static const TokenVerifier verifier({keyPairFromSeed({9}).verify});
    (void)checkHello(*hello, verifier, "fuzz-scene", 1000);
  } else if (const auto* welcome = std::get_if<WelcomeMsg>(&m)) {
    (void)checkServerVersion(welcome->protocolVersion);
  } else if (const auto* info = std::get_if<SessionInfoMsg>(&m)) {
    if (slotCount(*info) <= kMaxMirrorSlots) {
      Result<Field> mirror = mirrorField(*info);
      if (mirror) {
        // The client's receiver sizes its per-brick state from these.
        if (mirror->cascadeCount() != int(info->cascades.size())) std::abort();
      }
    }
  } else if (const auto* resume = std::get_if<ResumeMsg>(&m)) {
    // A field of exactly the claimed bricks, so that the versions are decompressed and read.
    auto held = heldBricksOf(*resume, {resume->brickCount});
    if (held && held->front().size() != resume->brickCount) std::abort();
  } else if (const auto* edit = std::get_if<EditMsg>(&m)) {
    // What a server does with an editor's edit: checked and applied, or refused unchanged.
    static const Scene scene = builtinScene();
    SceneEdits edits(scene);
    auto applied = edits.apply(edit->edit, 0.5);
    if (!applied && edits.version() != 0) std::abort();
    const SceneState s = edits.evaluate(0.5);
    for (const Light& l : s.lights)
      if (!std::isfinite(l.intensity) || !std::isfinite(l.position.x)) std::abort();
  } else if (const auto* state = std::get_if<SceneStateMsg>(&m)) {
    static const Scene scene = builtinScene();
    SceneState s = evaluateScene(scene, 0.0);
    (void)applySceneState(*state, s);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  (void)messageFrameSize(std::span<const std::uint8_t>(data, size < 4 ? size : 4));
  // As received, then with the length prefix made to fit so that mutations reach the body.
  const std::vector<std::uint8_t> fitted = fuzz::withFittedPrefix(data, size);
  for (const std::span<const std::uint8_t> frame :
       {std::span<const std::uint8_t>(data, size), std::span<const std::uint8_t>(fitted)}) {
    Result<SessionMessage> m = decodeMessage(frame);
    if (!m) continue;
    useMessage(m.value());
    // Encoding what was decoded gives a frame that decodes to the same encoding.
    // (Tables shared by reference in the input are written out once each, so the encoding
    // may outgrow the size limit.)
    const std::vector<std::uint8_t> once = encodeMessage(m.value());
    if (once.size() > kMaxSessionMessageBytes) continue;
    Result<SessionMessage> again = decodeMessage(once);
    if (!again) std::abort();
    if (encodeMessage(again.value()) != once) std::abort();
  }
  return 0;
}
