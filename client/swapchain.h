// A window's swapchain with what presenting needs: image views, one "acquired" semaphore per
// frame slot and one "rendered" semaphore per image (an image's semaphore is reused only
// after that image is acquired again, which the presentation engine orders).
#pragma once

#include <cstdint>
#include <vector>

#include "common/result.h"
#include "common/vulkan/context.h"

namespace pc::client {

class Swapchain {
 public:
  Swapchain(const vk::Context& ctx, VkSurfaceKHR surface) : ctx_(&ctx), surface_(surface) {}
  ~Swapchain();
  Swapchain(const Swapchain&) = delete;
  Swapchain& operator=(const Swapchain&) = delete;

  // (Re)creates for the surface's current size (`fallback` when the surface leaves it to us).
  // The caller makes sure the GPU no longer uses the old images.
  Status create(VkExtent2D fallback, int frameSlots);
  VkSwapchainKHR get() const { return swapchain_; }
  VkExtent2D extent() const { return extent_; }
  VkFormat format() const { return format_; }
  VkImage image(std::uint32_t i) const { return images_[i]; }
  VkImageView view(std::uint32_t i) const { return views_[i].get(); }
  VkSemaphore acquired(int slot) const { return acquired_[std::size_t(slot)].get(); }
  VkSemaphore rendered(std::uint32_t i) const { return rendered_[i].get(); }

 private:
  void destroy();
  const vk::Context* ctx_;
  VkSurfaceKHR surface_;
  VkSwapchainKHR swapchain_ = VK_NULL_HANDLE;
  VkExtent2D extent_{};
  VkFormat format_ = VK_FORMAT_UNDEFINED;
  std::vector<VkImage> images_;
  std::vector<vk::UniqueImageView> views_;
  std::vector<vk::UniqueSemaphore> acquired_, rendered_;
};

}  // namespace pc::client
