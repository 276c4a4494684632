#include <algorithm>
#include <string>
#include <vector>

#include "context.h"

namespace pc::vk {

std::uint32_t formatTexelBytes(VkFormat format) {
  switch (format) {
    case VK_FORMAT_R8_UNORM:
      return 1;
    case VK_FORMAT_R8G8B8A8_UNORM:
    case VK_FORMAT_R8G8B8A8_SRGB:
    case VK_FORMAT_B8G8R8A8_UNORM:
    case VK_FORMAT_B8G8R8A8_SRGB:
    case VK_FORMAT_R32_SFLOAT:
    case VK_FORMAT_R16G16_SFLOAT:
    case VK_FORMAT_D32_SFLOAT:
    case VK_FORMAT_B10G11R11_UFLOAT_PACK32:
      return 4;
    case VK_FORMAT_R16G16B16A16_SFLOAT:
    case VK_FORMAT_R32G32_SFLOAT:
      return 8;
    case VK_FORMAT_R32G32B32A32_SFLOAT:
      return 16;
    default:
      return 0;
  }
}

Result<Image> Image::create(const Context& ctx, const ImageDesc& desc) {
  Image img;
  img.ctx_ = &ctx;
  img.desc_ = desc;
  VkImageCreateInfo ici{VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO};
  ici.flags = desc.cube ? VK_IMAGE_CREATE_CUBE_COMPATIBLE_BIT : 0;
  ici.imageType = VK_IMAGE_TYPE_2D;
  ici.format = desc.format;
  ici.extent = {desc.width, desc.height, 1};
  ici.mipLevels = desc.mipLevels;
  ici.arrayLayers = desc.layers;
  ici.samples = desc.samples;
  ici.tiling = VK_IMAGE_TILING_OPTIMAL;
  ici.usage = desc.usage;
  ici.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
  ici.initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
  PC_VK_TRY(vkCreateImage(ctx.device(), &ici, nullptr, &img.image_));
  VkMemoryRequirements req;
  vkGetImageMemoryRequirements(ctx.device(), img.image_, &req);
  const int type = ctx.findMemoryType(req.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
  if (type < 0) return Error{"no device-local memory type for an image"};
  VkMemoryAllocateInfo ai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
  ai.allocationSize = req.size;
  ai.memoryTypeIndex = std::uint32_t(type);
  PC_VK_TRY(vkAllocateMemory(ctx.device(), &ai, nullptr, &img.memory_));
  PC_VK_TRY(vkBindImageMemory(ctx.device(), img.image_, img.memory_, 0));

  VkImageViewCreateInfo vci{VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO};
  vci.image = img.image_;
  vci.viewType = desc.cube
                     ? (desc.layers > 6 ? VK_IMAGE_VIEW_TYPE_CUBE_ARRAY : VK_IMAGE_VIEW_TYPE_CUBE)
                     : (desc.layers > 1 ? VK_IMAGE_VIEW_TYPE_2D_ARRAY : VK_IMAGE_VIEW_TYPE_2D);
  vci.format = desc.format;
  vci.subresourceRange = img.range();
  PC_VK_TRY(vkCreateImageView(ctx.device(), &vci, nullptr, &img.view_));
  return img;
}

Image::~Image() { release(); }

void Image::release() {
  if (!ctx_) return;
  if (view_) vkDestroyImageView(ctx_->device(), view_, nullptr);
  if (image_) vkDestroyImage(ctx_->device(), image_, nullptr);
  if (memory_) vkFreeMemory(ctx_->device(), memory_, nullptr);
  view_ = VK_NULL_HANDLE;
  image_ = VK_NULL_HANDLE;
  memory_ = VK_NULL_HANDLE;
}

Image::Image(Image&& o) noexcept { *this = std::move(o); }

Image& Image::operator=(Image&& o) noexcept {
  if (this == &o) return *this;
  release();
  ctx_ = o.ctx_;
  image_ = std::exchange(o.image_, VK_NULL_HANDLE);
  memory_ = std::exchange(o.memory_, VK_NULL_HANDLE);
  view_ = std::exchange(o.view_, VK_NULL_HANDLE);
  desc_ = o.desc_;
  layout_ = o.layout_;
  return *this;
}

VkImageAspectFlags Image::aspect() const {
  switch (desc_.format) {
    case VK_FORMAT_D32_SFLOAT:
    case VK_FORMAT_D16_UNORM:
      return VK_IMAGE_ASPECT_DEPTH_BIT;
    case VK_FORMAT_D24_UNORM_S8_UINT:
    case VK_FORMAT_D32_SFLOAT_S8_UINT:
      return VK_IMAGE_ASPECT_DEPTH_BIT | VK_IMAGE_ASPECT_STENCIL_BIT;
    default:
      return VK_IMAGE_ASPECT_COLOR_BIT;
  }
}

VkImageSubresourceRange Image::range() const {
  return {aspect(), 0, desc_.mipLevels, 0, desc_.layers};
}

void Image::transition(VkCommandBuffer cmd, VkImageLayout newLayout, VkPipelineStageFlags2 srcStage,
                       VkAccessFlags2 srcAccess, VkPipelineStageFlags2 dstStage,
                       VkAccessFlags2 dstAccess) {
  VkImageMemoryBarrier b{VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER};
  b.srcAccessMask = legacyAccess(srcAccess);
  b.dstAccessMask = legacyAccess(dstAccess);
  b.oldLayout = layout_;
  b.newLayout = newLayout;
  b.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  b.image = image_;
  b.subresourceRange = range();
  vkCmdPipelineBarrier(cmd, legacyStages(srcStage, true), legacyStages(dstStage, false), 0, 0,
                       nullptr, 0, nullptr, 1, &b);
  layout_ = newLayout;
}

Status Image::upload(const void* data, std::size_t bytes) {
  const std::size_t texel = formatTexelBytes(desc_.format);
  if (texel == 0) return Error{"Image::upload: the image's format has no known texel size"};
  std::vector<VkBufferImageCopy> copies;
  std::size_t offset = 0;
  for (std::uint32_t level = 0; level < desc_.mipLevels; ++level) {
    const std::uint32_t w = std::max(1u, desc_.width >> level);
    const std::uint32_t h = std::max(1u, desc_.height >> level);
    VkBufferImageCopy copy{};
    copy.bufferOffset = offset;
    copy.imageSubresource = {aspect(), level, 0, desc_.layers};
    copy.imageExtent = {w, h, 1};
    copies.push_back(copy);
    offset += std::size_t(w) * h * desc_.layers * texel;
  }
  if (bytes != offset)
    return Error{"Image::upload: " + std::to_string(bytes) + " bytes given for an image of " +
                 std::to_string(offset)};
  auto staging =
      Buffer::create(*ctx_, bytes, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, MemoryUsage::Upload);
  if (!staging) return staging.error();
  staging->write(data, bytes);
  return ctx_->submitAndWait([&](VkCommandBuffer cmd) {
    transition(cmd, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL);
    vkCmdCopyBufferToImage(cmd, staging->get(), image_, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                           std::uint32_t(copies.size()), copies.data());
    transition(cmd, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL);
  });
}

}  // namespace pc::vk
