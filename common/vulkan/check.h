// Checking of Vulkan results. Every call that returns a VkResult goes through one of these:
//   PC_VK_TRY(call)    in functions returning pc::Error-compatible results (Result<T>, Status):
//                      a failure returns Error{"<call>: <VkResult name>"}.
//   VK_CHECK(call)     where a failure leaves nothing sensible to do (device lost, out of memory
//                      mid-frame): logs "<file>:<line>: <call>: <VkResult name>" and aborts.
#pragma once

#include <string>

#include <vulkan/vulkan.h>

namespace pc::vk {

// "VK_ERROR_OUT_OF_DEVICE_MEMORY" etc.; "VkResult(<n>)" for codes this build does not name.
const char* resultName(VkResult result);

// Logs the failed call and aborts (used by VK_CHECK).
[[noreturn]] void fatalVkError(const char* call, VkResult result, const char* file, int line);

std::string vkErrorMessage(const char* call, VkResult result);

}  // namespace pc::vk

#define VK_CHECK(call)                                                       \
  do {                                                                       \
    const VkResult pc_vk_result_ = (call);                                   \
    if (pc_vk_result_ != VK_SUCCESS)                                         \
      ::pc::vk::fatalVkError(#call, pc_vk_result_, __FILE__, __LINE__);      \
  } while (0)

#define PC_VK_TRY(call)                                                      \
  do {                                                                       \
    const VkResult pc_vk_result_ = (call);                                   \
    if (pc_vk_result_ != VK_SUCCESS)                                         \
      return ::pc::Error{::pc::vk::vkErrorMessage(#call, pc_vk_result_)};    \
  } while (0)
