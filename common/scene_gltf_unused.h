// Internal to the glTF reader: what a glTF file holds that probecast reads past without using
// (PBR terms beyond base colour, normal maps, material extensions, animations, skins).
#pragma once

#include <set>
#include <string>
#include <vector>

namespace tinygltf {
class Model;
}

namespace pc::scene_detail {

// One warning per unused feature, naming it and the materials (the first few) that use it, so
// that a scene that looks wrong says why without a warning per material. `honoured` lists the
// extensions the reader does honour.
std::vector<std::string> unusedGltfFeatures(const tinygltf::Model& model,
                                            const std::set<std::string>& honoured);

}  // namespace pc::scene_detail
