#include "swapchain.h"

#include <algorithm>

#include "vk_util.h"

namespace pc::client {

Swapchain::~Swapchain() { destroy(); }

void Swapchain::destroy() {
  views_.clear();
  acquired_.clear();
  rendered_.clear();
  if (swapchain_) vkDestroySwapchainKHR(ctx_->device(), swapchain_, nullptr);
  swapchain_ = VK_NULL_HANDLE;
}

Status Swapchain::create(VkExtent2D fallback, int frameSlots) {
  const VkPhysicalDevice gpu = ctx_->physicalDevice();
  VkBool32 supported = VK_FALSE;
  PC_VK_TRY(vkGetPhysicalDeviceSurfaceSupportKHR(gpu, ctx_->queueFamily(), surface_, &supported));
  if (!supported) return Error{"the Vulkan queue cannot present to this window"};
  VkSurfaceCapabilitiesKHR caps;
  PC_VK_TRY(vkGetPhysicalDeviceSurfaceCapabilitiesKHR(gpu, surface_, &caps));
  std::uint32_t count = 0;
  PC_VK_TRY(vkGetPhysicalDeviceSurfaceFormatsKHR(gpu, surface_, &count, nullptr));
  std::vector<VkSurfaceFormatKHR> formats(count);
  PC_VK_TRY(vkGetPhysicalDeviceSurfaceFormatsKHR(gpu, surface_, &count, formats.data()));
  // UNORM: the tone-mapping shader writes sRGB-encoded values itself, the same bytes as the
  // headless PNGs.
  VkSurfaceFormatKHR chosen{VK_FORMAT_UNDEFINED, VK_COLOR_SPACE_SRGB_NONLINEAR_KHR};
  for (const VkSurfaceFormatKHR& f : formats) {
    if ((f.format == VK_FORMAT_B8G8R8A8_UNORM || f.format == VK_FORMAT_R8G8B8A8_UNORM) &&
        f.colorSpace == VK_COLOR_SPACE_SRGB_NONLINEAR_KHR) {
      chosen = f;
      break;
    }
  }
  if (chosen.format == VK_FORMAT_UNDEFINED) return Error{"the window offers no 8-bit UNORM format"};

  VkExtent2D extent = caps.currentExtent;
  if (extent.width == UINT32_MAX) {
    extent.width = std::clamp(fallback.width, caps.minImageExtent.width, caps.maxImageExtent.width);
    extent.height =
        std::clamp(fallback.height, caps.minImageExtent.height, caps.maxImageExtent.height);
  }
  std::uint32_t images = std::max(caps.minImageCount + 1, 2u);
  if (caps.maxImageCount > 0) images = std::min(images, caps.maxImageCount);

  VkSwapchainCreateInfoKHR ci{VK_STRUCTURE_TYPE_SWAPCHAIN_CREATE_INFO_KHR};
  ci.surface = surface_;
  ci.minImageCount = images;
  ci.imageFormat = chosen.format;
  ci.imageColorSpace = chosen.colorSpace;
  ci.imageExtent = extent;
  ci.imageArrayLayers = 1;
  ci.imageUsage = VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT;
  ci.imageSharingMode = VK_SHARING_MODE_EXCLUSIVE;
  ci.preTransform = caps.currentTransform;
  ci.compositeAlpha = VK_COMPOSITE_ALPHA_OPAQUE_BIT_KHR;
  ci.presentMode = VK_PRESENT_MODE_FIFO_KHR;  // always available; no tearing
  ci.clipped = VK_TRUE;
  ci.oldSwapchain = swapchain_;
  VkSwapchainKHR created = VK_NULL_HANDLE;
  PC_VK_TRY(vkCreateSwapchainKHR(ctx_->device(), &ci, nullptr, &created));
  destroy();
  swapchain_ = created;
  extent_ = extent;
  format_ = chosen.format;

  PC_VK_TRY(vkGetSwapchainImagesKHR(ctx_->device(), swapchain_, &count, nullptr));
  images_.resize(count);
  PC_VK_TRY(vkGetSwapchainImagesKHR(ctx_->device(), swapchain_, &count, images_.data()));
  auto semaphore = [&]() -> Result<vk::UniqueSemaphore> {
    VkSemaphoreCreateInfo si{VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO};
    VkSemaphore s = VK_NULL_HANDLE;
    PC_VK_TRY(vkCreateSemaphore(ctx_->device(), &si, nullptr, &s));
    return vk::UniqueSemaphore(ctx_->device(), s);
  };
  for (VkImage image : images_) {
    auto view =
        makeView(*ctx_, image, format_, VK_IMAGE_VIEW_TYPE_2D, VK_IMAGE_ASPECT_COLOR_BIT, 0, 1);
    if (!view) return view.error();
    views_.push_back(std::move(view).value());
    auto s = semaphore();
    if (!s) return s.error();
    rendered_.push_back(std::move(s).value());
  }
  for (int i = 0; i < frameSlots; ++i) {
    auto s = semaphore();
    if (!s) return s.error();
    acquired_.push_back(std::move(s).value());
  }
  return Status::success();
}

}  // namespace pc::client
