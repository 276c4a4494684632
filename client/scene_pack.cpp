#include "scene_pack.h"

#include <algorithm>

namespace pc::client {

PackedScene packScene(const Scene& scene) {
  PackedScene p;
  p.meshes.resize(scene.meshes.size());
  for (std::size_t m = 0; m < scene.meshes.size(); ++m) {
    const Mesh& mesh = scene.meshes[m];
    MeshRange& range = p.meshes[m];
    range.firstIndex = std::uint32_t(p.indices.size());
    range.vertexOffset = std::int32_t(p.vertices.size());
    const bool hasNormals = mesh.normals.size() == mesh.positions.size();
    const bool hasUvs = mesh.uvs.size() == mesh.positions.size();
    const bool hasTangents = mesh.tangents.size() == mesh.positions.size();
    for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
      p.vertices.push_back({mesh.positions[v], hasNormals ? mesh.normals[v] : glm::vec3(0.0f),
                            hasUvs ? mesh.uvs[v] : glm::vec2(0.0f),
                            hasTangents ? mesh.tangents[v] : glm::vec4(0.0f)});
    }
    // Triangles with an index out of range are dropped, as the CPU renders drop them.
    for (std::size_t t = 0; t + 2 < mesh.indices.size(); t += 3) {
      const std::uint32_t a = mesh.indices[t], b = mesh.indices[t + 1], c = mesh.indices[t + 2];
      if (a >= mesh.positions.size() || b >= mesh.positions.size() || c >= mesh.positions.size())
        continue;
      p.indices.insert(p.indices.end(), {a, b, c});
    }
    range.indexCount = std::uint32_t(p.indices.size()) - range.firstIndex;
  }
  for (std::size_t i = 0; i < scene.instances.size(); ++i) {
    const int mesh = scene.instances[i].mesh;
    if (mesh >= 0 && std::size_t(mesh) < p.meshes.size() && p.meshes[mesh].indexCount > 0) {
      p.drawInstances.push_back(int(i));
      p.triangleBases.push_back(std::uint32_t(p.triangleIds));
      p.triangleIds += p.meshes[mesh].indexCount / 3;
    }
  }
  return p;
}

std::vector<gpu::DrawData> drawData(const Scene& scene, const PackedScene& packed,
                                    const SceneState& state) {
  std::vector<gpu::DrawData> draws;
  draws.reserve(packed.drawInstances.size());
  for (std::size_t k = 0; k < packed.drawInstances.size(); ++k) {
    const int i = packed.drawInstances[k];
    const Instance& inst = scene.instances[i];
    gpu::DrawData d{};
    d.model = std::size_t(i) < state.instanceTransforms.size() ? state.instanceTransforms[i]
                                                               : inst.transform;
    d.normalMatrix = glm::transpose(glm::inverse(d.model));
    const int mat = scene.meshes[inst.mesh].material;
    d.textures = glm::ivec4(-1, -1, 0, -1);
    d.normalTexture = -1;
    d.metallicRoughnessTexture = -1;
    const MeshRange& range = packed.meshes[std::size_t(inst.mesh)];
    d.geometry = glm::ivec4(std::int32_t(range.firstIndex), range.vertexOffset,
                            std::int32_t(packed.triangleBases[k]),
                            glm::determinant(glm::mat3(d.model)) < 0.0f ? -1 : 1);
    d.baseColor = glm::vec4(0.8f, 0.8f, 0.8f, 0.0f);
    d.metallic = 0.0f;  // the plain diffuse surface (Material's defaults)
    d.roughness = 1.0f;
    if (mat >= 0 && std::size_t(mat) < scene.materials.size()) {
      const Material& m = scene.materials[mat];
      d.baseColor = glm::vec4(m.baseColor, 0.0f);
      d.emissive = glm::vec4(m.emissive * state.emissionScaleOf(mat), 0.0f);  // runtime edits
      d.metallic = m.metallic;
      d.roughness = m.roughness;
      const int textures = int(scene.textures.size());
      d.textures.x = m.baseColorTexture < textures ? m.baseColorTexture : -1;
      d.textures.y = m.emissiveTexture < textures ? m.emissiveTexture : -1;
      d.metallicRoughnessTexture =
          m.metallicRoughnessTexture < textures ? m.metallicRoughnessTexture : -1;
      // Meshes without tangents (no coordinates to make them from) keep their vertex normals.
      const Mesh& mesh = scene.meshes[std::size_t(inst.mesh)];
      if (m.normalTexture >= 0 && m.normalTexture < textures &&
          mesh.tangents.size() == mesh.positions.size()) {
        d.normalTexture = m.normalTexture;
        d.normalScale = m.normalScale;
      }
      if (m.isCutOut()) {  // client_surface.glsl reads these three
        d.baseColor.w = m.baseAlpha;
        d.emissive.w = m.alphaCutoff;
        d.textures.w = m.alphaTexture >= 0 && m.alphaTexture < textures
                           ? m.alphaTexture * 4 + std::clamp(m.alphaChannel, 0, 3)
                           : -1;
      }
    }
    draws.push_back(d);
  }
  return draws;
}

}  // namespace pc::client
