#include "field_gpu.h"

#include <cstring>
#include <glm/gtc/packing.hpp>

#include "vk_util.h"

namespace pc::client {
namespace {

constexpr VkFormat kIrradianceFormat = VK_FORMAT_R16G16B16A16_SFLOAT;
constexpr VkFormat kDepthFormat = VK_FORMAT_R32G32_SFLOAT;  // mean square needs the range
constexpr VkFormat kOcclusionFormat = VK_FORMAT_R16_SFLOAT;
constexpr std::size_t kProbeRecordBytes = 16;  // vec4: offset xyz, state w

std::size_t align16(std::size_t v) { return (v + 15) & ~std::size_t(15); }

std::size_t atlasBrickBytes(int tileSize, int texelBytes) {
  return align16(std::size_t(gpu::PC_PROBES_PER_BRICK) * tileSize * tileSize * texelBytes);
}

// Writes one atlas's tiles of a brick into staging at `offset` (converted to the GPU format)
// and appends the copy regions. Returns the bytes written.
template <typename Convert>
std::size_t stageTiles(const Atlas& atlas, const gpu::CascadeDesc& c, int brick, int tileSize,
                       int texelBytes, std::uint8_t* staging, std::size_t offset,
                       std::vector<VkBufferImageCopy>& regions, Convert convert) {
  std::size_t written = 0;
  for (const TileRun& run : brickTileRuns(c, brick)) {
    const int w = run.count * tileSize;
    VkBufferImageCopy r{};
    r.bufferOffset = offset + written;
    r.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    r.imageOffset = {run.tileX * tileSize, run.tileY * tileSize, 0};
    r.imageExtent = {std::uint32_t(w), std::uint32_t(tileSize), 1};
    regions.push_back(r);
    std::uint8_t* out = staging + offset + written;
    for (int y = 0; y < tileSize; ++y) {
      const float* src = atlas.at(run.tileX * tileSize, run.tileY * tileSize + y);
      for (int x = 0; x < w; ++x)
        convert(src + std::size_t(x) * atlas.channels, out + std::size_t(y * w + x) * texelBytes);
    }
    written += std::size_t(w) * tileSize * texelBytes;
  }
  return written;
}

void toIrradiance(const float* in, std::uint8_t* out) {
  const std::uint16_t h[4] = {glm::packHalf1x16(in[0]), glm::packHalf1x16(in[1]),
                              glm::packHalf1x16(in[2]), glm::packHalf1x16(1.0f)};
  std::memcpy(out, h, sizeof h);
}
void toDepth(const float* in, std::uint8_t* out) { std::memcpy(out, in, 2 * sizeof(float)); }
void toOcclusion(const float* in, std::uint8_t* out) {
  const std::uint16_t h = glm::packHalf1x16(in[0]);
  std::memcpy(out, &h, sizeof h);
}

}  // namespace

std::size_t brickUploadBytes() {
  return atlasBrickBytes(gpu::PC_IRRADIANCE_TEXELS + 2, 8) +
         atlasBrickBytes(gpu::PC_DEPTH_TEXELS + 2, 8) +
         atlasBrickBytes(gpu::PC_OCCLUSION_TEXELS + 2, 2) +
         gpu::PC_PROBES_PER_BRICK * kProbeRecordBytes;
}

Result<FieldGpu> FieldGpu::create(const vk::Context& ctx, const std::optional<gpu::FieldDesc>& desc,
                                  int frameSlots, int bricksPerFrame) {
  FieldGpu f;
  f.ctx_ = &ctx;
  f.present_ = desc.has_value() && desc->cascadeCount > 0;
  f.fieldDesc_ = f.present_ ? *desc : gpu::FieldDesc{};
  f.bricksPerFrame_ = std::max(1, bricksPerFrame);
  const std::uint32_t rows = f.present_ ? std::uint32_t(f.fieldDesc_.atlasTileRows) : 0;
  auto atlas = [&](VkFormat format, int tileSize) {
    vk::ImageDesc d;
    d.format = format;
    d.width = f.present_ ? std::uint32_t(gpu::PC_ATLAS_TILES_PER_ROW * tileSize) : 1;
    d.height = f.present_ ? rows * std::uint32_t(tileSize) : 1;
    d.usage = VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT;
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

  const std::size_t probeBytes =
      std::max<std::size_t>(1, f.present_ ? std::size_t(f.fieldDesc_.probeCount) : 1) *
      kProbeRecordBytes;
  auto probes = vk::Buffer::create(
      ctx, probeBytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
      vk::MemoryUsage::DeviceLocal);
  if (!probes) return probes.error();
  f.probes_ = std::move(probes).value();
  auto descBuffer = vk::Buffer::create(ctx, sizeof(gpu::FieldDesc),
                                       VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT, vk::MemoryUsage::Upload);
  if (!descBuffer) return descBuffer.error();
  f.desc_ = std::move(descBuffer).value();
  f.desc_.write(&f.fieldDesc_, sizeof f.fieldDesc_);

  const std::size_t stagingBytes = std::size_t(f.bricksPerFrame_) * brickUploadBytes();
  for (int i = 0; i < frameSlots; ++i) {
    auto s = vk::Buffer::create(ctx, stagingBytes, VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                                vk::MemoryUsage::Upload);
    if (!s) return s.error();
    f.staging_.push_back(std::move(s).value());
  }

  // Every probe starts uninitialized (never sampled) and every texel at zero, until its brick
  // arrives.
  Status cleared = ctx.submitAndWait([&](VkCommandBuffer cmd) {
    imageBarriers(
        cmd, {{f.irradiance_.get(), VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
               VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_PIPELINE_STAGE_2_NONE, VK_ACCESS_2_NONE,
               VK_PIPELINE_STAGE_2_CLEAR_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT},
              {f.depth_.get(), VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
               VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_PIPELINE_STAGE_2_NONE, VK_ACCESS_2_NONE,
               VK_PIPELINE_STAGE_2_CLEAR_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT},
              {f.occlusion_.get(), VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
               VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_PIPELINE_STAGE_2_NONE, VK_ACCESS_2_NONE,
               VK_PIPELINE_STAGE_2_CLEAR_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT}});
    const VkClearColorValue zero{};
    const VkImageSubresourceRange all{VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
    for (VkImage image : {f.irradiance_.get(), f.depth_.get(), f.occlusion_.get()})
      vkCmdClearColorImage(cmd, image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, &zero, 1, &all);
    // Every float of every record becomes 3.0f: the state (w) reads PC_PROBE_UNINITIALIZED,
    // and the offsets of such probes are never read.
    static_assert(gpu::PC_PROBE_UNINITIALIZED == 3);
    vkCmdFillBuffer(cmd, f.probes_.get(), 0, VK_WHOLE_SIZE, 0x40400000u);
    const VkPipelineStageFlags2 shaders =
        VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT;
    for (VkImage image : {f.irradiance_.get(), f.depth_.get(), f.occlusion_.get()}) {
      imageBarriers(
          cmd, {{image, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                 VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, VK_PIPELINE_STAGE_2_CLEAR_BIT,
                 VK_ACCESS_2_TRANSFER_WRITE_BIT, shaders, VK_ACCESS_2_SHADER_SAMPLED_READ_BIT}});
    }
    vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_CLEAR_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT, shaders,
                      VK_ACCESS_2_SHADER_STORAGE_READ_BIT);
  });
  if (!cleared) return cleared.error();
  return f;
}

VkDescriptorImageInfo FieldGpu::irradiance(VkSampler s) const {
  return {s, irradiance_.view(), VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
}
VkDescriptorImageInfo FieldGpu::depth(VkSampler s) const {
  return {s, depth_.view(), VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
}
VkDescriptorImageInfo FieldGpu::occlusion(VkSampler s) const {
  return {s, occlusion_.view(), VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
}

FieldUploadStats FieldGpu::recordUploads(VkCommandBuffer cmd, int slot, FieldMirror& mirror) {
  FieldUploadStats stats;
  if (!present_) return stats;
  const std::vector<BrickId> bricks = mirror.takePending(bricksPerFrame_);
  if (bricks.empty()) return stats;

  std::vector<VkBufferImageCopy> irrRegions, depRegions, occRegions;
  std::vector<VkBufferCopy> probeRegions;
  auto* staging = static_cast<std::uint8_t*>(staging_[slot].mapped());
  std::size_t offset = 0;
  mirror.read([&](const Field& field) {
    for (const BrickId& id : bricks) {
      if (id.cascade >= field.desc.cascadeCount) continue;
      const gpu::CascadeDesc& c = field.desc.cascades[id.cascade];
      offset += align16(stageTiles(field.irradiance, c, id.brick, gpu::PC_IRRADIANCE_TEXELS + 2, 8,
                                   staging, offset, irrRegions, toIrradiance));
      offset += align16(stageTiles(field.depth, c, id.brick, gpu::PC_DEPTH_TEXELS + 2, 8, staging,
                                   offset, depRegions, toDepth));
      offset += align16(stageTiles(field.occlusion, c, id.brick, gpu::PC_OCCLUSION_TEXELS + 2, 2,
                                   staging, offset, occRegions, toOcclusion));
      const int first = c.firstProbe + id.brick * gpu::PC_PROBES_PER_BRICK;
      for (int p = 0; p < gpu::PC_PROBES_PER_BRICK; ++p) {
        const ProbeRecord& r = field.probes[std::size_t(first + p)];
        const float record[4] = {r.offset.x, r.offset.y, r.offset.z, float(r.state)};
        std::memcpy(staging + offset + std::size_t(p) * kProbeRecordBytes, record, sizeof record);
      }
      probeRegions.push_back({offset, std::size_t(first) * kProbeRecordBytes,
                              gpu::PC_PROBES_PER_BRICK * kProbeRecordBytes});
      offset += gpu::PC_PROBES_PER_BRICK * kProbeRecordBytes;
      ++stats.bricks;
    }
  });
  stats.bytes = offset;
  if (stats.bricks == 0) return stats;

  // Earlier frames' shader reads finish before the copies overwrite tiles; the copies finish
  // before this frame's shaders read. The layout changes keep the contents.
  const VkPipelineStageFlags2 shaders =
      VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT;
  auto toTransfer = [&](VkImage image) {
    return ImageBarrier{image,
                        VK_IMAGE_ASPECT_COLOR_BIT,
                        VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL,
                        VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                        shaders,
                        VK_ACCESS_2_NONE,
                        VK_PIPELINE_STAGE_2_COPY_BIT,
                        VK_ACCESS_2_TRANSFER_WRITE_BIT};
  };
  auto toShader = [&](VkImage image) {
    return ImageBarrier{image,
                        VK_IMAGE_ASPECT_COLOR_BIT,
                        VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                        VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL,
                        VK_PIPELINE_STAGE_2_COPY_BIT,
                        VK_ACCESS_2_TRANSFER_WRITE_BIT,
                        shaders,
                        VK_ACCESS_2_SHADER_SAMPLED_READ_BIT};
  };
  imageBarriers(
      cmd, {toTransfer(irradiance_.get()), toTransfer(depth_.get()), toTransfer(occlusion_.get())});
  vk::memoryBarrier(cmd, shaders, VK_ACCESS_2_NONE, VK_PIPELINE_STAGE_2_COPY_BIT,
                    VK_ACCESS_2_TRANSFER_WRITE_BIT);
  const VkBuffer src = staging_[slot].get();
  vkCmdCopyBufferToImage(cmd, src, irradiance_.get(), VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                         std::uint32_t(irrRegions.size()), irrRegions.data());
  vkCmdCopyBufferToImage(cmd, src, depth_.get(), VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                         std::uint32_t(depRegions.size()), depRegions.data());
  vkCmdCopyBufferToImage(cmd, src, occlusion_.get(), VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                         std::uint32_t(occRegions.size()), occRegions.data());
  vkCmdCopyBuffer(cmd, src, probes_.get(), std::uint32_t(probeRegions.size()), probeRegions.data());
  imageBarriers(cmd,
                {toShader(irradiance_.get()), toShader(depth_.get()), toShader(occlusion_.get())});
  vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT, shaders,
                    VK_ACCESS_2_SHADER_STORAGE_READ_BIT);
  return stats;
}

Status FieldGpu::uploadAll(FieldMirror& mirror) {
  while (present_ && mirror.age(0.0).pendingBricks > 0) {
    Status s = ctx_->submitAndWait([&](VkCommandBuffer cmd) { recordUploads(cmd, 0, mirror); });
    if (!s) return s;
  }
  return Status::success();
}

}  // namespace pc::client
