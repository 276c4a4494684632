#include "emissive_lights.h"

#include <algorithm>
#include <cstdint>

#include "../shaders/interop/probe_math.h"

namespace pc {
namespace {

glm::mat4 instanceTransform(const Scene& scene, const SceneState& state, std::size_t i) {
  return i < state.instanceTransforms.size() ? state.instanceTransforms[i]
                                             : scene.instances[i].transform;
}

const Material* materialOf(const Scene& scene, const Mesh& mesh) {
  return mesh.material >= 0 && std::size_t(mesh.material) < scene.materials.size()
             ? &scene.materials[mesh.material]
             : nullptr;
}

// Mean emitted radiance over a triangle: the emissive texture at four interior points is a
// cheap stand-in for its integral, enough to weight light selection and the estimate.
glm::vec3 triangleRadiance(const Scene& scene, const Mesh& mesh, const Material& mat,
                           std::uint32_t i0, std::uint32_t i1, std::uint32_t i2) {
  if (mat.emissiveTexture < 0 || std::size_t(mat.emissiveTexture) >= scene.textures.size() ||
      mesh.uvs.size() != mesh.positions.size()) {
    return mat.emissive;
  }
  const Texture& tex = scene.textures[mat.emissiveTexture];
  const glm::vec2 a = mesh.uvs[i0], b = mesh.uvs[i1], c = mesh.uvs[i2];
  const glm::vec3 bary[4] = {{1.0f / 3, 1.0f / 3, 1.0f / 3},
                             {2.0f / 3, 1.0f / 6, 1.0f / 6},
                             {1.0f / 6, 2.0f / 3, 1.0f / 6},
                             {1.0f / 6, 1.0f / 6, 2.0f / 3}};
  glm::vec3 sum(0.0f);
  for (const glm::vec3& w : bary) {
    const glm::vec4 t = tex.sample(w.x * a + w.y * b + w.z * c);
    sum += glm::vec3(t.x, t.y, t.z);
  }
  return mat.emissive * sum * 0.25f;
}

}  // namespace

bool emissiveAsLights(EmissiveMode mode, double emissiveArea, double totalArea) {
  switch (mode) {
    case EmissiveMode::Lights:
      return true;
    case EmissiveMode::Field:
      return false;
    case EmissiveMode::Auto:
      // Small bright emitters (lamps, screens) cast sharp shadows that only light sampling
      // with shadow rays resolves, and a probe field is too coarse to hold them. Large dim
      // emitters (glowing walls, skylight panels) light everything softly: sampling them is
      // noisy for little gain, while the field captures their smooth light well.
      return emissiveArea > 0.0 && emissiveArea < kEmissiveLightsMaxAreaShare * totalArea;
  }
  return false;
}

EmissiveSurfaces::EmissiveSurfaces(const Scene& scene) {
  const SceneState rest = evaluateScene(scene, 0.0);
  for (std::size_t i = 0; i < scene.instances.size(); ++i) {
    const Instance& inst = scene.instances[i];
    if (inst.mesh < 0 || std::size_t(inst.mesh) >= scene.meshes.size()) continue;
    const Mesh& mesh = scene.meshes[inst.mesh];
    const Material* mat = materialOf(scene, mesh);
    const bool glows = mat && mat->isEmissive();
    const glm::mat4 m = instanceTransform(scene, rest, i);
    for (std::size_t t = 0; t + 2 < mesh.indices.size(); t += 3) {
      const std::uint32_t i0 = mesh.indices[t], i1 = mesh.indices[t + 1], i2 = mesh.indices[t + 2];
      if (std::max({i0, i1, i2}) >= mesh.positions.size()) continue;
      const glm::vec3 p0 = glm::vec3(m * glm::vec4(mesh.positions[i0], 1.0f));
      const glm::vec3 p1 = glm::vec3(m * glm::vec4(mesh.positions[i1], 1.0f));
      const glm::vec3 p2 = glm::vec3(m * glm::vec4(mesh.positions[i2], 1.0f));
      const float twiceArea = glm::length(glm::cross(p1 - p0, p2 - p0));
      if (twiceArea <= 0.0f) continue;
      const float area = 0.5f * twiceArea;
      totalArea_ += area;
      if (!glows) continue;
      emissiveArea_ += area;
      const glm::vec3 radiance = triangleRadiance(scene, mesh, *mat, i0, i1, i2);
      if (gpu::pcLuminance(radiance) <= 0.0f) continue;
      sources_.push_back({i, i0, i1, i2, radiance});
    }
  }
}

EmissiveLights EmissiveLights::build(const Scene& scene, const SceneState& state) {
  return build(scene, state, EmissiveSurfaces(scene));
}

EmissiveLights EmissiveLights::build(const Scene& scene, const SceneState& state,
                                     const EmissiveSurfaces& surfaces) {
  EmissiveLights lights;
  lights.sampledMaterials_.assign(scene.materials.size(), false);
  if (!emissiveAsLights(scene.emissiveMode, surfaces.emissiveArea_, surfaces.totalArea_))
    return lights;
  for (std::size_t m = 0; m < scene.materials.size(); ++m) {
    lights.sampledMaterials_[m] = scene.materials[m].isEmissive();
  }
  // Only the emitting triangles are placed at `state`.
  std::size_t placed = SIZE_MAX;
  glm::mat4 m(1.0f);
  float side = 1.0f;
  for (const EmissiveSurfaces::Source& src : surfaces.sources_) {
    if (src.instance != placed) {
      placed = src.instance;
      m = instanceTransform(scene, state, src.instance);
      // A mirroring transform flips the winding, and with it which side is the front.
      side = glm::determinant(glm::mat3(m)) < 0.0f ? -1.0f : 1.0f;
    }
    const Mesh& mesh = scene.meshes[scene.instances[src.instance].mesh];
    const glm::vec3 p0 = glm::vec3(m * glm::vec4(mesh.positions[src.i0], 1.0f));
    const glm::vec3 p1 = glm::vec3(m * glm::vec4(mesh.positions[src.i1], 1.0f));
    const glm::vec3 p2 = glm::vec3(m * glm::vec4(mesh.positions[src.i2], 1.0f));
    const glm::vec3 cross = glm::cross(p1 - p0, p2 - p0);
    const float twiceArea = glm::length(cross);
    if (twiceArea <= 0.0f) continue;
    // An edit may dim or switch off a material's emission (SceneState::emissionScale).
    const glm::vec3 radiance = src.radiance * state.emissionScaleOf(mesh.material);
    if (gpu::pcLuminance(radiance) <= 0.0f) continue;
    lights.triangles_.push_back(
        {p0, p1 - p0, p2 - p0, side * cross / twiceArea, 0.5f * twiceArea, radiance});
  }
  if (lights.triangles_.empty()) return lights;
  double sum = 0.0;
  lights.cdf_.reserve(lights.triangles_.size());
  for (const Triangle& tri : lights.triangles_) {
    sum += double(gpu::pcLuminance(tri.radiance)) * tri.area * gpu::PC_PI;
    lights.cdf_.push_back(static_cast<float>(sum));
  }
  for (float& c : lights.cdf_) c = static_cast<float>(c / sum);
  lights.cdf_.back() = 1.0f;  // not empty: the list has triangles
  lights.totalPower_ = static_cast<float>(sum);
  return lights;
}

bool EmissiveLights::sampled(int material) const {
  return material >= 0 && std::size_t(material) < sampledMaterials_.size() &&
         sampledMaterials_[material];
}

}  // namespace pc
