// Shared by the scene-file fuzz targets (fuzz_obj, fuzz_gltf; fuzz_sidecar writes its inputs
// with inputDir and writeInput too): each input is written to a file in a directory of its own
// (the loaders take paths, and a scene.json beside an input would be read as its sidecar),
// loaded with loadScene and an empty sidecar, and then either refused with an error that
// names the file or checked against what every user of a Scene relies on.
#pragma once

#include <unistd.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "common/scene.h"

namespace pc::fuzz {

// A directory for this process's inputs, removed at exit.
inline const std::filesystem::path& inputDir(const char* target) {
  static const std::filesystem::path dir = [target] {
    std::filesystem::path d =
        std::filesystem::temp_directory_path() /
        ("probecast-fuzz-" + std::string(target) + "-" + std::to_string(::getpid()));
    std::filesystem::create_directories(d);
    std::ofstream(d / "empty-sidecar.json") << "{}";
    std::atexit([] {
      std::error_code ec;
      std::filesystem::remove_all(inputDir(nullptr), ec);
    });
    return d;
  }();
  return dir;
}

inline void writeInput(const std::filesystem::path& path, const std::uint8_t* data,
                       std::size_t size) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), std::streamsize(size));
  if (!out) std::abort();
}

inline bool finite(glm::vec3 v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

// What the tracers, renderers and the scene hash index without checking again.
inline void checkLoadedScene(const Scene& scene) {
  const int textures = int(scene.textures.size());
  for (const Texture& t : scene.textures)
    if (t.width <= 0 || t.height <= 0 ||
        t.rgba.size() != std::size_t(t.width) * std::size_t(t.height) * 4)
      std::abort();
  for (const Material& m : scene.materials)
    for (int t : {m.baseColorTexture, m.emissiveTexture, m.alphaTexture})
      if (t < -1 || t >= textures) std::abort();
  for (const Mesh& m : scene.meshes) {
    if (m.indices.size() % 3 != 0) std::abort();
    if (m.normals.size() != m.positions.size()) std::abort();
    if (!m.uvs.empty() && m.uvs.size() != m.positions.size()) std::abort();
    for (std::uint32_t i : m.indices)
      if (i >= m.positions.size()) std::abort();
    for (const glm::vec3& p : m.positions)
      if (!finite(p)) std::abort();
  }
  if (scene.triangleCount() == 0) std::abort();  // loadScene refuses scenes without triangles
  if (!finite(scene.boundsMin) || !finite(scene.boundsMax)) std::abort();
  for (const Instance& inst : scene.instances) (void)scene.materialOf(inst);
  if (scene.volumes.empty()) (void)defaultVolumes(scene);
  for (double t : {0.0, 0.7, 1e4}) {
    SceneState state = evaluateScene(scene, t);
    if (state.lights.size() != scene.lights.size()) std::abort();
  }
}

// Loads `path`; an error must name the file it is about (the input or a file it refers to,
// all within the input's directory).
inline void loadAndCheck(const std::filesystem::path& path) {
  Result<Scene> scene = loadScene(path, path.parent_path() / "empty-sidecar.json");
  if (!scene) {
    if (scene.error().message.find(path.parent_path().string()) == std::string::npos) std::abort();
    return;
  }
  checkLoadedScene(*scene);
}

}  // namespace pc::fuzz
