#include "legacy_sync.h"

#include <cstdint>

namespace pc::vk {

namespace {

// synchronization2's bits above 32 and the 1.0 flag each belongs to.
struct Mapping {
  std::uint64_t from;
  std::uint32_t to;
};

constexpr Mapping kStages[] = {
    {VK_PIPELINE_STAGE_2_COPY_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT},
    {VK_PIPELINE_STAGE_2_RESOLVE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT},
    {VK_PIPELINE_STAGE_2_BLIT_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT},
    {VK_PIPELINE_STAGE_2_CLEAR_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT},
    {VK_PIPELINE_STAGE_2_INDEX_INPUT_BIT, VK_PIPELINE_STAGE_VERTEX_INPUT_BIT},
    {VK_PIPELINE_STAGE_2_VERTEX_ATTRIBUTE_INPUT_BIT, VK_PIPELINE_STAGE_VERTEX_INPUT_BIT},
    // Tessellation and geometry stages need their features; the vertex stage is what every
    // pipeline that rasterizes has, and 1.0 orders it before the rest of pre-rasterization.
    {VK_PIPELINE_STAGE_2_PRE_RASTERIZATION_SHADERS_BIT, VK_PIPELINE_STAGE_VERTEX_SHADER_BIT},
};

constexpr Mapping kAccess[] = {
    {VK_ACCESS_2_SHADER_SAMPLED_READ_BIT, VK_ACCESS_SHADER_READ_BIT},
    {VK_ACCESS_2_SHADER_STORAGE_READ_BIT, VK_ACCESS_SHADER_READ_BIT},
    {VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT, VK_ACCESS_SHADER_WRITE_BIT},
};

template <std::size_t N>
std::uint32_t fold(std::uint64_t flags, const Mapping (&table)[N]) {
  // Below bit 32 the two vocabularies give every bit the same value and meaning.
  std::uint32_t out = std::uint32_t(flags & 0xffffffffu);
  for (const Mapping& m : table)
    if (flags & m.from) out |= m.to;
  return out;
}

}  // namespace

VkPipelineStageFlags legacyStages(VkPipelineStageFlags2 stages, bool source) {
  const std::uint32_t out = fold(stages, kStages);
  if (out != 0) return out;
  return source ? VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT : VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT;
}

VkAccessFlags legacyAccess(VkAccessFlags2 access) { return fold(access, kAccess); }

VkResult submitOne(VkQueue queue, VkCommandBuffer cmd, VkFence fence) {
  VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
  si.commandBufferCount = 1;
  si.pCommandBuffers = &cmd;
  return vkQueueSubmit(queue, 1, &si, fence);
}

}  // namespace pc::vk
