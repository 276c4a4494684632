#include "vk_util.h"

#include <vector>

namespace pc::client {

Result<vk::UniqueImageView> makeView(const vk::Context& ctx, VkImage image, VkFormat format,
                                     VkImageViewType type, VkImageAspectFlags aspect,
                                     std::uint32_t baseLayer, std::uint32_t layerCount) {
  VkImageViewCreateInfo info{VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO};
  info.image = image;
  info.viewType = type;
  info.format = format;
  info.subresourceRange = {aspect, 0, 1, baseLayer, layerCount};
  VkImageView view = VK_NULL_HANDLE;
  PC_VK_TRY(vkCreateImageView(ctx.device(), &info, nullptr, &view));
  return vk::UniqueImageView(ctx.device(), view);
}

void imageBarriers(VkCommandBuffer cmd, std::initializer_list<ImageBarrier> barriers) {
  std::vector<VkImageMemoryBarrier2> list;
  list.reserve(barriers.size());
  for (const ImageBarrier& b : barriers) {
    VkImageMemoryBarrier2 m{VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER_2};
    m.srcStageMask = b.srcStage;
    m.srcAccessMask = b.srcAccess;
    m.dstStageMask = b.dstStage;
    m.dstAccessMask = b.dstAccess;
    m.oldLayout = b.oldLayout;
    m.newLayout = b.newLayout;
    m.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    m.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    m.image = b.image;
    m.subresourceRange = {b.aspect, 0, VK_REMAINING_MIP_LEVELS, 0, VK_REMAINING_ARRAY_LAYERS};
    list.push_back(m);
  }
  VkDependencyInfo dep{VK_STRUCTURE_TYPE_DEPENDENCY_INFO};
  dep.imageMemoryBarrierCount = std::uint32_t(list.size());
  dep.pImageMemoryBarriers = list.data();
  vkCmdPipelineBarrier2(cmd, &dep);
}

}  // namespace pc::client
