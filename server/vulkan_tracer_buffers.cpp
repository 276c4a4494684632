// The Vulkan tracer's buffers: per-update capacity, the field on the GPU, the device-local
// mirrors of host-written inputs, descriptors, the snapshot of sliced updates, and writing an
// update's inputs.
#include <cstring>
#include <glm/gtc/packing.hpp>

#include "../common/split_sum_table.h"
#include "embree_tracer.h"  // probeRayDirections: both backends trace the same rays
#include "vulkan_tracer_impl.h"

namespace pc {

int VulkanTracer::Impl::shadowSlots() const {
  return pcShadowSlots(int(state.lights.size()), int(emissive.size() / sizeof(GpuEmissiveTriangle)),
                       options.emissiveSamples);
}

void VulkanTracer::Impl::ensureRequestCapacity(std::size_t probes, int rayCount, int slots) {
  probes = std::max<std::size_t>(probes, 1);
  const std::size_t perProbe = std::size_t(std::max(rayCount, 1));
  // Buffers grow to the most probes and rays per probe asked for; where both at once would
  // pass what a pass holds (after a change of rays per probe), they are made for this request
  // alone.
  const std::size_t passRays =
      vulkanPassRays(maxPassRays, slots, shadowMemoryBudget, maxBufferBytes);
  const bool fits = probes <= probeCapacity && perProbe <= rayCapacity;
  std::size_t capProbes = std::max(probes, probeCapacity),
              capRays = std::max(perProbe, rayCapacity);
  if (fits) {
    capProbes = probeCapacity;
    capRays = rayCapacity;
  } else if (capProbes * capRays > std::max(passRays, probes * perProbe)) {
    capProbes = probes;
    capRays = perProbe;
  }
  // A round holds as many slots as the memory budget allows for the buffers' rays (at least
  // one, at most every slot).
  const std::size_t records = capProbes * capRays;
  const std::size_t slotBytes = records * (sizeof(GpuShadowRay) + sizeof(GpuShadowLight));
  // Each per-ray buffer is bound whole, so none may pass the device's storage-buffer range: a
  // round's slots share one shadow-ray buffer, so they are held to it as to the budget.
  const std::size_t slotsInRange = maxBufferBytes / (records * sizeof(GpuShadowRay));
  roundSlots = std::max(
      1, std::min({slots, int(std::min<std::size_t>(shadowMemoryBudget / slotBytes, 1u << 20)),
                   int(std::min<std::size_t>(slotsInRange, 1u << 20))}));
  // Past the range even with one slot a round (or without slots): the update is refused, as
  // buffers it cannot do without are.
  const std::size_t widestRecord =
      std::max({sizeof(GpuHit), std::size_t(16), slots > 0 ? sizeof(GpuShadowRay) : 0});
  if (records * widestRecord > maxBufferBytes)
    failOverRange(
        "a pass of " + std::to_string(capProbes) + " probes x " + std::to_string(capRays) + " rays",
        records * widestRecord, maxBufferBytes, "use fewer rays per probe");
  if (fits && roundSlots <= slotCapacity && slots <= counterSlotCapacity) return;
  probeCapacity = capProbes;
  rayCapacity = capRays;
  slotCapacity = roundSlots;  // not more: the budget is for these rays
  counterSlotCapacity = std::max(slots, counterSlotCapacity);
  using vk::MemoryUsage;
  const std::size_t rayRecords = probeCapacity * rayCapacity;
  params = orFail(vk::Buffer::create(*ctx, sizeof(UpdateParams), kHostInput, MemoryUsage::Upload),
                  "params");
  rayDirs = orFail(vk::Buffer::create(*ctx, rayCapacity * 16, kHostInput, MemoryUsage::Upload),
                   "ray directions");
  requests = orFail(vk::Buffer::create(*ctx, probeCapacity * 8, kHostInput, MemoryUsage::Upload),
                    "requests");
  hits = orFail(
      vk::Buffer::create(*ctx, rayRecords * sizeof(GpuHit),
                         kStorage | VK_BUFFER_USAGE_TRANSFER_SRC_BIT, MemoryUsage::DeviceLocal),
      "hits");
  rays = orFail(vk::Buffer::create(*ctx, rayRecords * 16, kStorage, MemoryUsage::DeviceLocal),
                "ray results");
  const std::size_t maskWords =
      std::max<std::size_t>(rayRecords * std::size_t(pcShadowMaskWords(slotCapacity)), 1);
  shadowMask = orFail(vk::Buffer::create(*ctx, maskWords * 4, kStorage, MemoryUsage::DeviceLocal),
                      "shadow masks");
  const std::size_t slotRecords = std::max<std::size_t>(rayRecords * std::size_t(slotCapacity), 1);
  shadowLight = orFail(vk::Buffer::create(*ctx, slotRecords * sizeof(GpuShadowLight), kStorage,
                                          MemoryUsage::DeviceLocal),
                       "shadow light");
  shadowRays = orFail(vk::Buffer::create(*ctx, slotRecords * sizeof(GpuShadowRay), kStorage,
                                         MemoryUsage::DeviceLocal),
                      "shadow rays");
  changes = orFail(vk::Buffer::create(*ctx, probeCapacity * 4, kStorage, MemoryUsage::DeviceLocal),
                   "changes");
  const std::size_t counterBytes =
      std::size_t(PC_COUNTER_WORDS) * 4 * std::size_t(std::max(counterSlotCapacity, 1));
  counters = orFail(
      vk::Buffer::create(*ctx, counterBytes,
                         kStorage | VK_BUFFER_USAGE_TRANSFER_SRC_BIT |
                             VK_BUFFER_USAGE_TRANSFER_DST_BIT | VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT,
                         MemoryUsage::DeviceLocal),
      "counters");
  countersReadback = orFail(vk::Buffer::create(*ctx, counterBytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                               MemoryUsage::Readback),
                            "counter readback");
  countersInit = orFail(
      vk::Buffer::create(*ctx, counterBytes, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, MemoryUsage::Upload),
      "counter start");
  {
    std::vector<std::uint32_t> init(counterBytes / 4);
    for (std::size_t s = 0; s < init.size() / PC_COUNTER_WORDS; ++s) {
      init[s * PC_COUNTER_WORDS + 1] = 1;
      init[s * PC_COUNTER_WORDS + 2] = 1;
    }
    countersInit.write(init.data(), counterBytes);
  }
  // At most every ray feeds every texel: the bound of the tap table.
  const std::size_t tapCapacity =
      (2 * PC_TAP_TEXELS + PC_TAP_TEXELS * (rayCapacity + 3)) * sizeof(std::uint32_t);
  tapsUpload = orFail(
      vk::Buffer::create(*ctx, tapCapacity, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, MemoryUsage::Upload),
      "tap upload");
  taps = orFail(vk::Buffer::create(*ctx, tapCapacity, kStorage | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                   MemoryUsage::DeviceLocal),
                "taps");
  descriptorsDirty = true;
}

// Makes the field buffers match `field`'s layout; true when they were (re)created.
bool VulkanTracer::Impl::ensureFieldBuffers(const Field& field) {
  if (haveField && std::memcmp(&layoutDesc, &field.desc, sizeof(FieldDesc)) == 0) return false;
  using vk::MemoryUsage;
  const VkBufferUsageFlags rw =
      kStorage | VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
  auto bytes = [](const Atlas& a) { return a.texels.size() * sizeof(float); };
  brickTotal = 0;
  brickOffset.fill(0);
  for (int k = 0; k < field.cascadeCount(); ++k) {
    brickOffset[k] = brickTotal;
    brickTotal += pcBrickCount(field.cascade(k));
  }
  for (int k = field.cascadeCount(); k < PC_MAX_CASCADES; ++k) brickOffset[k] = brickTotal;
  const std::size_t bricks = std::size_t(std::max(brickTotal, 1));
  const std::size_t packedBytes =
      bricks * PC_PROBES_PER_BRICK * PC_PACKED_PROBE_FLOATS * sizeof(float);
  // Every field buffer is bound whole, so none may pass the storage-buffer range; the packed
  // bricks (every tile of the field with its borders, when all change) are the largest.
  const std::size_t widest = std::max(bytes(field.irradiance) / 3 * 4, packedBytes);
  if (widest > maxBufferBytes)
    failOverRange("a field of " + std::to_string(field.probes.size()) + " probes", widest,
                  maxBufferBytes, "use fewer probes (the sidecar's volumes)");
  fieldDesc = orFail(vk::Buffer::create(*ctx, sizeof(FieldDesc), kHostInput, MemoryUsage::Upload),
                     "field desc");
  // The irradiance atlas holds a vec4 per texel on the GPU (field_buffers.glsl).
  irradiance = orFail(
      vk::Buffer::create(*ctx, bytes(field.irradiance) / 3 * 4, rw, MemoryUsage::DeviceLocal),
      "irradiance");
  depth =
      orFail(vk::Buffer::create(*ctx, bytes(field.depth), rw, MemoryUsage::DeviceLocal), "depth");
  occlusion = orFail(vk::Buffer::create(*ctx, bytes(field.occlusion), rw, MemoryUsage::DeviceLocal),
                     "occlusion");
  const std::size_t recordBytes =
      std::max<std::size_t>(field.probes.size(), 1) * sizeof(GpuProbeRecord);
  records = orFail(vk::Buffer::create(*ctx, recordBytes, rw, MemoryUsage::DeviceLocal), "records");
  recordsReadback = orFail(vk::Buffer::create(*ctx, recordBytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                              MemoryUsage::Readback),
                           "record readback");
  brickFlags =
      orFail(vk::Buffer::create(*ctx, bricks * 4, rw, MemoryUsage::DeviceLocal), "brick flags");
  const std::size_t listBytes = (PC_BRICK_LIST_HEADER + bricks) * 4;
  brickList = orFail(vk::Buffer::create(*ctx, listBytes, rw | VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT,
                                        MemoryUsage::DeviceLocal),
                     "brick list");
  brickListReadback = orFail(
      vk::Buffer::create(*ctx, listBytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT, MemoryUsage::Readback),
      "brick list readback");
  // Shaders write the packed tiles straight into host memory: only changed bricks cross.
  packed = orFail(vk::Buffer::create(*ctx, packedBytes, kStorage, MemoryUsage::Readback),
                  "packed bricks");
  layoutDesc = field.desc;
  haveField = true;
  syncedField = nullptr;
  descriptorsDirty = true;
  return true;
}

void VulkanTracer::Impl::ensureMirrors() {
  for (auto [host, device] : mirrors()) {
    if (device->get() && device->size() == host->size()) continue;
    *device =
        orFail(vk::Buffer::create(*ctx, host->size(), kStorage | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                  vk::MemoryUsage::DeviceLocal),
               "input copy");
    descriptorsDirty = true;
  }
}

void VulkanTracer::Impl::recordMirrorCopies() {
  for (auto [host, device] : mirrors()) {
    const VkBufferCopy copy{0, 0, host->size()};
    if (copy.size > 0) vkCmdCopyBuffer(cmd, host->get(), device->get(), 1, &copy);
  }
  vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT,
                    traceStage | kComputeStage, VK_ACCESS_2_SHADER_STORAGE_READ_BIT);
}

void VulkanTracer::Impl::writeDescriptors() {
  ensureMirrors();
  if (!descriptorsDirty) return;
  std::array<VkDescriptorBufferInfo, PC_BINDING_COUNT> infos{};
  std::array<const vk::Buffer*, PC_BINDING_COUNT> buffers{};
  buffers[PC_BIND_PARAMS] = &paramsGpu;
  buffers[PC_BIND_FIELD] = &fieldDescGpu;
  buffers[PC_BIND_IRRADIANCE] = &irradiance;
  buffers[PC_BIND_DEPTH] = &depth;
  buffers[PC_BIND_OCCLUSION] = &occlusion;
  buffers[PC_BIND_PROBES] = &records;
  buffers[PC_BIND_REQUESTS] = &requestsGpu;
  buffers[PC_BIND_RAY_DIRS] = &rayDirsGpu;
  buffers[PC_BIND_RAYS] = &rays;
  buffers[PC_BIND_VERTICES] = &vertices;
  buffers[PC_BIND_INDICES] = &indices;
  buffers[PC_BIND_MESHES] = &meshes;
  buffers[PC_BIND_INSTANCES] = &instancesGpu;
  buffers[PC_BIND_MATERIALS] = &materialsGpu;
  buffers[PC_BIND_LIGHTS] = &lightsGpu;
  buffers[PC_BIND_EMISSIVE] = &emissiveGpu;
  buffers[PC_BIND_CHANGES] = &changes;
  buffers[PC_BIND_BRICK_FLAGS] = &brickFlags;
  buffers[PC_BIND_BRICK_LIST] = &brickList;
  buffers[PC_BIND_PACKED] = &packed;
  buffers[PC_BIND_COUNTERS] = &counters;
  buffers[PC_BIND_TAPS] = &taps;
  buffers[PC_BIND_HITS] = &hits;
  buffers[PC_BIND_SHADOW_MASK] = &shadowMask;
  buffers[PC_BIND_SHADOW_RAYS] = &shadowRays;
  buffers[PC_BIND_SHADOW_LIGHT] = &shadowLight;
  if (sdf) {
    buffers[PC_BIND_SDF_GRID] = &sdfGrid;
    buffers[PC_BIND_SDF_BRICKS] = &sdfBricks;
    buffers[PC_BIND_SDF_TRIANGLES] = &sdfTriangles;
    buffers[PC_BIND_SDF_OUTSIDE] = &sdfOutside;
    buffers[PC_BIND_SDF_LISTS] = &sdfLists;
  }
  std::vector<VkDescriptorImageInfo> images;
  for (std::size_t i = 0; i < textures.size(); ++i)
    images.push_back(
        {textureSamplers[i], textures[i].view(), VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL});
  VkAccelerationStructureKHR tlas = accel.topLevel();
  VkWriteDescriptorSetAccelerationStructureKHR asw{
      VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET_ACCELERATION_STRUCTURE_KHR};
  asw.accelerationStructureCount = 1;
  asw.pAccelerationStructures = &tlas;
  auto writeSet = [&](VkDescriptorSet dst) {
    std::vector<VkWriteDescriptorSet> writes;
    for (int b = 0; b < PC_BINDING_COUNT; ++b) {
      if (!buffers[b] || !buffers[b]->get()) continue;
      infos[b] = buffers[b]->descriptor();
      VkWriteDescriptorSet w{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
      w.dstSet = dst;
      w.dstBinding = std::uint32_t(b);
      w.descriptorCount = 1;
      w.descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
      w.pBufferInfo = &infos[b];
      writes.push_back(w);
    }
    if (!sdf) {
      VkWriteDescriptorSet w{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
      w.pNext = &asw;
      w.dstSet = dst;
      w.dstBinding = PC_BIND_TLAS;
      w.descriptorCount = 1;
      w.descriptorType = VK_DESCRIPTOR_TYPE_ACCELERATION_STRUCTURE_KHR;
      writes.push_back(w);
    }
    VkWriteDescriptorSet tw{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
    tw.dstSet = dst;
    tw.dstBinding = PC_BIND_TEXTURES;
    tw.descriptorCount = std::uint32_t(images.size());
    tw.descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
    tw.pImageInfo = images.data();
    writes.push_back(tw);
    vkUpdateDescriptorSets(ctx->device(), std::uint32_t(writes.size()), writes.data(), 0, nullptr);
  };
  writeSet(set);
  if (prevIrradiance.get()) {
    // The snapshot set: the field as the update found it, for the slices' trace and shading.
    buffers[PC_BIND_IRRADIANCE] = &prevIrradiance;
    buffers[PC_BIND_DEPTH] = &prevDepth;
    buffers[PC_BIND_OCCLUSION] = &prevOcclusion;
    buffers[PC_BIND_PROBES] = &prevRecords;
    writeSet(snapshotSet);
  }
  descriptorsDirty = false;
}

// Probes per slice of an update of `probes` probes at `rayCount` rays per probe: as few slices
// as the pass size allows, of even sizes (not full ones and a sliver).
std::size_t VulkanTracer::Impl::sliceProbes(std::size_t probes, int rayCount) const {
  const std::size_t rays =
      vulkanPassRays(maxPassRays, shadowSlots(), shadowMemoryBudget, maxBufferBytes);
  const std::size_t most = std::max<std::size_t>(1, rays / std::size_t(std::max(rayCount, 1)));
  const std::size_t slices = (probes + most - 1) / most;
  return slices <= 1 ? most : (probes + slices - 1) / slices;
}

// Snapshot buffers the size of the field's (made when an update first runs in slices).
void VulkanTracer::Impl::ensureSnapshot() {
  const VkBufferUsageFlags usage = kStorage | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
  for (auto [live, copy] : snapshots()) {
    if (copy->get() && copy->size() == live->size()) continue;
    *copy = orFail(vk::Buffer::create(*ctx, live->size(), usage, vk::MemoryUsage::DeviceLocal),
                   "field snapshot");
    descriptorsDirty = true;
  }
}

void VulkanTracer::Impl::recordSnapshot() {
  // After any upload of host edits into the field (recordFieldSync).
  vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT,
                    VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_READ_BIT);
  for (auto [live, copy] : snapshots()) {
    const VkBufferCopy region{0, 0, live->size()};
    vkCmdCopyBuffer(cmd, live->get(), copy->get(), 1, &region);
  }
  vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT,
                    traceStage | kComputeStage, kShaderRW);
}

void VulkanTracer::Impl::writeUpdateInputs(const Field& field, const UpdateRequest& request,
                                           std::size_t first, std::size_t count, bool blendTaps,
                                           bool sliced) {
  const int rayCount = field.settings.raysPerProbe;
  const std::size_t n = count;
  ensureRequestCapacity(n, rayCount, shadowSlots());
  ensureFieldBuffers(field);
  if (sliced) ensureSnapshot();
  writeDescriptors();
  traceSet = sliced ? snapshotSet : set;

  // The same directions as the Embree backend, computed once on the host.
  const std::vector<glm::vec3> dirs = probeRayDirections(rayCount, request.rotationSeed);
  auto* d = rayDirs.as<glm::vec4>();
  for (int i = 0; i < rayCount; ++i) d[i] = glm::vec4(dirs[i], 0.0f);
  if (blendTaps) {
    // The CPU's taps for these directions, laid out for the blend shader (gpu_trace.h); the
    // occlusion taps are the irradiance taps (same tile size, same lobe).
    const BlendTaps bt = BlendTaps::build(dirs.data(), rayCount, field.settings.distanceExponent);
    auto* out = tapsUpload.as<std::uint32_t>();
    std::uint32_t texel = 0, next = 2 * PC_TAP_TEXELS;
    for (const TexelTaps* tt : {&bt.irradiance, &bt.depth}) {
      const std::uint32_t texels = std::uint32_t(tt->begin.size() - 1);
      std::uint32_t most = 0;
      for (std::uint32_t t = 0; t < texels; ++t)
        most = std::max(most, tt->begin[t + 1] - tt->begin[t]);
      const std::uint32_t blocks = (most + 3) / 4;
      std::memset(out + next, 0, std::size_t(blocks) * 4 * texels * sizeof(std::uint32_t));
      for (std::uint32_t t = 0; t < texels; ++t) {
        const std::uint32_t first = tt->begin[t], count = tt->begin[t + 1] - first;
        out[2 * (texel + t)] = count;
        out[2 * (texel + t) + 1] = next + 4 * t;
        for (std::uint32_t j = 0; j < count; ++j) {
          // Exact: the CPU's weights are float16 values already.
          const std::uint32_t half = glm::packHalf1x16(tt->weight[first + j]);
          out[next + (j / 4) * 4 * texels + 4 * t + j % 4] =
              std::uint32_t(tt->ray[first + j]) | half << 16;
        }
      }
      texel += texels;
      next += blocks * 4 * texels;
    }
    tapBytes = std::size_t(next) * sizeof(std::uint32_t);
  }
  auto* r = requests.as<glm::ivec2>();
  for (std::size_t i = 0; i < n; ++i)
    r[i] = glm::ivec2(request.probes[first + i].cascade, request.probes[first + i].slot);

  UpdateParams p{};
  p.skyZenith = scene->sky.zenith;
  p.skyHorizon = scene->sky.horizon;
  p.skyGround = scene->sky.ground;
  p.rayCount = rayCount;
  p.probeCount = int(n);
  p.requestBase = int(first);
  p.shading = request.shading;
  p.lightCount = int(state.lights.size());
  p.emissiveCount = int(emissive.size() / sizeof(GpuEmissiveTriangle));
  p.emissiveSamples = options.emissiveSamples;
  p.seed = request.rotationSeed;
  p.changeThreshold = request.changeThreshold;
  p.brickTotal = brickTotal;
  p.shadowSlots = shadowSlots();
  p.shadowRouletteShare = options.shadowRouletteShare;
  p.roundSlots = roundSlots;
  p.lightsResolved = pcShadowRounds(p.shadowSlots, roundSlots) > 1 ? 1 : 0;
  p.cascadeBrickOffset = glm::ivec4(brickOffset[0], brickOffset[1], brickOffset[2], brickOffset[3]);
  const SplitSumTable& table = splitSumTable();
  static_assert(sizeof p.splitSum == sizeof table);
  std::memcpy(p.splitSum, table.data(), sizeof table);
  params.write(&p, sizeof p);

  // The blend reads the lobe exponent from the settings, as the CPU's blendProbe does.
  FieldDesc desc = field.desc;
  desc.distanceExponent = field.settings.distanceExponent;
  fieldDesc.write(&desc, sizeof desc);
}

}  // namespace pc
