// Scene sidecars (common/scene_sidecar.cpp): the scene.json reader applied to the built-in
// scene, as loadScene applies it to a loaded file, returns success or an Error naming the file
// and the JSON pointer, never crashes. The reader takes a path, so each input is written to a
// file first (scene_file_checks.h). A sidecar that applies is followed by the steps loadScene
// and its users run next: bounds, the scene hash, default volumes, the animation clock.
#include "common/scene_loaders.h"
#include "scene_file_checks.h"

using namespace pc;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const std::filesystem::path path = fuzz::inputDir("sidecar") / "scene.json";
  fuzz::writeInput(path, data, size);
  static const Scene builtin = builtinScene();
  Scene scene = builtin;
  Status s = scene_detail::applySidecar(scene, path);
  if (!s) {
    if (s.error().message.rfind(path.string(), 0) != 0) std::abort();  // names the file
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
