// Scene sidecars (common/scene_sidecar.cpp): the scene.json reader applied to the built-in
// scene, as loadScene applies it to a loaded file, returns success or an Error naming the file
// and the JSON pointer, never crashes. The reader takes a path, so each input is written to a
// temporary file first. A sidecar that applies is followed by the steps loadScene and its users
// run next: bounds, the scene hash, default volumes, the animation clock.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "common/scene.h"
#include "common/scene_loaders.h"

namespace {

using namespace pc;

void removeInput();

const std::filesystem::path& inputPath() {
  static const std::filesystem::path path = [] {
    std::atexit(removeInput);
    return std::filesystem::temp_directory_path() /
           ("probecast-fuzz-sidecar-" + std::to_string(::getpid()) + ".json");
  }();
  return path;
}

void removeInput() {
  std::error_code ec;
  std::filesystem::remove(inputPath(), ec);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  {
    std::ofstream out(inputPath(), std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), std::streamsize(size));
    if (!out) std::abort();
  }
  static const Scene builtin = builtinScene();
  Scene scene = builtin;
  Status s = scene_detail::applySidecar(scene, inputPath());
  if (!s) {
    if (s.error().message.rfind(inputPath().string(), 0) != 0) std::abort();  // names the file
    return 0;
  }
  // A unit_scale large enough to overflow the box's corners is refused by name, as loadScene
  // refuses it with the scene file's name in front.
  if (Status b = scene_detail::computeBounds(scene); !b) {
    if (b.error().message.find("non-finite world position") == std::string::npos) std::abort();
    return 0;
  }
  (void)scene_detail::hashScene(scene);
  if (scene.volumes.empty()) (void)defaultVolumes(scene);
  for (double t : {0.0, 0.7, 1e4}) {
    SceneState state = evaluateScene(scene, t);
    if (state.lights.size() != scene.lights.size()) std::abort();
  }
  return 0;
}
