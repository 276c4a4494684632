// The Vulkan tracer's occlusion from layered depth maps (VulkanTracerOptions::ldmOcclusion,
// ldm_occlusion.h): after an update, the updated probes' occlusion tiles are replaced by their
// LDM occlusion at their (relocated) positions, in the host field and in the GPU's atlas, so
// that a later brick readback brings back the same values.
#include "vulkan_tracer_impl.h"

namespace pc {

void VulkanTracer::Impl::applyLdmOcclusion(Field& field, const UpdateRequest& request,
                                           UpdateStats& stats) {
  if (request.probes.empty()) return;
  const auto t0 = Clock::now();
  glm::vec3 lo, hi;
  ldmFieldBounds(field, lo, hi);
  // Rebuilt where the field's bounds moved (a scrolled cascade) or the instances did.
  if (!ldmBuilt || lo != ldmLo || hi != ldmHi || state.instanceTransforms != ldmTransforms) {
    const std::vector<LdmTriangle> tris = ldmSceneTriangles(*scene, state, lo, hi);
    if (Status s = ldm->build(tris, lo, hi); !s) fail("ldm build: " + s.error().message);
    ldmBuilt = true;
    ldmLo = lo, ldmHi = hi;
    ldmTransforms = state.instanceTransforms;
    stats.gpuPasses.emplace_back("ldm build (wall)", msSince(t0));
  }
  const auto t1 = Clock::now();
  const std::vector<glm::vec3> positions = ldmProbePositions(field, request.probes);
  auto tiles = ldm->occlusion(positions, field.desc.occlusionDistance);
  if (!tiles) fail("ldm occlusion: " + tiles.error().message);

  // Bricks whose tiles change beyond the request's threshold are marked changed, in this
  // update's version (the one it made, or the next where it changed nothing).
  constexpr int n = PC_OCCLUSION_TEXELS, side = n + 2;
  const float threshold = std::max(request.changeThreshold, 1e-4f);
  const std::uint64_t version = stats.bricksChanged > 0 ? field.version : field.version + 1;
  bool changed = false;
  for (std::size_t i = 0; i < request.probes.size(); ++i) {
    const ProbeRef& p = request.probes[i];
    if (field.probe(p.cascade, p.slot).state == PC_PROBE_INSIDE) continue;
    const glm::ivec2 o = pcAtlasTileOrigin(field.cascade(p.cascade), p.slot, side);
    float delta = 0.0f;
    for (int t = 0; t < n * n; ++t)
      delta = std::max(delta, std::abs(field.occlusion.at(o.x + 1 + t % n, o.y + 1 + t / n)[0] -
                                       (*tiles)[i * n * n + std::size_t(t)]));
    if (delta > threshold) {
      field.brickVersions[std::size_t(p.cascade)][std::size_t(p.slot / PC_PROBES_PER_BRICK)] =
          version;
      changed = true;
    }
  }
  writeLdmOcclusion(field, request.probes, *tiles);
  if (changed) field.version = version;

  // The same tiles (interior and border) into the GPU's atlas: one copy region per tile row.
  std::vector<float> rows;
  std::vector<VkBufferCopy> regions;
  rows.reserve(request.probes.size() * side * side);
  for (const ProbeRef& p : request.probes) {
    if (field.probe(p.cascade, p.slot).state == PC_PROBE_INSIDE) continue;
    const glm::ivec2 o = pcAtlasTileOrigin(field.cascade(p.cascade), p.slot, side);
    for (int y = 0; y < side; ++y) {
      const float* src = field.occlusion.at(o.x, o.y + y);
      const VkDeviceSize dst =
          (VkDeviceSize(o.y + y) * VkDeviceSize(field.occlusion.width) + VkDeviceSize(o.x)) * 4;
      regions.push_back({rows.size() * 4, dst, side * 4});
      rows.insert(rows.end(), src, src + side);
    }
  }
  if (!regions.empty()) {
    vk::Buffer staging =
        orFail(vk::Buffer::create(*ctx, rows.size() * 4, VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                                  vk::MemoryUsage::Upload),
               "ldm occlusion staging");
    staging.write(rows.data(), rows.size() * 4);
    Status copied = commandPool.submitAndWait([&](VkCommandBuffer c) {
      vkCmdCopyBuffer(c, staging.get(), occlusion.get(), std::uint32_t(regions.size()),
                      regions.data());
    });
    if (!copied) fail("ldm occlusion upload: " + copied.error().message);
  }
  // The GPU holds what the host does.
  syncedVersion = field.version;
  stats.gpuPasses.emplace_back("ldm occlusion (wall)", msSince(t1));
  stats.totalMs += msSince(t0);
}

const LdmBuildStats* VulkanTracer::ldmBuildStats() const {
  return impl_->ldm && impl_->ldmBuilt ? &impl_->ldm->stats() : nullptr;
}

}  // namespace pc
