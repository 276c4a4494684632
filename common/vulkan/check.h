// Checking of Vulkan results. A call that returns a VkResult goes through PC_VK_TRY in
// functions returning pc::Error-compatible results (Result<T>, Status): a failure returns
// Error{"<call> failed: <VkResult name>"}. There is no aborting form: a lost device or memory
// that runs out mid-frame is an error the caller reports (the GPU server falls back to the CPU).
#pragma once

#include <vulkan/vulkan.h>

#include <string>

namespace pc::vk {

// "VK_ERROR_OUT_OF_DEVICE_MEMORY" etc.; "VkResult(<n>)" for codes this build does not name.
const char* resultName(VkResult result);

std::string vkErrorMessage(const char* call, VkResult result);

}  // namespace pc::vk

#define PC_VK_TRY(call)                                                   \
  do {                                                                    \
    const VkResult pc_vk_result_ = (call);                                \
    if (pc_vk_result_ != VK_SUCCESS)                                      \
      return ::pc::Error{::pc::vk::vkErrorMessage(#call, pc_vk_result_)}; \
  } while (0)
