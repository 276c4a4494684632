#include "texture_samplers.h"

#include <algorithm>

#include "check.h"

namespace pc::vk {
namespace {

VkSamplerAddressMode addressMode(TextureWrap wrap) {
  switch (wrap) {
    case TextureWrap::ClampToEdge:
      return VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE;
    case TextureWrap::MirroredRepeat:
      return VK_SAMPLER_ADDRESS_MODE_MIRRORED_REPEAT;
    case TextureWrap::Repeat:
      break;
  }
  return VK_SAMPLER_ADDRESS_MODE_REPEAT;
}

}  // namespace

Result<VkSampler> TextureSamplers::forTexture(const Texture& texture) {
  return get(texture.wrapU, texture.wrapV);
}

Result<VkSampler> TextureSamplers::repeating() {
  return get(TextureWrap::Repeat, TextureWrap::Repeat);
}

Result<VkSampler> TextureSamplers::get(TextureWrap u, TextureWrap v) {
  auto it = samplers_.find({u, v});
  if (it != samplers_.end()) return it->second.get();
  VkSamplerCreateInfo si{VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO};
  si.magFilter = si.minFilter = VK_FILTER_LINEAR;
  si.mipmapMode = desc_.mipmaps ? VK_SAMPLER_MIPMAP_MODE_LINEAR : VK_SAMPLER_MIPMAP_MODE_NEAREST;
  si.addressModeU = addressMode(u);
  si.addressModeV = addressMode(v);
  si.addressModeW = VK_SAMPLER_ADDRESS_MODE_REPEAT;
  si.maxLod = desc_.mipmaps ? VK_LOD_CLAMP_NONE : 0.0f;
  if (desc_.maxAnisotropy > 0.0f) {
    VkPhysicalDeviceFeatures features{};
    vkGetPhysicalDeviceFeatures(ctx_->physicalDevice(), &features);
    if (features.samplerAnisotropy) {
      si.anisotropyEnable = VK_TRUE;
      si.maxAnisotropy =
          std::min(desc_.maxAnisotropy, ctx_->properties().limits.maxSamplerAnisotropy);
    }
  }
  VkSampler sampler = VK_NULL_HANDLE;
  PC_VK_TRY(vkCreateSampler(ctx_->device(), &si, nullptr, &sampler));
  samplers_.emplace(std::make_pair(u, v), UniqueSampler(ctx_->device(), sampler));
  return sampler;
}

}  // namespace pc::vk
