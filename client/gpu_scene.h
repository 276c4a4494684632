// The scene's geometry and textures on the GPU: one vertex and one index buffer for every
// mesh (scene_pack.h; the lighting pass reads them as storage buffers too), the base-color and
// emissive textures as sRGB images with their mip chains, and the samplers that read them:
// bilinear with each texture's wrap modes like Texture::sample, with trilinear (and
// anisotropic) minification.
#pragma once

#include <optional>
#include <span>
#include <vector>

#include "common/result.h"
#include "common/scene.h"
#include "common/vulkan/context.h"
#include "common/vulkan/texture_samplers.h"
#include "scene_pack.h"

namespace pc::client {

class GpuScene {
 public:
  // Anisotropic filtering goes up to this many taps where the device has it.
  static constexpr float kMaxAnisotropy = 16.0f;
  // mipmaps false: level 0 alone, each lookup a bilinear tap as on the CPU (a baseline).
  static Result<GpuScene> create(const vk::Context& ctx, const Scene& scene, bool mipmaps);

  const PackedScene& packed() const { return packed_; }
  VkBuffer vertices() const { return vertices_.get(); }
  VkBuffer indices() const { return indices_.get(); }
  // One entry per scene texture (a white texel where the scene has none), for the
  // textures[] binding.
  std::vector<VkDescriptorImageInfo> textureInfos() const;
  int textureCount() const { return int(textures_.size()); }

 private:
  PackedScene packed_;
  vk::Buffer vertices_, indices_;
  std::vector<vk::Image> textures_;
  std::optional<vk::TextureSamplers> samplers_;
  std::vector<VkSampler> textureSamplers_;  // per texture (owned by samplers_)
};

}  // namespace pc::client
