// Wavefront OBJ and MTL (common/scene_obj.cpp, through tinyobjloader): loadScene on any bytes
// returns a scene every user can index safely, or an error naming the file; never crashes.
// The same bytes are written as scene.obj and as scene.mtl, so one input reaches both parsers
// (each skips the other's statements) and `mtllib scene.mtl` finds its materials.
#include "scene_file_checks.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::filesystem::path& dir = pc::fuzz::inputDir("obj");
  pc::fuzz::writeInput(dir / "scene.obj", data, size);
  pc::fuzz::writeInput(dir / "scene.mtl", data, size);
  pc::fuzz::loadAndCheck(dir / "scene.obj");
  return 0;
}
