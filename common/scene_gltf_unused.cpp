#include "common/scene_gltf_unused.h"

#include <tiny_gltf.h>

#include <map>

namespace pc::scene_detail {

namespace {

// Feature -> names of the materials that use it, in file order.
using Users = std::map<std::string, std::vector<std::string>>;

std::string materialName(const tinygltf::Material& m, std::size_t index) {
  return m.name.empty() ? "material" + std::to_string(index) : m.name;
}

std::string listed(const std::vector<std::string>& names) {
  constexpr std::size_t kShown = 3;  // enough to find them; the count says how many more
  std::string out;
  for (std::size_t i = 0; i < names.size() && i < kShown; ++i)
    out += (i ? ", '" : "'") + names[i] + "'";
  if (names.size() > kShown) out += " and " + std::to_string(names.size() - kShown) + " more";
  return out;
}

void collectMaterialFeatures(const tinygltf::Model& model, const std::set<std::string>& honoured,
                             Users& users) {
  for (std::size_t i = 0; i < model.materials.size(); ++i) {
    const tinygltf::Material& m = model.materials[i];
    const std::string name = materialName(m, i);
    if (m.occlusionTexture.index >= 0) users["occlusion texture"].push_back(name);
    for (const auto& [ext, value] : m.extensions)
      if (!honoured.count(ext)) users["material extension " + ext].push_back(name);
  }
}

}  // namespace

std::vector<std::string> unusedGltfFeatures(const tinygltf::Model& model,
                                            const std::set<std::string>& honoured) {
  Users users;
  collectMaterialFeatures(model, honoured, users);
  std::vector<std::string> out;
  for (const auto& [feature, names] : users)
    out.push_back("glTF " + feature + " not used (materials " + listed(names) + ")");
  // Extensions the file declares but nothing reads (material ones are named above).
  for (const std::string& ext : model.extensionsUsed) {
    if (honoured.count(ext) || users.count("material extension " + ext)) continue;
    out.push_back("glTF extension " + ext + " not used");
  }
  // Node animations are read (scene_gltf.cpp); the reader itself names the skins and the
  // channels it leaves alone.
  return out;
}

}  // namespace pc::scene_detail
