#include "vulkan_accel.h"

#include <cstring>

namespace pc {

namespace {

VkDeviceAddress alignUp(VkDeviceAddress v, VkDeviceAddress a) { return (v + a - 1) / a * a; }

// Scratch memory whose device address is aligned as builds require. Vulkan leaves the
// alignment to a property queried per device; 256 covers every implementation we know, and
// the buffer is over-allocated so the aligned address stays inside it.
constexpr VkDeviceSize kScratchAlignment = 256;

Result<vk::Buffer> scratchBuffer(const vk::Context& ctx, VkDeviceSize size, VkDeviceAddress* aligned) {
  auto b = vk::Buffer::create(ctx, size + kScratchAlignment,
                              VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT,
                              vk::MemoryUsage::DeviceLocal);
  if (b) *aligned = alignUp(b->address(), kScratchAlignment);
  return b;
}

}  // namespace

Result<AccelerationStructure> AccelerationStructure::create(const vk::Context& ctx,
                                                            VkAccelerationStructureTypeKHR type,
                                                            VkDeviceSize size) {
  AccelerationStructure as;
  as.ctx_ = &ctx;
  auto storage = vk::Buffer::create(ctx, size,
                                    VK_BUFFER_USAGE_ACCELERATION_STRUCTURE_STORAGE_BIT_KHR |
                                        VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT,
                                    vk::MemoryUsage::DeviceLocal);
  if (!storage) return storage.error();
  as.storage_ = std::move(storage).value();
  VkAccelerationStructureCreateInfoKHR ci{VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_CREATE_INFO_KHR};
  ci.buffer = as.storage_.get();
  ci.size = size;
  ci.type = type;
  PC_VK_TRY(ctx.rt().createAccelerationStructure(ctx.device(), &ci, nullptr, &as.handle_));
  VkAccelerationStructureDeviceAddressInfoKHR ai{VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_DEVICE_ADDRESS_INFO_KHR};
  ai.accelerationStructure = as.handle_;
  as.address_ = ctx.rt().getAccelerationStructureDeviceAddress(ctx.device(), &ai);
  return as;
}

AccelerationStructure::~AccelerationStructure() { release(); }

void AccelerationStructure::release() {
  if (ctx_ && handle_) ctx_->rt().destroyAccelerationStructure(ctx_->device(), handle_, nullptr);
  handle_ = VK_NULL_HANDLE;
}

AccelerationStructure::AccelerationStructure(AccelerationStructure&& o) noexcept { *this = std::move(o); }

AccelerationStructure& AccelerationStructure::operator=(AccelerationStructure&& o) noexcept {
  if (this == &o) return *this;
  release();
  ctx_ = o.ctx_;
  handle_ = std::exchange(o.handle_, VK_NULL_HANDLE);
  storage_ = std::move(o.storage_);
  address_ = o.address_;
  return *this;
}

Result<SceneAccel> SceneAccel::build(const vk::Context& ctx, const vk::Buffer& vertices,
                                     std::uint32_t vertexStride, const vk::Buffer& indices,
                                     const std::vector<MeshRange>& meshes, std::size_t instanceCount) {
  SceneAccel s;
  s.ctx_ = &ctx;
  s.blas_.resize(meshes.size());

  // ---- bottom level: one per mesh, all built in one submission ----
  std::vector<VkAccelerationStructureGeometryKHR> geometries(meshes.size());
  std::vector<VkAccelerationStructureBuildGeometryInfoKHR> builds;
  std::vector<VkAccelerationStructureBuildRangeInfoKHR> ranges;
  std::vector<vk::Buffer> scratch;
  for (std::size_t m = 0; m < meshes.size(); ++m) {
    const MeshRange& r = meshes[m];
    if (r.triangleCount == 0) continue;
    VkAccelerationStructureGeometryKHR& g = geometries[m];
    g = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_KHR};
    g.geometryType = VK_GEOMETRY_TYPE_TRIANGLES_KHR;
    g.flags = VK_GEOMETRY_OPAQUE_BIT_KHR;  // no any-hit shaders: every triangle occludes
    auto& t = g.geometry.triangles;
    t = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_TRIANGLES_DATA_KHR};
    t.vertexFormat = VK_FORMAT_R32G32B32_SFLOAT;
    t.vertexData.deviceAddress = vertices.address() + VkDeviceAddress(r.firstVertex) * vertexStride;
    t.vertexStride = vertexStride;
    t.maxVertex = r.vertexCount > 0 ? r.vertexCount - 1 : 0;
    t.indexType = VK_INDEX_TYPE_UINT32;
    t.indexData.deviceAddress = indices.address() + VkDeviceAddress(r.firstIndex) * 4;

    VkAccelerationStructureBuildGeometryInfoKHR info{VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_GEOMETRY_INFO_KHR};
    info.type = VK_ACCELERATION_STRUCTURE_TYPE_BOTTOM_LEVEL_KHR;
    info.flags = VK_BUILD_ACCELERATION_STRUCTURE_PREFER_FAST_TRACE_BIT_KHR;
    info.mode = VK_BUILD_ACCELERATION_STRUCTURE_MODE_BUILD_KHR;
    info.geometryCount = 1;
    info.pGeometries = &g;
    VkAccelerationStructureBuildSizesInfoKHR sizes{VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_SIZES_INFO_KHR};
    ctx.rt().getAccelerationStructureBuildSizes(ctx.device(), VK_ACCELERATION_STRUCTURE_BUILD_TYPE_DEVICE_KHR,
                                                &info, &r.triangleCount, &sizes);
    auto as = AccelerationStructure::create(ctx, VK_ACCELERATION_STRUCTURE_TYPE_BOTTOM_LEVEL_KHR,
                                            sizes.accelerationStructureSize);
    if (!as) return as.error();
    s.blas_[m] = std::move(as).value();
    VkDeviceAddress scratchAddress = 0;
    auto sb = scratchBuffer(ctx, sizes.buildScratchSize, &scratchAddress);
    if (!sb) return sb.error();
    scratch.push_back(std::move(sb).value());
    info.dstAccelerationStructure = s.blas_[m].get();
    info.scratchData.deviceAddress = scratchAddress;
    builds.push_back(info);
    ranges.push_back({r.triangleCount, 0, 0, 0});
  }
  if (!builds.empty()) {
    std::vector<const VkAccelerationStructureBuildRangeInfoKHR*> rangePtrs;
    for (const auto& r : ranges) rangePtrs.push_back(&r);
    Status st = ctx.submitAndWait([&](VkCommandBuffer cmd) {
      ctx.rt().cmdBuildAccelerationStructures(cmd, std::uint32_t(builds.size()), builds.data(), rangePtrs.data());
    });
    if (!st) return st.error();
  }

  // ---- top level: sized for every instance ----
  s.instanceCapacity_ = std::max<std::size_t>(instanceCount, 1);
  auto inst = vk::Buffer::create(ctx, s.instanceCapacity_ * sizeof(VkAccelerationStructureInstanceKHR),
                                 VK_BUFFER_USAGE_ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_BIT_KHR |
                                     VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT,
                                 vk::MemoryUsage::Upload);
  if (!inst) return inst.error();
  s.instances_ = std::move(inst).value();
  VkAccelerationStructureGeometryKHR g{VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_KHR};
  g.geometryType = VK_GEOMETRY_TYPE_INSTANCES_KHR;
  g.geometry.instances = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_INSTANCES_DATA_KHR};
  g.geometry.instances.data.deviceAddress = s.instances_.address();
  VkAccelerationStructureBuildGeometryInfoKHR info{VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_GEOMETRY_INFO_KHR};
  info.type = VK_ACCELERATION_STRUCTURE_TYPE_TOP_LEVEL_KHR;
  info.flags = VK_BUILD_ACCELERATION_STRUCTURE_PREFER_FAST_TRACE_BIT_KHR;
  info.mode = VK_BUILD_ACCELERATION_STRUCTURE_MODE_BUILD_KHR;
  info.geometryCount = 1;
  info.pGeometries = &g;
  const auto maxInstances = std::uint32_t(s.instanceCapacity_);
  VkAccelerationStructureBuildSizesInfoKHR sizes{VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_SIZES_INFO_KHR};
  ctx.rt().getAccelerationStructureBuildSizes(ctx.device(), VK_ACCELERATION_STRUCTURE_BUILD_TYPE_DEVICE_KHR, &info,
                                              &maxInstances, &sizes);
  auto tlas = AccelerationStructure::create(ctx, VK_ACCELERATION_STRUCTURE_TYPE_TOP_LEVEL_KHR,
                                            sizes.accelerationStructureSize);
  if (!tlas) return tlas.error();
  s.tlas_ = std::move(tlas).value();
  auto sb = scratchBuffer(ctx, sizes.buildScratchSize, &s.tlasScratchAddress_);
  if (!sb) return sb.error();
  s.tlasScratch_ = std::move(sb).value();
  return s;
}

void SceneAccel::setInstances(const std::vector<glm::mat4>& transforms, const std::vector<int>& instanceMesh) {
  auto* out = instances_.as<VkAccelerationStructureInstanceKHR>();
  std::uint32_t n = 0;
  for (std::size_t i = 0; i < transforms.size() && n < instanceCapacity_; ++i) {
    const int mesh = instanceMesh[i];
    if (mesh < 0 || std::size_t(mesh) >= blas_.size() || !blas_[mesh].get()) continue;
    VkAccelerationStructureInstanceKHR inst{};
    // VkTransformMatrixKHR is 3x4 row-major; glm is column-major.
    const glm::mat4& m = transforms[i];
    for (int row = 0; row < 3; ++row)
      for (int col = 0; col < 4; ++col) inst.transform.matrix[row][col] = m[col][row];
    inst.instanceCustomIndex = std::uint32_t(i);  // the shaders' index into Scene::instances
    inst.mask = 0xFF;
    inst.instanceShaderBindingTableRecordOffset = 0;
    // Probe rays must see backfaces (they mark probes inside geometry), so never cull.
    inst.flags = VK_GEOMETRY_INSTANCE_TRIANGLE_FACING_CULL_DISABLE_BIT_KHR;
    inst.accelerationStructureReference = blas_[mesh].address();
    out[n++] = inst;
  }
  instanceCount_ = n;
}

void SceneAccel::recordTopLevelBuild(VkCommandBuffer cmd) {
  VkAccelerationStructureGeometryKHR g{VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_KHR};
  g.geometryType = VK_GEOMETRY_TYPE_INSTANCES_KHR;
  g.geometry.instances = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_INSTANCES_DATA_KHR};
  g.geometry.instances.data.deviceAddress = instances_.address();
  VkAccelerationStructureBuildGeometryInfoKHR info{VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_GEOMETRY_INFO_KHR};
  info.type = VK_ACCELERATION_STRUCTURE_TYPE_TOP_LEVEL_KHR;
  info.flags = VK_BUILD_ACCELERATION_STRUCTURE_PREFER_FAST_TRACE_BIT_KHR;
  info.mode = VK_BUILD_ACCELERATION_STRUCTURE_MODE_BUILD_KHR;
  info.dstAccelerationStructure = tlas_.get();
  info.geometryCount = 1;
  info.pGeometries = &g;
  info.scratchData.deviceAddress = tlasScratchAddress_;
  VkAccelerationStructureBuildRangeInfoKHR range{instanceCount_, 0, 0, 0};
  const VkAccelerationStructureBuildRangeInfoKHR* ranges = &range;
  // The host wrote the instance records; make them visible to the build.
  vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_HOST_BIT, VK_ACCESS_2_HOST_WRITE_BIT,
                    VK_PIPELINE_STAGE_2_ACCELERATION_STRUCTURE_BUILD_BIT_KHR,
                    VK_ACCESS_2_ACCELERATION_STRUCTURE_READ_BIT_KHR | VK_ACCESS_2_SHADER_READ_BIT);
  ctx_->rt().cmdBuildAccelerationStructures(cmd, 1, &info, &ranges);
  vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_ACCELERATION_STRUCTURE_BUILD_BIT_KHR,
                    VK_ACCESS_2_ACCELERATION_STRUCTURE_WRITE_BIT_KHR, VK_PIPELINE_STAGE_2_RAY_TRACING_SHADER_BIT_KHR,
                    VK_ACCESS_2_ACCELERATION_STRUCTURE_READ_BIT_KHR);
}

}  // namespace pc
