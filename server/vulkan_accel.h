// Acceleration structures for the Vulkan tracer: a bottom-level structure per mesh (object
// space, built once) and a top-level structure over the scene's instances, rebuilt when
// instances move. RAII: each structure owns its handle and storage buffer.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

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
  static Result<AccelerationStructure> create(const vk::Context& ctx, VkAccelerationStructureTypeKHR type,
                                              VkDeviceSize size);
  VkAccelerationStructureKHR get() const { return handle_; }
  VkDeviceAddress address() const { return address_; }

 private:
  void release();
  const vk::Context* ctx_ = nullptr;
  VkAccelerationStructureKHR handle_ = VK_NULL_HANDLE;
  vk::Buffer storage_;
  VkDeviceAddress address_ = 0;
};

// Where a mesh's triangles live in the shared vertex and index buffers.
struct MeshRange {
  std::uint32_t firstVertex = 0, vertexCount = 0;
  std::uint32_t firstIndex = 0, triangleCount = 0;
};

class SceneAccel {
 public:
  // Builds one BLAS per mesh with triangles. `vertices` holds positions at offset 0 of each
  // `vertexStride`-byte vertex; indices are 32-bit and mesh-local.
  static Result<SceneAccel> build(const vk::Context& ctx, const vk::Buffer& vertices,
                                  std::uint32_t vertexStride, const vk::Buffer& indices,
                                  const std::vector<MeshRange>& meshes, std::size_t instanceCount);

  // Writes the instance records for `transforms` (one per Scene::instances entry, mesh index in
  // `instanceMesh`); the next recordTopLevelBuild() uses them.
  void setInstances(const std::vector<glm::mat4>& transforms, const std::vector<int>& instanceMesh);
  // Records the top-level build (full rebuild: rigid motion of a few instances makes a refit
  // degrade, and a TLAS over instances builds in microseconds on a GPU).
  void recordTopLevelBuild(VkCommandBuffer cmd);
  VkAccelerationStructureKHR topLevel() const { return tlas_.get(); }

 private:
  const vk::Context* ctx_ = nullptr;
  std::vector<AccelerationStructure> blas_;  // per mesh; empty handle for meshes without triangles
  AccelerationStructure tlas_;
  vk::Buffer instances_;  // VkAccelerationStructureInstanceKHR[], host-written
  vk::Buffer tlasScratch_;
  VkDeviceAddress tlasScratchAddress_ = 0;
  std::uint32_t instanceCount_ = 0;  // written by setInstances
  std::size_t instanceCapacity_ = 0;
};

}  // namespace pc
