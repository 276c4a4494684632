// Small Vulkan helpers the client's passes share: image views over chosen layers and
// synchronization2 image barriers with explicit stages.
#pragma once

#include <cstdint>

#include "common/result.h"
#include "common/vulkan/context.h"

namespace pc::client {

// A view of `layerCount` layers from `baseLayer` (mip 0). 2D_ARRAY views are used even for
// one layer, so shaders see the same array types in mono and stereo.
Result<vk::UniqueImageView> makeView(const vk::Context& ctx, VkImage image, VkFormat format,
                                     VkImageViewType type, VkImageAspectFlags aspect,
                                     std::uint32_t baseLayer, std::uint32_t layerCount);

struct ImageBarrier {
  VkImage image = VK_NULL_HANDLE;
  VkImageAspectFlags aspect = VK_IMAGE_ASPECT_COLOR_BIT;
  VkImageLayout oldLayout = VK_IMAGE_LAYOUT_UNDEFINED, newLayout = VK_IMAGE_LAYOUT_UNDEFINED;
  VkPipelineStageFlags2 srcStage = VK_PIPELINE_STAGE_2_NONE;
  VkAccessFlags2 srcAccess = VK_ACCESS_2_NONE;
  VkPipelineStageFlags2 dstStage = VK_PIPELINE_STAGE_2_NONE;
  VkAccessFlags2 dstAccess = VK_ACCESS_2_NONE;
};

// Records the barriers (all layers and mips of each image) in one vkCmdPipelineBarrier2.
void imageBarriers(VkCommandBuffer cmd, std::initializer_list<ImageBarrier> barriers);

}  // namespace pc::client
