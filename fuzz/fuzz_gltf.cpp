// glTF 2.0 (common/scene_gltf.cpp, through tinygltf): loadScene on any bytes returns a scene
// every user can index safely, or an error naming the file; never crashes. Inputs that begin
// with the binary container's magic are written as scene.glb, the rest as scene.gltf (whose
// buffers and images the seeds carry as data URIs: no other file is there to refer to).
#include <cstring>

#include "scene_file_checks.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::filesystem::path& dir = pc::fuzz::inputDir("gltf");
  const bool binary = size >= 4 && std::memcmp(data, "glTF", 4) == 0;
  const std::filesystem::path path = dir / (binary ? "scene.glb" : "scene.gltf");
  pc::fuzz::writeInput(path, data, size);
  pc::fuzz::loadAndCheck(path);
  std::error_code ec;
  std::filesystem::remove(path, ec);
  return 0;
}
