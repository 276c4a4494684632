#include "vulkan_accel.h"

#include <cstring>
#include <utility>

namespace pc {

namespace {

VkDeviceAddress alignUp(VkDeviceAddress v, VkDeviceAddress a) { return (v + a - 1) / a * a; }

// Scratch memory whose device address is aligned as builds require. Vulkan leaves the
// alignment to a property queried per device; 256 covers every implementation we know, and
// the buffer is over-allocated so the aligned address stays inside it.
constexpr VkDeviceSize kScratchAlignment = 256;

Result<vk::Buffer> scratchBuffer(const vk::Context& ctx, VkDeviceSize size,
                                 VkDeviceAddress* aligned) {
  auto b = vk::Buffer::create(
      ctx, size + kScratchAlignment,
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
  as.size_ = size;
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
  VkAccelerationStructureDeviceAddressInfoKHR ai{
      VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_DEVICE_ADDRESS_INFO_KHR};
  ai.accelerationStructure = as.handle_;
  as.address_ = ctx.rt().getAccelerationStructureDeviceAddress(ctx.device(), &ai);
  return as;
}

AccelerationStructure::~AccelerationStructure() { release(); }

void AccelerationStructure::release() {
  if (ctx_ && handle_) ctx_->rt().destroyAccelerationStructure(ctx_->device(), handle_, nullptr);
  handle_ = VK_NULL_HANDLE;
}

AccelerationStructure::AccelerationStructure(AccelerationStructure&& o) noexcept {
  *this = std::move(o);
}

AccelerationStructure& AccelerationStructure::operator=(AccelerationStructure&& o) noexcept {
  if (this == &o) return *this;
  release();
  ctx_ = o.ctx_;
  handle_ = std::exchange(o.handle_, VK_NULL_HANDLE);
  storage_ = std::move(o.storage_);
  address_ = o.address_;
  size_ = o.size_;
  return *this;
}

namespace {

// One bottom-level structure to build: its triangle ranges (one geometry each).
struct BottomLevelJob {
  std::vector<MeshRange> ranges;
  AccelerationStructure* target = nullptr;
};

// Builds `jobs` in one submission, then compacts them (a second submission): compaction
// typically halves a structure built for fast tracing, and a smaller structure caches better.
Status buildBottomLevels(const vk::Context& ctx, const vk::Buffer& vertices,
                         std::uint32_t vertexStride, const vk::Buffer& indices,
                         std::vector<BottomLevelJob>& jobs) {
  if (jobs.empty()) return Status::success();
  std::vector<std::vector<VkAccelerationStructureGeometryKHR>> geometries(jobs.size());
  std::vector<std::vector<VkAccelerationStructureBuildRangeInfoKHR>> ranges(jobs.size());
  std::vector<VkAccelerationStructureBuildGeometryInfoKHR> builds;
  std::vector<AccelerationStructure> built;
  std::vector<vk::Buffer> scratch;
  for (std::size_t j = 0; j < jobs.size(); ++j) {
    std::vector<std::uint32_t> counts;
    for (const MeshRange& r : jobs[j].ranges) {
      VkAccelerationStructureGeometryKHR g{VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_KHR};
      g.geometryType = VK_GEOMETRY_TYPE_TRIANGLES_KHR;
      // Opaque: every triangle occludes, no any-hit shader runs. Cut-outs leave it to theirs.
      g.flags = r.cutOut ? 0 : VK_GEOMETRY_OPAQUE_BIT_KHR;
      auto& t = g.geometry.triangles;
      t = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_TRIANGLES_DATA_KHR};
      t.vertexFormat = VK_FORMAT_R32G32B32_SFLOAT;
      t.vertexData.deviceAddress =
          vertices.address() + VkDeviceAddress(r.firstVertex) * vertexStride;
      t.vertexStride = vertexStride;
      t.maxVertex = r.vertexCount > 0 ? r.vertexCount - 1 : 0;
      t.indexType = VK_INDEX_TYPE_UINT32;
      t.indexData.deviceAddress = indices.address() + VkDeviceAddress(r.firstIndex) * 4;
      geometries[j].push_back(g);
      ranges[j].push_back({r.triangleCount, 0, 0, 0});
      counts.push_back(r.triangleCount);
    }
    VkAccelerationStructureBuildGeometryInfoKHR info{
        VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_GEOMETRY_INFO_KHR};
    info.type = VK_ACCELERATION_STRUCTURE_TYPE_BOTTOM_LEVEL_KHR;
    info.flags = VK_BUILD_ACCELERATION_STRUCTURE_PREFER_FAST_TRACE_BIT_KHR |
                 VK_BUILD_ACCELERATION_STRUCTURE_ALLOW_COMPACTION_BIT_KHR;
    info.mode = VK_BUILD_ACCELERATION_STRUCTURE_MODE_BUILD_KHR;
    info.geometryCount = std::uint32_t(geometries[j].size());
    info.pGeometries = geometries[j].data();
    VkAccelerationStructureBuildSizesInfoKHR sizes{
        VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_SIZES_INFO_KHR};
    ctx.rt().getAccelerationStructureBuildSizes(ctx.device(),
                                                VK_ACCELERATION_STRUCTURE_BUILD_TYPE_DEVICE_KHR,
                                                &info, counts.data(), &sizes);
    auto as = AccelerationStructure::create(ctx, VK_ACCELERATION_STRUCTURE_TYPE_BOTTOM_LEVEL_KHR,
                                            sizes.accelerationStructureSize);
    if (!as) return as.error();
    built.push_back(std::move(as).value());
    VkDeviceAddress scratchAddress = 0;
    auto sb = scratchBuffer(ctx, sizes.buildScratchSize, &scratchAddress);
    if (!sb) return sb.error();
    scratch.push_back(std::move(sb).value());
    info.dstAccelerationStructure = built.back().get();
    info.scratchData.deviceAddress = scratchAddress;
    builds.push_back(info);
  }

  // The compaction entry points are not among the context's loaded functions.
  auto writeProperties = reinterpret_cast<PFN_vkCmdWriteAccelerationStructuresPropertiesKHR>(
      vkGetDeviceProcAddr(ctx.device(), "vkCmdWriteAccelerationStructuresPropertiesKHR"));
  auto copyStructure = reinterpret_cast<PFN_vkCmdCopyAccelerationStructureKHR>(
      vkGetDeviceProcAddr(ctx.device(), "vkCmdCopyAccelerationStructureKHR"));
  VkQueryPool pool = VK_NULL_HANDLE;
  if (writeProperties && copyStructure) {
    VkQueryPoolCreateInfo qci{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
    qci.queryType = VK_QUERY_TYPE_ACCELERATION_STRUCTURE_COMPACTED_SIZE_KHR;
    qci.queryCount = std::uint32_t(jobs.size());
    PC_VK_TRY(vkCreateQueryPool(ctx.device(), &qci, nullptr, &pool));
  }
  struct PoolGuard {
    VkDevice device;
    VkQueryPool pool;
    ~PoolGuard() {
      if (pool) vkDestroyQueryPool(device, pool, nullptr);
    }
  } guard{ctx.device(), pool};

  std::vector<const VkAccelerationStructureBuildRangeInfoKHR*> rangePtrs;
  for (const auto& r : ranges) rangePtrs.push_back(r.data());
  std::vector<VkAccelerationStructureKHR> handles;
  for (const auto& as : built) handles.push_back(as.get());
  Status st = ctx.submitAndWait([&](VkCommandBuffer cmd) {
    ctx.rt().cmdBuildAccelerationStructures(cmd, std::uint32_t(builds.size()), builds.data(),
                                            rangePtrs.data());
    if (!pool) return;
    vkCmdResetQueryPool(cmd, pool, 0, std::uint32_t(handles.size()));
    vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_ACCELERATION_STRUCTURE_BUILD_BIT_KHR,
                      VK_ACCESS_2_ACCELERATION_STRUCTURE_WRITE_BIT_KHR,
                      VK_PIPELINE_STAGE_2_ACCELERATION_STRUCTURE_BUILD_BIT_KHR,
                      VK_ACCESS_2_ACCELERATION_STRUCTURE_READ_BIT_KHR);
    writeProperties(cmd, std::uint32_t(handles.size()), handles.data(),
                    VK_QUERY_TYPE_ACCELERATION_STRUCTURE_COMPACTED_SIZE_KHR, pool, 0);
  });
  if (!st) return st.error();
  std::vector<VkDeviceSize> compacted(jobs.size(), 0);
  if (pool) {
    PC_VK_TRY(vkGetQueryPoolResults(
        ctx.device(), pool, 0, std::uint32_t(jobs.size()), compacted.size() * sizeof(VkDeviceSize),
        compacted.data(), sizeof(VkDeviceSize), VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT));
  }
  // Structures that report no size (or no gain) stay as built.
  std::vector<std::pair<std::size_t, AccelerationStructure>> copies;
  for (std::size_t j = 0; j < jobs.size(); ++j) {
    if (compacted[j] == 0 || compacted[j] >= built[j].size()) continue;
    auto as = AccelerationStructure::create(ctx, VK_ACCELERATION_STRUCTURE_TYPE_BOTTOM_LEVEL_KHR,
                                            compacted[j]);
    if (!as) return as.error();
    copies.emplace_back(j, std::move(as).value());
  }
  if (!copies.empty()) {
    st = ctx.submitAndWait([&](VkCommandBuffer cmd) {
      for (const auto& [j, as] : copies) {
        VkCopyAccelerationStructureInfoKHR ci{
            VK_STRUCTURE_TYPE_COPY_ACCELERATION_STRUCTURE_INFO_KHR};
        ci.src = built[j].get();
        ci.dst = as.get();
        ci.mode = VK_COPY_ACCELERATION_STRUCTURE_MODE_COMPACT_KHR;
        copyStructure(cmd, &ci);
      }
    });
    if (!st) return st.error();
    for (auto& [j, as] : copies) built[j] = std::move(as);
  }
  for (std::size_t j = 0; j < jobs.size(); ++j) *jobs[j].target = std::move(built[j]);
  return Status::success();
}

}  // namespace

Result<SceneAccel> SceneAccel::build(const vk::Context& ctx, const vk::Buffer& vertices,
                                     std::uint32_t vertexStride, const vk::Buffer& indices,
                                     const std::vector<MeshRange>& staticGeometries,
                                     const std::vector<MeshRange>& meshes,
                                     const std::vector<bool>& meshNeeded,
                                     std::size_t instanceCapacity) {
  SceneAccel s;
  s.ctx_ = &ctx;
  s.blas_.resize(meshes.size());

  // ---- bottom level: the static structure and the animated meshes' ----
  std::vector<BottomLevelJob> jobs;
  // Geometry g of the static structure is the g-th range: callers leave out empty ones.
  bool anyStatic = false;
  for (const MeshRange& r : staticGeometries) anyStatic = anyStatic || r.triangleCount > 0;
  if (anyStatic) jobs.push_back({staticGeometries, &s.static_});
  for (std::size_t m = 0; m < meshes.size(); ++m) {
    if (m < meshNeeded.size() && meshNeeded[m] && meshes[m].triangleCount > 0)
      jobs.push_back({{meshes[m]}, &s.blas_[m]});
  }
  if (Status st = buildBottomLevels(ctx, vertices, vertexStride, indices, jobs); !st)
    return st.error();

  // ---- top level: sized for every instance ----
  s.instanceCapacity_ = std::max<std::size_t>(instanceCapacity, 1);
  auto inst =
      vk::Buffer::create(ctx, s.instanceCapacity_ * sizeof(VkAccelerationStructureInstanceKHR),
                         VK_BUFFER_USAGE_ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_BIT_KHR |
                             VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT,
                         vk::MemoryUsage::Upload);
  if (!inst) return inst.error();
  s.instances_ = std::move(inst).value();
  VkAccelerationStructureGeometryKHR g{VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_KHR};
  g.geometryType = VK_GEOMETRY_TYPE_INSTANCES_KHR;
  g.geometry.instances = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_INSTANCES_DATA_KHR};
  g.geometry.instances.data.deviceAddress = s.instances_.address();
  VkAccelerationStructureBuildGeometryInfoKHR info{
      VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_GEOMETRY_INFO_KHR};
  info.type = VK_ACCELERATION_STRUCTURE_TYPE_TOP_LEVEL_KHR;
  info.flags = VK_BUILD_ACCELERATION_STRUCTURE_PREFER_FAST_TRACE_BIT_KHR;
  info.mode = VK_BUILD_ACCELERATION_STRUCTURE_MODE_BUILD_KHR;
  info.geometryCount = 1;
  info.pGeometries = &g;
  const auto maxInstances = std::uint32_t(s.instanceCapacity_);
  VkAccelerationStructureBuildSizesInfoKHR sizes{
      VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_SIZES_INFO_KHR};
  ctx.rt().getAccelerationStructureBuildSizes(
      ctx.device(), VK_ACCELERATION_STRUCTURE_BUILD_TYPE_DEVICE_KHR, &info, &maxInstances, &sizes);
  auto tlas = AccelerationStructure::create(ctx, VK_ACCELERATION_STRUCTURE_TYPE_TOP_LEVEL_KHR,
                                            sizes.accelerationStructureSize);
  if (!tlas) return tlas.error();
  s.tlas_ = std::move(tlas).value();
  auto sb = scratchBuffer(ctx, sizes.buildScratchSize, &s.tlasScratchAddress_);
  if (!sb) return sb.error();
  s.tlasScratch_ = std::move(sb).value();
  return s;
}

void SceneAccel::setInstances(const std::vector<TopLevelInstance>& instances) {
  auto* out = instances_.as<VkAccelerationStructureInstanceKHR>();
  std::uint32_t n = 0;
  for (std::size_t i = 0; i < instances.size() && n < instanceCapacity_; ++i) {
    const TopLevelInstance& t = instances[i];
    const AccelerationStructure* blas = t.mesh < 0                           ? &static_
                                        : std::size_t(t.mesh) < blas_.size() ? &blas_[t.mesh]
                                                                             : nullptr;
    if (!blas || !blas->get()) continue;
    VkAccelerationStructureInstanceKHR inst{};
    // VkTransformMatrixKHR is 3x4 row-major; glm is column-major.
    const glm::mat4& m = t.transform;
    for (int row = 0; row < 3; ++row)
      for (int col = 0; col < 4; ++col) inst.transform.matrix[row][col] = m[col][row];
    inst.instanceCustomIndex = t.customIndex;
    inst.mask = 0xFF;
    inst.instanceShaderBindingTableRecordOffset = 0;
    // Probe rays must see backfaces (they mark probes inside geometry), so never cull.
    inst.flags = VK_GEOMETRY_INSTANCE_TRIANGLE_FACING_CULL_DISABLE_BIT_KHR;
    inst.accelerationStructureReference = blas->address();
    out[n++] = inst;
  }
  instanceCount_ = n;
}

void SceneAccel::recordTopLevelBuild(VkCommandBuffer cmd) {
  VkAccelerationStructureGeometryKHR g{VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_KHR};
  g.geometryType = VK_GEOMETRY_TYPE_INSTANCES_KHR;
  g.geometry.instances = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_INSTANCES_DATA_KHR};
  g.geometry.instances.data.deviceAddress = instances_.address();
  VkAccelerationStructureBuildGeometryInfoKHR info{
      VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_GEOMETRY_INFO_KHR};
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
                    VK_ACCESS_2_ACCELERATION_STRUCTURE_WRITE_BIT_KHR,
                    VK_PIPELINE_STAGE_2_RAY_TRACING_SHADER_BIT_KHR,
                    VK_ACCESS_2_ACCELERATION_STRUCTURE_READ_BIT_KHR);
}

}  // namespace pc
