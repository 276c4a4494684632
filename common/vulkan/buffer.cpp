#include <cstring>

#include "context.h"

namespace pc::vk {

Result<Buffer> Buffer::create(const Context& ctx, VkDeviceSize size, VkBufferUsageFlags usage,
                              MemoryUsage memory) {
  Buffer b;
  b.ctx_ = &ctx;
  b.size_ = size;
  const bool wantAddress = ctx.options().rayTracing;
  if (wantAddress) usage |= VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT;
  VkBufferCreateInfo bci{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
  bci.size = size > 0 ? size : 4;  // zero-sized buffers are invalid; empty inputs get a stub
  bci.usage = usage;
  bci.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
  PC_VK_TRY(vkCreateBuffer(ctx.device(), &bci, nullptr, &b.buffer_));

  VkMemoryRequirements req;
  vkGetBufferMemoryRequirements(ctx.device(), b.buffer_, &req);
  int type = -1;
  switch (memory) {
    case MemoryUsage::DeviceLocal:
      type = ctx.findMemoryType(req.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
      break;
    case MemoryUsage::Upload:
      type = ctx.findMemoryType(req.memoryTypeBits, VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT |
                                                        VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
      break;
    case MemoryUsage::Readback:
      // Cached memory makes host reads fast; coherence is optional (invalidate() handles it).
      type = ctx.findMemoryType(req.memoryTypeBits, VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT,
                                VK_MEMORY_PROPERTY_HOST_CACHED_BIT);
      break;
  }
  if (type < 0) return Error{"no memory type for a buffer of " + std::to_string(size) + " bytes"};
  b.coherent_ = (ctx.memoryProperties().memoryTypes[type].propertyFlags &
                 VK_MEMORY_PROPERTY_HOST_COHERENT_BIT) != 0;

  VkMemoryAllocateFlagsInfo flags{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_FLAGS_INFO};
  flags.flags = VK_MEMORY_ALLOCATE_DEVICE_ADDRESS_BIT;
  VkMemoryAllocateInfo ai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
  ai.pNext = wantAddress ? &flags : nullptr;
  ai.allocationSize = req.size;
  ai.memoryTypeIndex = std::uint32_t(type);
  PC_VK_TRY(vkAllocateMemory(ctx.device(), &ai, nullptr, &b.memory_));
  PC_VK_TRY(vkBindBufferMemory(ctx.device(), b.buffer_, b.memory_, 0));
  if (memory != MemoryUsage::DeviceLocal) {
    PC_VK_TRY(vkMapMemory(ctx.device(), b.memory_, 0, VK_WHOLE_SIZE, 0, &b.mapped_));
  }
  if (wantAddress) {
    VkBufferDeviceAddressInfo info{VK_STRUCTURE_TYPE_BUFFER_DEVICE_ADDRESS_INFO};
    info.buffer = b.buffer_;
    b.address_ = vkGetBufferDeviceAddress(ctx.device(), &info);
  }
  return b;
}

Buffer::~Buffer() { release(); }

void Buffer::release() {
  if (!ctx_) return;
  if (buffer_) vkDestroyBuffer(ctx_->device(), buffer_, nullptr);
  if (memory_) vkFreeMemory(ctx_->device(), memory_, nullptr);  // unmaps too
  buffer_ = VK_NULL_HANDLE;
  memory_ = VK_NULL_HANDLE;
  mapped_ = nullptr;
}

Buffer::Buffer(Buffer&& o) noexcept { *this = std::move(o); }

Buffer& Buffer::operator=(Buffer&& o) noexcept {
  if (this == &o) return *this;
  release();
  ctx_ = o.ctx_;
  buffer_ = std::exchange(o.buffer_, VK_NULL_HANDLE);
  memory_ = std::exchange(o.memory_, VK_NULL_HANDLE);
  size_ = o.size_;
  address_ = o.address_;
  mapped_ = std::exchange(o.mapped_, nullptr);
  coherent_ = o.coherent_;
  return *this;
}

VkResult Buffer::invalidate() const {
  if (coherent_ || !mapped_) return VK_SUCCESS;
  VkMappedMemoryRange range{VK_STRUCTURE_TYPE_MAPPED_MEMORY_RANGE};
  range.memory = memory_;
  range.size = VK_WHOLE_SIZE;
  return vkInvalidateMappedMemoryRanges(ctx_->device(), 1, &range);
}

void Buffer::write(const void* data, std::size_t bytes, std::size_t offset) const {
  if (bytes > 0) std::memcpy(static_cast<char*>(mapped_) + offset, data, bytes);
}

Result<Buffer> uploadBuffer(const Context& ctx, const void* data, std::size_t bytes,
                            VkBufferUsageFlags usage) {
  auto staging = Buffer::create(ctx, bytes, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, MemoryUsage::Upload);
  if (!staging) return staging.error();
  staging->write(data, bytes);
  auto buffer = Buffer::create(ctx, bytes, usage | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                               MemoryUsage::DeviceLocal);
  if (!buffer) return buffer.error();
  if (bytes > 0) {
    Status s = ctx.submitAndWait([&](VkCommandBuffer cmd) {
      VkBufferCopy copy{0, 0, bytes};
      vkCmdCopyBuffer(cmd, staging->get(), buffer->get(), 1, &copy);
    });
    if (!s) return s.error();
  }
  return buffer;
}

}  // namespace pc::vk
