#include "scene_glossy.h"

#include <fstream>
#include <nlohmann/json.hpp>

namespace pc {

Status writeGlossyCornellSidecar(const std::filesystem::path& baseSidecar, float roughness,
                                 const std::filesystem::path& out) {
  std::ifstream in(baseSidecar);
  if (!in) return Error{"glossy Cornell: cannot read " + baseSidecar.string()};
  nlohmann::json root = nlohmann::json::parse(in, nullptr, false);
  if (root.is_discarded() || !root.is_object())
    return Error{"glossy Cornell: " + baseSidecar.string() + " is not a JSON object"};
  nlohmann::json materials = nlohmann::json::array();
  for (const GlossyOverride& m : kGlossyCornellMaterials)
    materials.push_back({{"name", m.material}, {"metallic", m.metallic}, {"roughness", roughness}});
  root["materials"] = materials;
  std::ofstream file(out);
  file << root.dump(2);
  if (!file) return Error{"glossy Cornell: cannot write " + out.string()};
  return {};
}

}  // namespace pc
