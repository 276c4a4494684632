// Acceleration structures for the Vulkan tracer. Every static instance goes into ONE bottom-level
// structure (one geometry per instance, vertices pre-transformed to world space): per-instance
// structures of a level split by material overlap everywhere, and traversal then descends into
// many of them per ray. Animated instances keep an object-space structure per mesh and move by
// their top-level transform. The top level (1 + animated instances) is rebuilt when instances
// move. RAII: each structure owns its handle and storage buffer.
#pragma once

#include <cstdint>
#include <glm/glm.hpp>
#include <vector>

#include "../common/scene.h"
#include "../common/vulkan/context.h"

namespace pc {

class AccelerationStructure {
 public:
  AccelerationStructure() = default;
  ~AccelerationStructure();
  AccelerationStructure(AccelerationStructure&& o) noexcept;
  AccelerationStructure& operator=(AccelerationStructure&& o) noexcept;
  AccelerationStructure(const AccelerationStructure&) = delete;
  AccelerationStructure& operator=(const AccelerationStructure&) = delete;

  // Creates the structure with storage for `size` bytes (from the build sizes query).
  static Result<AccelerationStructure> create(const vk::Context& ctx,
                                              VkAccelerationStructureTypeKHR type,
                                              VkDeviceSize size);
  VkAccelerationStructureKHR get() const { return handle_; }
  VkDeviceAddress address() const { return address_; }
  VkDeviceSize size() const { return size_; }

 private:
  void release();
  const vk::Context* ctx_ = nullptr;
  VkAccelerationStructureKHR handle_ = VK_NULL_HANDLE;
  vk::Buffer storage_;
  VkDeviceAddress address_ = 0;
  VkDeviceSize size_ = 0;
};

// Where a mesh's triangles live in the shared vertex and index buffers.
struct MeshRange {
  std::uint32_t firstVertex = 0, vertexCount = 0;
  std::uint32_t firstIndex = 0, triangleCount = 0;
  // A cut-out material's triangles: built without the opaque flag, so that the any-hit shader
  // (probe_cutout.rahit) decides each candidate hit.
  bool cutOut = false;
};

// One record of the top level: the static structure (mesh < 0, identity transform) or the
// object-space structure of `mesh`. Hits report customIndex + the geometry index within the
// structure as gl_InstanceCustomIndexEXT + gl_GeometryIndexEXT.
struct TopLevelInstance {
  glm::mat4 transform{1.0f};
  int mesh = -1;
  std::uint32_t customIndex = 0;
};

class SceneAccel {
 public:
  // Builds the static structure from `staticGeometries` (world space; geometry g is the g-th
  // range) and an object-space structure for each mesh m with `meshNeeded[m]`. `vertices` holds
  // positions at offset 0 of each `vertexStride`-byte vertex; indices are 32-bit and local to
  // their range. Static structures are compacted after the build.
  static Result<SceneAccel> build(const vk::Context& ctx, const vk::Buffer& vertices,
                                  std::uint32_t vertexStride, const vk::Buffer& indices,
                                  const std::vector<MeshRange>& staticGeometries,
                                  const std::vector<MeshRange>& meshes,
                                  const std::vector<bool>& meshNeeded,
                                  std::size_t instanceCapacity);

  // Writes the top-level records; the next recordTopLevelBuild() uses them. Records naming a
  // structure that was not built (no triangles) are skipped.
  void setInstances(const std::vector<TopLevelInstance>& instances);
  // Records the top-level build (full rebuild: rigid motion of a few instances makes a refit
  // degrade, and a TLAS over instances builds in microseconds on a GPU).
  void recordTopLevelBuild(VkCommandBuffer cmd);
  VkAccelerationStructureKHR topLevel() const { return tlas_.get(); }

 private:
  const vk::Context* ctx_ = nullptr;
  AccelerationStructure static_;             // all static instances; empty handle when none
  std::vector<AccelerationStructure> blas_;  // per mesh; empty handle where not needed
  AccelerationStructure tlas_;
  vk::Buffer instances_;  // VkAccelerationStructureInstanceKHR[], host-written
  vk::Buffer tlasScratch_;
  VkDeviceAddress tlasScratchAddress_ = 0;
  std::uint32_t instanceCount_ = 0;  // written by setInstances
  std::size_t instanceCapacity_ = 0;
};

}  // namespace pc
