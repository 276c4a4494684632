// The SDF backend's own part of the Vulkan tracer (VulkanTracing::DistanceField): the scene's
// triangles in world space, the distance field's build on the GPU (sdf_cells.comp, then
// sdf_bricks.comp, shaders/interop/sdf_grid.h) and the compute passes that take the ray-tracing
// pipelines' place (sdf_trace.comp for the probe rays, sdf_shadow.comp for the shadow lists).
// Everything else (shade, blend, changes, readback) is the Vulkan tracer's.
#include <limits>

#include "vulkan_tracer_impl.h"

namespace pc {

namespace {

constexpr VkBufferUsageFlags kCopyable =
    kStorage | VK_BUFFER_USAGE_TRANSFER_DST_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT;

// Bands of this many voxels are held exactly by the bricks' samples: an empty stretch inside a
// brick is crossed in steps of about 3 voxels (the band less the interpolation's error).
constexpr float kBandVoxels = 4.0f;

std::size_t brickBytes(int bricks) {
  return std::size_t(std::max(bricks, 1)) * PC_SDF_BRICK_SAMPLES * sizeof(SdfSample);
}

// Reads `bytes` of device buffer `src` from `offset` through a readback buffer.
template <typename T>
Result<std::vector<T>> readBack(const vk::Context& ctx, const vk::Buffer& src, std::size_t offset,
                                std::size_t count) {
  std::vector<T> out(count);
  if (count == 0) return out;
  auto rb = vk::Buffer::create(ctx, count * sizeof(T), VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                               vk::MemoryUsage::Readback);
  if (!rb) return rb.error();
  Status copied = ctx.submitAndWait([&](VkCommandBuffer cmd) {
    const VkBufferCopy copy{offset, 0, count * sizeof(T)};
    vkCmdCopyBuffer(cmd, src.get(), rb->get(), 1, &copy);
  });
  if (!copied) return copied.error();
  if (VkResult r = rb->invalidate(); r != VK_SUCCESS)
    return Error{vk::vkErrorMessage("vkInvalidateMappedMemoryRanges", r)};
  std::memcpy(out.data(), rb->mapped(), count * sizeof(T));
  return out;
}

}  // namespace

std::vector<SdfTriangle> VulkanTracer::Impl::sdfSceneTriangles() const {
  const Scene& s = *scene;
  std::vector<SdfTriangle> out;
  for (std::size_t r = 0; r < recordInstance.size(); ++r) {
    const std::size_t i = std::size_t(recordInstance[r]);
    const Instance& inst = s.instances[i];
    // As setState places them: static instances where they were at time 0.
    const glm::mat4 t = int(r) < staticCount || i >= state.instanceTransforms.size()
                            ? inst.transform
                            : state.instanceTransforms[i];
    const Mesh& mesh = s.meshes[std::size_t(inst.mesh)];
    const bool cutOut = mesh.material >= 0 && std::size_t(mesh.material) < s.materials.size() &&
                        s.materials[std::size_t(mesh.material)].isCutOut();
    auto world = [&](std::uint32_t v) { return glm::vec3(t * glm::vec4(mesh.positions[v], 1.0f)); };
    for (std::size_t k = 0; k < mesh.triangleCount(); ++k) {
      SdfTriangle tri{};
      tri.p0 = world(mesh.indices[3 * k]);
      tri.p1 = world(mesh.indices[3 * k + 1]);
      tri.p2 = world(mesh.indices[3 * k + 2]);
      tri.record = int(r);
      tri.primitive = int(k);
      tri.cutOut = cutOut ? 1 : 0;
      out.push_back(tri);
    }
  }
  return out;
}

Status VulkanTracer::Impl::createSdfPipelines(bool cutOuts) {
  const int cutOutSpec = cutOuts ? 1 : 0;  // kCutOuts (constant_id 0)
  auto trace = computePipeline("sdf_trace.comp.spv", {{0, cutOutSpec}});
  if (!trace) return trace.error();
  tracePipeline = std::move(trace).value();
  auto shadow = computePipeline("sdf_shadow.comp.spv", {{0, cutOutSpec}});
  if (!shadow) return shadow.error();
  shadowPipeline = std::move(shadow).value();
  auto cellsPass = computePipeline("sdf_cells.comp.spv", {});
  if (!cellsPass) return cellsPass.error();
  sdfCellsPipeline = std::move(cellsPass).value();
  auto bricksPass = computePipeline("sdf_bricks.comp.spv", {});
  if (!bricksPass) return bricksPass.error();
  sdfBricksPipeline = std::move(bricksPass).value();
  return Status::success();
}

// The grid's layout is fixed by the first build: the scene's bounds (and its triangles' at
// time 0) with a margin of the band and a voxel, in whole cells. Instances that move out of it
// later are not hit outside it.
void VulkanTracer::Impl::ensureSdf() {
  if (!sdf || !sdfDirty) return;
  std::vector<SdfTriangle> tris = sdfSceneTriangles();
  SdfHeader& h = sdfHeader;
  if (h.cells.x == 0) {
    glm::vec3 lo = scene->boundsMin, hi = scene->boundsMax;
    for (const SdfTriangle& t : tris) {
      lo = glm::min(lo, glm::min(t.p0, glm::min(t.p1, t.p2)));
      hi = glm::max(hi, glm::max(t.p0, glm::max(t.p1, t.p2)));
    }
    // Where the scene has probe volumes, no farther than a spacing past them: a ground plane
    // a kilometre wide would otherwise set the voxels' size (its triangles, reaching outside,
    // are tested by every ray instead).
    if (!scene->volumes.empty()) {
      glm::vec3 vlo(std::numeric_limits<float>::max()), vhi(-vlo);
      for (const ProbeVolume& v : scene->volumes) {
        const glm::vec3 far = v.origin + v.spacing * glm::vec3(v.counts - 1);
        vlo = glm::min(vlo, glm::min(v.origin, far) - glm::vec3(v.spacing));
        vhi = glm::max(vhi, glm::max(v.origin, far) + glm::vec3(v.spacing));
      }
      lo = glm::max(lo, vlo);
      hi = glm::max(glm::min(hi, vhi), lo);
    }
    const glm::vec3 extent = glm::max(hi - lo, glm::vec3(0.0f));
    const float longest = std::max({extent.x, extent.y, extent.z, 1e-3f});
    const int voxels =
        (sdfVoxels + PC_SDF_BRICK_CELLS - 1) / PC_SDF_BRICK_CELLS * PC_SDF_BRICK_CELLS;
    h.voxel = longest / float(voxels);
    h.band = kBandVoxels * h.voxel;
    const float margin = h.band + h.voxel;
    h.origin = lo - glm::vec3(margin);
    h.cells =
        glm::max(glm::ivec3(glm::ceil((extent + 2.0f * margin) / pcSdfCellSize(h))), glm::ivec3(1));
    const int cellCount = h.cells.x * h.cells.y * h.cells.z;
    // A first guess; a build that allocates more grows the bricks and runs again.
    h.brickCapacity = std::max(64, cellCount / 4);
    h.listCapacity = h.brickCapacity * 16;
    sdfGrid = orFail(vk::Buffer::create(*ctx, sizeof(SdfHeader) + std::size_t(cellCount) * 8,
                                        kCopyable, vk::MemoryUsage::DeviceLocal),
                     "distance field grid");
    sdfHeaderReadback =
        orFail(vk::Buffer::create(*ctx, sizeof(SdfHeader), VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                  vk::MemoryUsage::Readback),
               "distance field header");
    descriptorsDirty = true;
  }
  const int cellCount = h.cells.x * h.cells.y * h.cells.z;
  h.triangleCount = int(tris.size());
  const std::size_t triBytes = std::max<std::size_t>(tris.size(), 1) * sizeof(SdfTriangle);
  if (!sdfTriangles.get() || sdfTriangles.size() != triBytes) {
    sdfTrianglesHost =
        orFail(vk::Buffer::create(*ctx, triBytes, kHostInput, vk::MemoryUsage::Upload),
               "distance field triangles");
    sdfTriangles =
        orFail(vk::Buffer::create(*ctx, triBytes, kCopyable, vk::MemoryUsage::DeviceLocal),
               "distance field triangles");
    descriptorsDirty = true;
  }
  sdfTrianglesHost.write(tris.data(), tris.size() * sizeof(SdfTriangle));
  // The triangles that reach outside the grid.
  std::vector<std::uint32_t> outside;
  const glm::vec3 gridLo = h.origin, gridHi = h.origin + glm::vec3(h.cells) * pcSdfCellSize(h);
  for (std::size_t i = 0; i < tris.size(); ++i) {
    const SdfTriangle& t = tris[i];
    for (const glm::vec3& p : {t.p0, t.p1, t.p2})
      if (glm::any(glm::lessThan(p, gridLo)) || glm::any(glm::greaterThan(p, gridHi))) {
        outside.push_back(std::uint32_t(i));
        break;
      }
  }
  h.outsideCount = int(outside.size());
  const std::size_t outsideBytes = std::max<std::size_t>(outside.size(), 1) * 4;
  if (!sdfOutside.get() || sdfOutside.size() < outsideBytes) {
    sdfOutside = orFail(vk::Buffer::create(*ctx, outsideBytes, kHostInput, vk::MemoryUsage::Upload),
                        "distance field outside triangles");
    descriptorsDirty = true;
  }
  sdfOutside.write(outside.data(), outside.size() * 4);
  if (outside.size() != sdfLastOutside) {
    if (outside.size() > 64)
      logWarn("sdf tracer: " + std::to_string(outside.size()) +
              " triangles reach outside the distance field's bounds; every ray tests them all");
    sdfLastOutside = outside.size();
  }

  // After a build, an update where only some triangles moved: their old and new bounds.
  bool update = sdfBuild.builds > 0 && sdfLastTriangles.size() == tris.size();
  glm::vec3 dirtyLo(std::numeric_limits<float>::max()), dirtyHi(-dirtyLo);
  bool moved = false;
  for (std::size_t i = 0; update && i < tris.size(); ++i) {
    const SdfTriangle &now = tris[i], &was = sdfLastTriangles[i];
    if (now.p0 == was.p0 && now.p1 == was.p1 && now.p2 == was.p2) continue;
    for (const glm::vec3& p : {now.p0, now.p1, now.p2, was.p0, was.p1, was.p2}) {
      dirtyLo = glm::min(dirtyLo, p);
      dirtyHi = glm::max(dirtyHi, p);
    }
    moved = true;
  }
  if (update && !moved) {
    sdfDirty = false;
    return;
  }

  for (int attempt = 0;; ++attempt) {
    if (!sdfBricks.get() || sdfBricks.size() < brickBytes(h.brickCapacity)) {
      sdfBricks = orFail(vk::Buffer::create(*ctx, brickBytes(h.brickCapacity), kCopyable,
                                            vk::MemoryUsage::DeviceLocal),
                         "distance field bricks");
      descriptorsDirty = true;
      update = false;  // the samples went with the old buffer
    }
    const std::size_t listBytes =
        (2 * std::size_t(h.brickCapacity) + std::size_t(h.listCapacity)) * sizeof(std::uint32_t);
    if (!sdfLists.get() || sdfLists.size() != listBytes) {
      sdfLists =
          orFail(vk::Buffer::create(*ctx, listBytes, kCopyable, vk::MemoryUsage::DeviceLocal),
                 "distance field triangle lists");
      descriptorsDirty = true;
      update = false;  // the ranges and lists went with the old buffer
    }
    writeDescriptors();
    begin();
    const VkBufferCopy triCopy{0, 0, triBytes};
    vkCmdCopyBuffer(cmd, sdfTrianglesHost.get(), sdfTriangles.get(), 1, &triCopy);
    SdfHeader start = h;
    start.brickCount = update ? sdfAllocated : 0;
    start.listCount = update ? sdfListed : 0;
    start.update = update ? 1 : 0;
    start.dirtyLo = dirtyLo;
    start.dirtyHi = dirtyHi;
    start.bricksBuilt = 0;
    vkCmdUpdateBuffer(cmd, sdfGrid.get(), 0, sizeof start, &start);
    vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT,
                      kComputeStage, kShaderRW);
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipelineLayout.get(), 0, 1, &set,
                            0, nullptr);
    timer.begin(cmd, "sdf cells");
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, sdfCellsPipeline.get());
    dispatchRows(std::uint64_t(cellCount));
    timer.end(cmd);
    vk::memoryBarrier(cmd, kComputeStage, kShaderRW, kComputeStage, kShaderRW);
    timer.begin(cmd, "sdf bricks");
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, sdfBricksPipeline.get());
    dispatchRows(std::uint64_t(cellCount));
    timer.end(cmd);
    vk::memoryBarrier(cmd, kComputeStage, kShaderRW, VK_PIPELINE_STAGE_2_COPY_BIT,
                      VK_ACCESS_2_TRANSFER_READ_BIT);
    const VkBufferCopy headerCopy{0, 0, sizeof(SdfHeader)};
    vkCmdCopyBuffer(cmd, sdfGrid.get(), sdfHeaderReadback.get(), 1, &headerCopy);
    vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT,
                      VK_PIPELINE_STAGE_2_HOST_BIT, VK_ACCESS_2_HOST_READ_BIT);
    submitAndWait();
    checkCall(sdfHeaderReadback.invalidate(), "vkInvalidateMappedMemoryRanges (distance field)");
    const SdfHeader done = *sdfHeaderReadback.as<SdfHeader>();
    if (done.brickCount > std::uint32_t(h.brickCapacity)) {
      // More near cells than bricks: grow, and build the whole field again (the count of a
      // whole build is known now, so that one fits).
      if (attempt >= 3) fail("the distance field's brick count did not settle");
      h.brickCapacity = int(done.brickCount + done.brickCount / 8 + 1);
      h.listCapacity = std::max(h.listCapacity, h.brickCapacity * 16);
      continue;
    }
    if (done.listCount > std::uint32_t(h.listCapacity)) {
      if (attempt >= 3) fail("the distance field's triangle lists did not settle");
      h.listCapacity = int(done.listCount + done.listCount / 4 + 1);
      continue;
    }
    sdfListed = done.listCount;
    sdfAllocated = done.brickCount;
    sdfPasses = timer.results();
    sdfBuild.builds += 1;
    sdfBuild.update = update;
    sdfBuild.bricksBuilt = int(done.bricksBuilt);
    sdfBuild.cellsMs = sdfBuild.bricksMs = 0;
    for (const auto& [name, ms] : sdfPasses)
      (name == "sdf cells" ? sdfBuild.cellsMs : sdfBuild.bricksMs) += ms;
    sdfBuild.gpuMs = sdfBuild.cellsMs + sdfBuild.bricksMs;
    sdfBuild.triangles = int(tris.size());
    sdfBuild.cells = cellCount;
    sdfBuild.bricks = int(done.brickCount);
    sdfBuild.voxel = h.voxel;
    sdfBuild.bytes = sdfGrid.size() + sdfBricks.size() + sdfTriangles.size() + sdfLists.size();
    if (sdfBuild.builds == 1)
      logInfo("sdf tracer: distance field of " + std::to_string(tris.size()) + " triangles, " +
              std::to_string(h.cells.x) + "x" + std::to_string(h.cells.y) + "x" +
              std::to_string(h.cells.z) + " cells of " + std::to_string(PC_SDF_BRICK_CELLS) +
              "^3 voxels of " + std::to_string(h.voxel) + " m, " + std::to_string(done.brickCount) +
              " bricks, " + std::to_string(sdfBuild.bytes >> 20) + " MiB, built in " +
              std::to_string(sdfBuild.gpuMs) + " ms");
    break;
  }
  sdfLastTriangles = std::move(tris);
  sdfDirty = false;
}

void VulkanTracer::Impl::recordSdfTrace(int probeCount, int rayCount) {
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, tracePipeline.get());
  vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipelineLayout.get(), 0, 1,
                          &traceSet, 0, nullptr);
  const std::uint64_t rays = std::uint64_t(probeCount) * std::uint64_t(rayCount);
  dispatchRows((rays + PC_SDF_TRACE_THREADS - 1) / PC_SDF_TRACE_THREADS);
}

// One dispatch over every entry the round's shadow lists could hold; those past a list's end
// (its length is on the GPU) return at once.
void VulkanTracer::Impl::recordSdfShadows(int slots, std::uint64_t rayCount, int slotBase) {
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, shadowPipeline.get());
  vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipelineLayout.get(), 0, 1,
                          &traceSet, 0, nullptr);
  const TracePush push{0, slots, slotBase, 0};
  vkCmdPushConstants(cmd, pipelineLayout.get(), shaderStages, 0, sizeof push, &push);
  const std::uint64_t entries = std::uint64_t(slots) * rayCount;
  dispatchRows((entries + PC_SDF_TRACE_THREADS - 1) / PC_SDF_TRACE_THREADS);
}

Result<std::vector<GpuHit>> VulkanTracer::traceHits(Field& field, const UpdateRequest& request) {
  const std::size_t rays = request.probes.size() * std::size_t(field.settings.raysPerProbe);
  if (impl_->sliceProbes(request.probes.size(), field.settings.raysPerProbe) <
      request.probes.size())
    return Error{"vulkan tracer: traceHits: the request needs more than one pass"};
  auto traced = traceOnly(field, request);
  if (!traced) return traced.error();
  return readBack<GpuHit>(*impl_->ctx, impl_->hits, 0, rays);
}

const SdfBuildStats& VulkanTracer::sdfBuildStats() const { return impl_->sdfBuild; }

Result<SdfFieldCopy> VulkanTracer::readSdf() {
  if (!impl_->sdf)
    return Error{"vulkan tracer: readSdf: the ray-tracing backend has no distance field"};
  auto built = impl_->guarded("readSdf", [&] { impl_->ensureSdf(); });
  if (!built) return built.error();
  const Impl& m = *impl_;
  SdfFieldCopy out;
  out.header = m.sdfHeader;
  out.header.brickCount = std::uint32_t(m.sdfBuild.bricks);
  const SdfHeader& h = out.header;
  auto cells = readBack<SdfCell>(*m.ctx, m.sdfGrid, sizeof(SdfHeader),
                                 std::size_t(h.cells.x) * h.cells.y * h.cells.z);
  if (!cells) return cells.error();
  out.cells = std::move(cells).value();
  auto samples = readBack<SdfSample>(*m.ctx, m.sdfBricks, 0,
                                     std::size_t(m.sdfBuild.bricks) * PC_SDF_BRICK_SAMPLES);
  if (!samples) return samples.error();
  out.samples = std::move(samples).value();
  auto tris = readBack<SdfTriangle>(*m.ctx, m.sdfTriangles, 0, std::size_t(h.triangleCount));
  if (!tris) return tris.error();
  out.triangles = std::move(tris).value();
  return out;
}

}  // namespace pc
