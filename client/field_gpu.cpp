#include "field_gpu.h"

#include <algorithm>
#include <cstring>
#include <glm/gtc/packing.hpp>

#include "shaders/interop/client_frame.h"
#include "vk_util.h"

namespace pc::client {
namespace {

constexpr VkFormat kIrradianceFormat = VK_FORMAT_R16G16B16A16_SFLOAT;
constexpr VkFormat kDepthFormat = VK_FORMAT_R32G32_SFLOAT;  // mean square needs the range
constexpr VkFormat kOcclusionFormat = VK_FORMAT_R16_SFLOAT;
constexpr std::size_t kProbeRecordBytes = 16;  // vec4: offset xyz, state w
constexpr int kBrick = gpu::PC_PROBES_PER_BRICK;

// Interior texels per probe and bytes per texel of the "new value" buffers (std430 vec4, vec2,
// float arrays).
constexpr std::size_t kIrradianceTexels = gpu::PC_IRRADIANCE_TEXELS * gpu::PC_IRRADIANCE_TEXELS;
constexpr std::size_t kDepthTexels = gpu::PC_DEPTH_TEXELS * gpu::PC_DEPTH_TEXELS;
constexpr std::size_t kOcclusionTexels = gpu::PC_OCCLUSION_TEXELS * gpu::PC_OCCLUSION_TEXELS;
constexpr std::size_t kIrradianceBytes = kIrradianceTexels * 16;
constexpr std::size_t kDepthBytes = kDepthTexels * 8;
constexpr std::size_t kOcclusionBytes = kOcclusionTexels * 4;

constexpr VkPipelineStageFlags2 kShaders =
    VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT;

// Copies the interiors of one brick's tiles of `atlas` into `out` (the layout of a "new
// value" buffer: per probe n*n texels of `stride` floats, channels first).
void stageInteriors(const Atlas& atlas, const gpu::CascadeDesc& c, int brick, int n, int stride,
                    float* out) {
  for (int p = 0; p < kBrick; ++p) {
    const int slot = brick * kBrick + p;
    const glm::ivec2 origin = gpu::pcAtlasTileOrigin(c, slot, n + 2);
    for (int y = 0; y < n; ++y) {
      for (int x = 0; x < n; ++x) {
        const float* src = atlas.at(origin.x + 1 + x, origin.y + 1 + y);
        float* dst = out + (std::size_t(p) * n * n + std::size_t(y) * n + x) * stride;
        std::memcpy(dst, src, std::size_t(atlas.channels) * sizeof(float));
      }
    }
  }
}

}  // namespace

std::size_t brickUploadBytes() {
  return kBrick * (kIrradianceBytes + kDepthBytes + kOcclusionBytes + kProbeRecordBytes);
}

Result<FieldGpu> FieldGpu::create(const vk::Context& ctx, const std::optional<gpu::FieldDesc>& desc,
                                  int frameSlots, int bricksPerFrame, double fadeSeconds) {
  FieldGpu f;
  f.ctx_ = &ctx;
  f.present_ = desc.has_value() && desc->cascadeCount > 0;
  f.fieldDesc_ = f.present_ ? *desc : gpu::FieldDesc{};
  f.bricksPerFrame_ = std::max(1, bricksPerFrame);
  f.fadeSeconds_ = std::max(0.0, fadeSeconds);
  const std::uint32_t rows = f.present_ ? std::uint32_t(f.fieldDesc_.atlasTileRows) : 0;
  auto atlas = [&](VkFormat format, int tileSize) {
    vk::ImageDesc d;
    d.format = format;
    d.width = f.present_ ? std::uint32_t(gpu::PC_ATLAS_TILES_PER_ROW * tileSize) : 1;
    d.height = f.present_ ? rows * std::uint32_t(tileSize) : 1;
    d.usage = VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_STORAGE_BIT |
              VK_IMAGE_USAGE_TRANSFER_DST_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT;
    return vk::Image::create(ctx, d);
  };
  auto irr = atlas(kIrradianceFormat, gpu::PC_IRRADIANCE_TEXELS + 2);
  if (!irr) return irr.error();
  auto dep = atlas(kDepthFormat, gpu::PC_DEPTH_TEXELS + 2);
  if (!dep) return dep.error();
  auto occ = atlas(kOcclusionFormat, gpu::PC_OCCLUSION_TEXELS + 2);
  if (!occ) return occ.error();
  f.irradiance_ = std::move(irr).value();
  f.depth_ = std::move(dep).value();
  f.occlusion_ = std::move(occ).value();

  int bricks = 0;
  for (int k = 0; k < f.fieldDesc_.cascadeCount && f.present_; ++k) {
    const int count = gpu::pcBrickCount(f.fieldDesc_.cascades[k]);
    f.held_.emplace_back(std::size_t(count), false);
    bricks += count;
  }
  const std::size_t slots =
      std::max<std::size_t>(1, f.present_ ? std::size_t(f.fieldDesc_.probeCount) : 1);
  auto deviceBuffer = [&](std::size_t bytes, vk::Buffer& out) -> Status {
    auto b = vk::Buffer::create(
        ctx, bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
        vk::MemoryUsage::DeviceLocal);
    if (!b) return b.error();
    out = std::move(b).value();
    return Status::success();
  };
  for (Status s : {deviceBuffer(slots * kProbeRecordBytes, f.probes_),
                   deviceBuffer(slots * kIrradianceBytes, f.irradianceNew_),
                   deviceBuffer(slots * kDepthBytes, f.depthNew_),
                   deviceBuffer(slots * kOcclusionBytes, f.occlusionNew_)}) {
    if (!s) return s.error();
  }
  // Written again in a frame's commands when cascades move (recordPlaces).
  auto descBuffer =
      vk::Buffer::create(ctx, sizeof(gpu::FieldDesc),
                         VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                         vk::MemoryUsage::Upload);
  if (!descBuffer) return descBuffer.error();
  f.desc_ = std::move(descBuffer).value();
  f.desc_.write(&f.fieldDesc_, sizeof f.fieldDesc_);

  // Every brick may be fading at once: the write list has room for all of them.
  f.maxWrites_ = std::max(1, bricks);
  const std::size_t stagingBytes = std::size_t(f.bricksPerFrame_) * brickUploadBytes();
  for (int i = 0; i < frameSlots; ++i) {
    auto s = vk::Buffer::create(ctx, stagingBytes, VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                                vk::MemoryUsage::Upload);
    if (!s) return s.error();
    f.staging_.push_back(std::move(s).value());
    auto list = vk::Buffer::create(ctx, std::size_t(f.maxWrites_) * sizeof(gpu::FieldWrite),
                                   VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, vk::MemoryUsage::Upload);
    if (!list) return list.error();
    f.writeLists_.push_back(std::move(list).value());
  }
  Status pass = f.createWritePass(frameSlots);
  if (!pass) return pass.error();

  // Every probe starts uninitialized (never sampled) and every texel at zero, until its brick
  // arrives. The atlases stay in GENERAL: sampled by the frame, written by the write pass.
  Status cleared = ctx.submitAndWait([&](VkCommandBuffer cmd) {
    const VkImage images[3] = {f.irradiance_.get(), f.depth_.get(), f.occlusion_.get()};
    for (VkImage image : images) {
      imageBarriers(cmd, {{image, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
                           VK_IMAGE_LAYOUT_GENERAL, VK_PIPELINE_STAGE_2_NONE, VK_ACCESS_2_NONE,
                           VK_PIPELINE_STAGE_2_CLEAR_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT}});
    }
    const VkClearColorValue zero{};
    const VkImageSubresourceRange all{VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
    for (VkImage image : images)
      vkCmdClearColorImage(cmd, image, VK_IMAGE_LAYOUT_GENERAL, &zero, 1, &all);
    // Every float of every record becomes 3.0f: the state (w) reads PC_PROBE_UNINITIALIZED,
    // and the offsets of such probes are never read.
    static_assert(gpu::PC_PROBE_UNINITIALIZED == 3);
    vkCmdFillBuffer(cmd, f.probes_.get(), 0, VK_WHOLE_SIZE, 0x40400000u);
    // All transfer stages: the image clears run in the clear stage, and a buffer fill is a
    // "transfer" operation of no named stage (the validation layer places it in the copy stage).
    vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_ALL_TRANSFER_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT,
                      kShaders,
                      VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_SAMPLED_READ_BIT |
                          VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT);
  });
  if (!cleared) return cleared.error();
  return f;
}

Status FieldGpu::createWritePass(int frameSlots) {
  const VkDevice device = ctx_->device();
  VkSamplerCreateInfo si{VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO};
  si.magFilter = si.minFilter = VK_FILTER_NEAREST;
  si.addressModeU = si.addressModeV = si.addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE;
  VkSampler sampler = VK_NULL_HANDLE;
  PC_VK_TRY(vkCreateSampler(device, &si, nullptr, &sampler));
  nearest_ = vk::UniqueSampler(device, sampler);

  std::vector<VkDescriptorSetLayoutBinding> bindings;
  auto bind = [&](int binding, VkDescriptorType type) {
    VkDescriptorSetLayoutBinding b{};
    b.binding = std::uint32_t(binding);
    b.descriptorType = type;
    b.descriptorCount = 1;
    b.stageFlags = VK_SHADER_STAGE_COMPUTE_BIT;
    bindings.push_back(b);
  };
  const VkDescriptorType ssbo = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
  const VkDescriptorType sampled = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
  const VkDescriptorType storage = VK_DESCRIPTOR_TYPE_STORAGE_IMAGE;
  bind(gpu::PC_FW_BIND_FIELD_DESC, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER);
  bind(gpu::PC_FW_BIND_WRITES, ssbo);
  bind(gpu::PC_FW_BIND_IRRADIANCE_NEW, ssbo);
  bind(gpu::PC_FW_BIND_DEPTH_NEW, ssbo);
  bind(gpu::PC_FW_BIND_OCCLUSION_NEW, ssbo);
  bind(gpu::PC_FW_BIND_IRRADIANCE_HELD, sampled);
  bind(gpu::PC_FW_BIND_DEPTH_HELD, sampled);
  bind(gpu::PC_FW_BIND_OCCLUSION_HELD, sampled);
  bind(gpu::PC_FW_BIND_IRRADIANCE_OUT, storage);
  bind(gpu::PC_FW_BIND_DEPTH_OUT, storage);
  bind(gpu::PC_FW_BIND_OCCLUSION_OUT, storage);
  auto dsl = vk::createDescriptorSetLayout(*ctx_, bindings);
  if (!dsl) return dsl.error();
  setLayout_ = std::move(dsl).value();
  const VkDescriptorSetLayout setLayout = setLayout_.get();
  auto layout = vk::createPipelineLayout(*ctx_, setLayout);
  if (!layout) return layout.error();
  pipelineLayout_ = std::move(layout).value();
  const VkPipelineLayout pipelineLayout = pipelineLayout_.get();

  const std::uint32_t n = std::uint32_t(frameSlots);
  const VkDescriptorPoolSize sizes[] = {
      {VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, n}, {ssbo, 4 * n}, {sampled, 3 * n}, {storage, 3 * n}};
  VkDescriptorPoolCreateInfo pi{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  pi.maxSets = n;
  pi.poolSizeCount = 4;
  pi.pPoolSizes = sizes;
  VkDescriptorPool pool = VK_NULL_HANDLE;
  PC_VK_TRY(vkCreateDescriptorPool(device, &pi, nullptr, &pool));
  descriptorPool_ = vk::UniqueDescriptorPool(device, pool);

  const VkDescriptorBufferInfo descInfo = desc_.descriptor(), irrNew = irradianceNew_.descriptor(),
                               depNew = depthNew_.descriptor(), occNew = occlusionNew_.descriptor();
  const VkImageLayout general = VK_IMAGE_LAYOUT_GENERAL;
  const VkDescriptorImageInfo held[3] = {{sampler, irradiance_.view(), general},
                                         {sampler, depth_.view(), general},
                                         {sampler, occlusion_.view(), general}};
  const VkDescriptorImageInfo out[3] = {{VK_NULL_HANDLE, irradiance_.view(), general},
                                        {VK_NULL_HANDLE, depth_.view(), general},
                                        {VK_NULL_HANDLE, occlusion_.view(), general}};
  for (std::uint32_t i = 0; i < n; ++i) {
    VkDescriptorSetAllocateInfo ai{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
    ai.descriptorPool = pool;
    ai.descriptorSetCount = 1;
    ai.pSetLayouts = &setLayout;
    VkDescriptorSet set = VK_NULL_HANDLE;
    PC_VK_TRY(vkAllocateDescriptorSets(device, &ai, &set));
    sets_.push_back(set);
    const VkDescriptorBufferInfo list = writeLists_[i].descriptor();
    std::vector<VkWriteDescriptorSet> writes;
    auto write = [&](int binding, VkDescriptorType type, const VkDescriptorBufferInfo* buffer,
                     const VkDescriptorImageInfo* image) {
      VkWriteDescriptorSet w{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
      w.dstSet = set;
      w.dstBinding = std::uint32_t(binding);
      w.descriptorCount = 1;
      w.descriptorType = type;
      w.pBufferInfo = buffer;
      w.pImageInfo = image;
      writes.push_back(w);
    };
    write(gpu::PC_FW_BIND_FIELD_DESC, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, &descInfo, nullptr);
    write(gpu::PC_FW_BIND_WRITES, ssbo, &list, nullptr);
    write(gpu::PC_FW_BIND_IRRADIANCE_NEW, ssbo, &irrNew, nullptr);
    write(gpu::PC_FW_BIND_DEPTH_NEW, ssbo, &depNew, nullptr);
    write(gpu::PC_FW_BIND_OCCLUSION_NEW, ssbo, &occNew, nullptr);
    write(gpu::PC_FW_BIND_IRRADIANCE_HELD, sampled, nullptr, &held[0]);
    write(gpu::PC_FW_BIND_DEPTH_HELD, sampled, nullptr, &held[1]);
    write(gpu::PC_FW_BIND_OCCLUSION_HELD, sampled, nullptr, &held[2]);
    write(gpu::PC_FW_BIND_IRRADIANCE_OUT, storage, nullptr, &out[0]);
    write(gpu::PC_FW_BIND_DEPTH_OUT, storage, nullptr, &out[1]);
    write(gpu::PC_FW_BIND_OCCLUSION_OUT, storage, nullptr, &out[2]);
    vkUpdateDescriptorSets(device, std::uint32_t(writes.size()), writes.data(), 0, nullptr);
  }

  auto shader = vk::loadShader(*ctx_, "client_field_write.comp.spv");
  if (!shader) return shader.error();
  VkComputePipelineCreateInfo ci{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
  ci.stage = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
  ci.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
  ci.stage.module = shader->get();
  ci.stage.pName = "main";
  ci.layout = pipelineLayout;
  VkPipeline pipeline = VK_NULL_HANDLE;
  PC_VK_TRY(vkCreateComputePipelines(device, VK_NULL_HANDLE, 1, &ci, nullptr, &pipeline));
  writePipeline_ = vk::UniquePipeline(device, pipeline);
  return Status::success();
}

VkDescriptorImageInfo FieldGpu::irradiance(VkSampler s) const {
  return {s, irradiance_.view(), VK_IMAGE_LAYOUT_GENERAL};
}
VkDescriptorImageInfo FieldGpu::depth(VkSampler s) const {
  return {s, depth_.view(), VK_IMAGE_LAYOUT_GENERAL};
}
VkDescriptorImageInfo FieldGpu::occlusion(VkSampler s) const {
  return {s, occlusion_.view(), VK_IMAGE_LAYOUT_GENERAL};
}

void FieldGpu::recordPlaces(VkCommandBuffer cmd, FieldMirror& mirror) {
  std::vector<std::pair<std::size_t, std::vector<float>>> records;  // (first slot, vec4s)
  mirror.read([&](const Field& field) {
    if (field.desc.cascadeCount != fieldDesc_.cascadeCount) return;
    for (int k = 0; k < field.desc.cascadeCount; ++k) {
      gpu::CascadeDesc& c = fieldDesc_.cascades[k];
      const gpu::CascadeDesc& now = field.desc.cascades[k];
      if (c.origin == now.origin && c.scroll == now.scroll) continue;
      c.origin = now.origin;
      c.scroll = now.scroll;
      std::vector<float> vec4s;
      vec4s.reserve(std::size_t(gpu::pcSlotCount(c)) * 4);
      for (int s = 0; s < gpu::pcSlotCount(c); ++s) {
        const ProbeRecord& r = field.probe(k, s);
        vec4s.insert(vec4s.end(), {r.offset.x, r.offset.y, r.offset.z, float(r.state)});
      }
      records.emplace_back(std::size_t(c.firstProbe), std::move(vec4s));
    }
  });
  if (records.empty()) return;
  // Earlier frames' reads finish before the places and records change under them.
  vk::memoryBarrier(cmd, kShaders, VK_ACCESS_2_NONE, VK_PIPELINE_STAGE_2_COPY_BIT,
                    VK_ACCESS_2_TRANSFER_WRITE_BIT);
  vkCmdUpdateBuffer(cmd, desc_.get(), 0, sizeof fieldDesc_, &fieldDesc_);
  // vkCmdUpdateBuffer takes at most 65,536 bytes a call.
  constexpr std::size_t kChunk = 65536;
  for (const auto& [first, vec4s] : records) {
    const std::size_t bytes = vec4s.size() * sizeof(float);
    for (std::size_t at = 0; at < bytes; at += kChunk) {
      vkCmdUpdateBuffer(cmd, probes_.get(), first * kProbeRecordBytes + at,
                        std::min(kChunk, bytes - at),
                        reinterpret_cast<const std::uint8_t*>(vec4s.data()) + at);
    }
  }
  vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT, kShaders,
                    VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_UNIFORM_READ_BIT);
}

FieldUploadStats FieldGpu::recordUploads(VkCommandBuffer cmd, int slot, FieldMirror& mirror,
                                         double now) {
  if (!present_) return {};
  if (const std::uint64_t serial = mirror.placesSerial(); serial != placesSerial_) {
    recordPlaces(cmd, mirror);
    placesSerial_ = serial;
  }
  return record(cmd, slot, mirror, mirror.takePending(bricksPerFrame_), now, fadeSeconds_ > 0);
}

FieldUploadStats FieldGpu::record(VkCommandBuffer cmd, int slot, FieldMirror& mirror,
                                  const std::vector<BrickId>& bricks, double now, bool fade) {
  FieldUploadStats stats;
  // ---- stage the interiors and probe records of the new bricks ----
  std::vector<VkBufferCopy> irrCopies, depCopies, occCopies, probeCopies;
  std::vector<BrickId> arrived;  // staged now, in order
  auto* staging = static_cast<std::uint8_t*>(staging_[std::size_t(slot)].mapped());
  std::size_t offset = 0;
  mirror.read([&](const Field& field) {
    for (const BrickId& id : bricks) {
      if (id.cascade >= field.desc.cascadeCount || std::size_t(id.cascade) >= held_.size() ||
          std::size_t(id.brick) >= held_[std::size_t(id.cascade)].size())
        continue;  // not in the layout these atlases were made for
      const gpu::CascadeDesc& c = field.desc.cascades[id.cascade];
      const std::size_t first = std::size_t(c.firstProbe) + std::size_t(id.brick) * kBrick;
      auto stage = [&](const Atlas& atlas, int n, int stride, std::size_t probeBytes,
                       std::vector<VkBufferCopy>& copies) {
        std::memset(staging + offset, 0, kBrick * probeBytes);
        stageInteriors(atlas, c, id.brick, n, stride, reinterpret_cast<float*>(staging + offset));
        copies.push_back({offset, first * probeBytes, kBrick * probeBytes});
        offset += kBrick * probeBytes;
      };
      stage(field.irradiance, gpu::PC_IRRADIANCE_TEXELS, 4, kIrradianceBytes, irrCopies);
      stage(field.depth, gpu::PC_DEPTH_TEXELS, 2, kDepthBytes, depCopies);
      stage(field.occlusion, gpu::PC_OCCLUSION_TEXELS, 1, kOcclusionBytes, occCopies);
      for (int p = 0; p < kBrick; ++p) {
        const ProbeRecord& r = field.probes[first + std::size_t(p)];
        const float record[4] = {r.offset.x, r.offset.y, r.offset.z, float(r.state)};
        std::memcpy(staging + offset + std::size_t(p) * kProbeRecordBytes, record, sizeof record);
      }
      probeCopies.push_back({offset, first * kProbeRecordBytes, kBrick * kProbeRecordBytes});
      offset += kBrick * kProbeRecordBytes;
      arrived.push_back(id);
    }
  });
  stats.bricks = int(arrived.size());
  stats.bytes = offset;

  // ---- the write list: new bricks (exact, or starting a fade) and running fades ----
  std::vector<gpu::FieldWrite> writes;
  for (const BrickId& id : arrived) {
    auto held = held_[std::size_t(id.cascade)].begin() + id.brick;
    // A newer version mid-fade restarts the fade from what is shown now.
    std::erase_if(fades_, [&](const Fade& f) { return f.id == id; });
    if (fade && *held) {
      fades_.push_back({id, now, 0.0});
    } else {
      writes.push_back({id.cascade, id.brick, 1.0f, 0});
    }
    *held = true;
  }
  for (Fade& f : fades_) {
    const double t = std::clamp((now - f.start) / fadeSeconds_, f.applied, 1.0);
    if (t <= f.applied) continue;
    // The atlas holds old + applied * (new - old); moving it (t - applied) / (1 - applied) of
    // the remaining way gives old + t * (new - old).
    const double weight = t >= 1.0 ? 1.0 : (t - f.applied) / (1.0 - f.applied);
    writes.push_back({f.id.cascade, f.id.brick, float(weight), 0});
    f.applied = t;
  }
  std::erase_if(fades_, [](const Fade& f) { return f.applied >= 1.0; });
  stats.fading = int(fades_.size());
  if (writes.empty() && arrived.empty()) return stats;
  writes.resize(std::min(writes.size(), std::size_t(maxWrites_)));

  // ---- record: copies into the "new value" buffers, then the write pass ----
  const VkBuffer src = staging_[std::size_t(slot)].get();
  if (!arrived.empty()) {
    // Earlier frames' reads of these buffers finish before the copies overwrite them.
    vk::memoryBarrier(cmd, kShaders, VK_ACCESS_2_NONE, VK_PIPELINE_STAGE_2_COPY_BIT,
                      VK_ACCESS_2_TRANSFER_WRITE_BIT);
    vkCmdCopyBuffer(cmd, src, irradianceNew_.get(), std::uint32_t(irrCopies.size()),
                    irrCopies.data());
    vkCmdCopyBuffer(cmd, src, depthNew_.get(), std::uint32_t(depCopies.size()), depCopies.data());
    vkCmdCopyBuffer(cmd, src, occlusionNew_.get(), std::uint32_t(occCopies.size()),
                    occCopies.data());
    vkCmdCopyBuffer(cmd, src, probes_.get(), std::uint32_t(probeCopies.size()), probeCopies.data());
    vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT, kShaders,
                      VK_ACCESS_2_SHADER_STORAGE_READ_BIT);
  }
  if (!writes.empty()) {
    writeLists_[std::size_t(slot)].write(writes.data(), writes.size() * sizeof(gpu::FieldWrite));
    // Earlier frames' sampling of the atlases finishes before the pass overwrites texels.
    vk::memoryBarrier(cmd, kShaders, VK_ACCESS_2_NONE, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                      VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT);
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, writePipeline_.get());
    const VkDescriptorSet set = sets_[std::size_t(slot)];
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipelineLayout_.get(), 0, 1, &set,
                            0, nullptr);
    vkCmdDispatch(cmd, std::uint32_t(writes.size()), kBrick, 1);
    vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                      VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT, kShaders,
                      VK_ACCESS_2_SHADER_SAMPLED_READ_BIT);
  }
  return stats;
}

Status FieldGpu::uploadAll(FieldMirror& mirror) {
  while (present_ && mirror.age(0.0).pendingBricks > 0) {
    Status s = ctx_->submitAndWait([&](VkCommandBuffer cmd) {
      record(cmd, 0, mirror, mirror.takePending(bricksPerFrame_), 0.0, false);
    });
    if (!s) return s;
  }
  return Status::success();
}

Result<FieldAtlases> FieldGpu::download() const {
  PC_VK_TRY(ctx_->waitIdle());
  const vk::Image* images[3] = {&irradiance_, &depth_, &occlusion_};
  const int channels[3] = {3, 2, 1};
  const std::size_t texelBytes[3] = {8, 8, 2};
  std::size_t total = 0;
  std::size_t offsets[3];
  for (int i = 0; i < 3; ++i) {
    offsets[i] = total;
    total += std::size_t(images[i]->desc().width) * images[i]->desc().height * texelBytes[i];
  }
  auto buffer =
      vk::Buffer::create(*ctx_, total, VK_BUFFER_USAGE_TRANSFER_DST_BIT, vk::MemoryUsage::Readback);
  if (!buffer) return buffer.error();
  Status s = ctx_->submitAndWait([&](VkCommandBuffer cmd) {
    vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, VK_ACCESS_2_MEMORY_WRITE_BIT,
                      VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_READ_BIT);
    for (int i = 0; i < 3; ++i) {
      VkBufferImageCopy r{};
      r.bufferOffset = offsets[i];
      r.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
      r.imageExtent = {images[i]->desc().width, images[i]->desc().height, 1};
      vkCmdCopyImageToBuffer(cmd, images[i]->get(), VK_IMAGE_LAYOUT_GENERAL, buffer->get(), 1, &r);
    }
    vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT,
                      VK_PIPELINE_STAGE_2_HOST_BIT, VK_ACCESS_2_HOST_READ_BIT);
  });
  if (!s) return s.error();
  PC_VK_TRY(buffer->invalidate());
  FieldAtlases out;
  Atlas* atlases[3] = {&out.irradiance, &out.depth, &out.occlusion};
  const auto* bytes = buffer->as<const std::uint8_t>();
  for (int i = 0; i < 3; ++i) {
    Atlas& a = *atlases[i];
    a.width = int(images[i]->desc().width);
    a.height = int(images[i]->desc().height);
    a.channels = channels[i];
    a.texels.resize(std::size_t(a.width) * a.height * a.channels);
    for (std::size_t t = 0; t < std::size_t(a.width) * a.height; ++t) {
      const std::uint8_t* texel = bytes + offsets[i] + t * texelBytes[i];
      for (int ch = 0; ch < a.channels; ++ch) {
        float v;
        if (i == 1) {
          std::memcpy(&v, texel + ch * 4, 4);
        } else {
          std::uint16_t h;
          std::memcpy(&h, texel + ch * 2, 2);
          v = glm::unpackHalf1x16(h);
        }
        a.texels[t * std::size_t(a.channels) + std::size_t(ch)] = v;
      }
    }
  }
  return out;
}

}  // namespace pc::client
