// Synchronization written once, in synchronization2's vocabulary, and recorded with Vulkan 1.0's
// commands. The compute and ray-tracing work of the server (and the helpers everything shares)
// must run on Vulkan 1.2 devices, where vkCmdPipelineBarrier2 and vkQueueSubmit2 may not
// exist; the 1.0 commands exist everywhere. synchronization2's extra bits are finer-grained
// names for what the 1.0 flags already cover, so each maps to the 1.0 flag that contains it:
// nothing is dropped that a barrier needs.
#pragma once

#include <vulkan/vulkan.h>

namespace pc::vk {

// The 1.0 stage mask that covers `stages`. An empty mask (VK_PIPELINE_STAGE_2_NONE) is
// TOP_OF_PIPE as a source and BOTTOM_OF_PIPE as a destination, as 1.0 asks.
VkPipelineStageFlags legacyStages(VkPipelineStageFlags2 stages, bool source);
// The 1.0 access mask that covers `access` (sampled and storage reads and writes become
// SHADER_READ / SHADER_WRITE).
VkAccessFlags legacyAccess(VkAccessFlags2 access);

// One command buffer to `queue`, signalling `fence` (may be VK_NULL_HANDLE): vkQueueSubmit.
VkResult submitOne(VkQueue queue, VkCommandBuffer cmd, VkFence fence);

}  // namespace pc::vk
