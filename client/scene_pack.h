// The scene in the form the rasterizer draws it: one vertex and one index array for all
// meshes, and one DrawData record per instance (transform and material), rebuilt per frame
// from the animated SceneState.
#pragma once

#include <cstdint>
#include <glm/glm.hpp>
#include <vector>

#include "common/scene.h"
#include "shaders/interop/client_frame.h"

namespace pc::client {

// The lighting pass reads these records from a float buffer (client_geometry.glsl, vertexAt).
struct Vertex {
  glm::vec3 position;
  glm::vec3 normal;
  glm::vec2 uv;
  glm::vec4 tangent;  // Mesh::tangents (xyz, handedness w); zero where the mesh has none
};
static_assert(sizeof(Vertex) == gpu::PC_CLIENT_VERTEX_FLOATS * sizeof(float));

struct MeshRange {
  std::uint32_t firstIndex = 0, indexCount = 0;
  std::int32_t vertexOffset = 0;
};

struct PackedScene {
  std::vector<Vertex> vertices;
  std::vector<std::uint32_t> indices;
  std::vector<MeshRange> meshes;   // per Scene::meshes entry
  std::vector<int> drawInstances;  // instance of each draw (instances with a drawable mesh)
  // Per draw: the first of its triangles' ids in the visibility buffer (ascending), and the
  // total over all draws, which must stay below 2^32 - 1 (id 0 is the sky).
  std::vector<std::uint32_t> triangleBases;
  std::uint64_t triangleIds = 0;
};

PackedScene packScene(const Scene& scene);

// One record per draw of `packed`, at the state's animation time.
std::vector<gpu::DrawData> drawData(const Scene& scene, const PackedScene& packed,
                                    const SceneState& state);

}  // namespace pc::client
