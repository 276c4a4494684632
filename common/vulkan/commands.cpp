#include "context.h"

namespace pc::vk {

Result<CommandPool> CommandPool::create(const Context& ctx) {
  CommandPool p;
  p.ctx_ = &ctx;
  VkCommandPoolCreateInfo pci{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
  pci.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
  pci.queueFamilyIndex = ctx.queueFamily();
  PC_VK_TRY(vkCreateCommandPool(ctx.device(), &pci, nullptr, &p.pool_));
  return p;
}

CommandPool::~CommandPool() {
  if (ctx_ && pool_) vkDestroyCommandPool(ctx_->device(), pool_, nullptr);
}

CommandPool::CommandPool(CommandPool&& o) noexcept
    : ctx_(o.ctx_), pool_(std::exchange(o.pool_, VK_NULL_HANDLE)) {}

CommandPool& CommandPool::operator=(CommandPool&& o) noexcept {
  if (this != &o) {
    if (ctx_ && pool_) vkDestroyCommandPool(ctx_->device(), pool_, nullptr);
    ctx_ = o.ctx_;
    pool_ = std::exchange(o.pool_, VK_NULL_HANDLE);
  }
  return *this;
}

Result<VkCommandBuffer> CommandPool::allocate() const {
  VkCommandBufferAllocateInfo ai{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
  ai.commandPool = pool_;
  ai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  ai.commandBufferCount = 1;
  VkCommandBuffer cmd = VK_NULL_HANDLE;
  PC_VK_TRY(vkAllocateCommandBuffers(ctx_->device(), &ai, &cmd));
  return cmd;
}

Status CommandPool::submitAndWait(const std::function<void(VkCommandBuffer)>& record) const {
  auto cmd = allocate();
  if (!cmd) return cmd.error();
  struct Free {
    VkDevice d;
    VkCommandPool p;
    VkCommandBuffer c;
    ~Free() { vkFreeCommandBuffers(d, p, 1, &c); }
  } release{ctx_->device(), pool_, *cmd};
  VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  PC_VK_TRY(vkBeginCommandBuffer(*cmd, &bi));
  record(*cmd);
  PC_VK_TRY(vkEndCommandBuffer(*cmd));
  VkFenceCreateInfo fci{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
  VkFence fenceHandle = VK_NULL_HANDLE;
  PC_VK_TRY(vkCreateFence(ctx_->device(), &fci, nullptr, &fenceHandle));
  UniqueFence fence(ctx_->device(), fenceHandle);
  PC_VK_TRY(submitOne(ctx_->queue(), *cmd, fenceHandle));
  PC_VK_TRY(vkWaitForFences(ctx_->device(), 1, &fenceHandle, VK_TRUE, UINT64_MAX));
  return Status::success();
}

void memoryBarrier(VkCommandBuffer cmd, VkPipelineStageFlags2 srcStage, VkAccessFlags2 srcAccess,
                   VkPipelineStageFlags2 dstStage, VkAccessFlags2 dstAccess) {
  VkMemoryBarrier b{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  b.srcAccessMask = legacyAccess(srcAccess);
  b.dstAccessMask = legacyAccess(dstAccess);
  vkCmdPipelineBarrier(cmd, legacyStages(srcStage, true), legacyStages(dstStage, false), 0, 1, &b,
                       0, nullptr, 0, nullptr);
}

}  // namespace pc::vk
