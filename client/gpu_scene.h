// The scene's geometry and textures on the GPU: one vertex and one index buffer for every
// mesh (scene_pack.h; the lighting pass reads them as storage buffers too), the base-color and
// emissive textures as sRGB images, and the sampler that reads them the way Texture::sample
// does (bilinear, repeating, no mipmaps).
#pragma once

#include <vector>

#include "common/result.h"
#include "common/scene.h"
#include "common/vulkan/context.h"
#include "scene_pack.h"

namespace pc::client {

class GpuScene {
 public:
  static Result<GpuScene> create(const vk::Context& ctx, const Scene& scene);

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
  vk::UniqueSampler sampler_;
};

}  // namespace pc::client
