#include "gpu_scene.h"

#include <algorithm>
#include <span>

#include "texture_mips.h"

namespace pc::client {

Result<GpuScene> GpuScene::create(const vk::Context& ctx, const Scene& scene, bool mipmaps) {
  GpuScene g;
  g.packed_ = packScene(scene);
  if (g.packed_.indices.empty()) return Error{"scene has no triangles to draw"};
  auto vb =
      vk::uploadBuffer(ctx, g.packed_.vertices.data(), g.packed_.vertices.size() * sizeof(Vertex),
                       VK_BUFFER_USAGE_VERTEX_BUFFER_BIT | VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  if (!vb) return vb.error();
  g.vertices_ = std::move(vb).value();
  auto ib = vk::uploadBuffer(ctx, g.packed_.indices.data(),
                             g.packed_.indices.size() * sizeof(std::uint32_t),
                             VK_BUFFER_USAGE_INDEX_BUFFER_BIT | VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  if (!ib) return ib.error();
  g.indices_ = std::move(ib).value();

  // Full mip chains (texture_mips.h) unless asked for level 0 alone; 1x1 stand-ins have one.
  // Colour textures are sRGB; data textures (normal maps) are linear and read as UNORM, as the
  // CPU's Texture::sample reads them.
  auto addTexture = [&](int width, int height, std::span<const std::uint8_t> rgba,
                        bool linear) -> Status {
    const MipChain chain = mipmaps ? buildMipChain(width, height, rgba, linear) : MipChain{};
    const std::span<const std::uint8_t> texels = mipmaps
                                                     ? std::span<const std::uint8_t>(chain.rgba)
                                                     : rgba.first(std::size_t(width) * height * 4);
    vk::ImageDesc d;
    // SRGB: decoded to linear by the sampler, as the CPU's LUT.
    d.format = linear ? VK_FORMAT_R8G8B8A8_UNORM : VK_FORMAT_R8G8B8A8_SRGB;
    d.width = std::uint32_t(width);
    d.height = std::uint32_t(height);
    d.mipLevels = mipmaps ? std::uint32_t(chain.levels) : 1u;
    auto image = vk::Image::create(ctx, d);
    if (!image) return image.error();
    Status s = image->upload(texels.data(), texels.size());
    if (!s) return s;
    g.textures_.push_back(std::move(image).value());
    return Status::success();
  };
  const std::uint8_t white[4] = {255, 255, 255, 255};
  for (const Texture& t : scene.textures) {
    const bool valid =
        t.width > 0 && t.height > 0 && t.rgba.size() >= std::size_t(t.width) * t.height * 4;
    Status s =
        valid ? addTexture(t.width, t.height, t.rgba, t.linear) : addTexture(1, 1, white, t.linear);
    if (!s) return s.error();
  }
  if (g.textures_.empty()) {
    Status s = addTexture(1, 1, white, false);
    if (!s) return s.error();
  }

  // Trilinear, and anisotropic where the device has it: the lighting pass gives each lookup
  // its pixel's texture-space footprint, as a fragment shader's derivatives would. Each
  // texture reads with its own wrap modes.
  g.samplers_.emplace(ctx, vk::TextureSamplerDesc{mipmaps, mipmaps ? kMaxAnisotropy : 0.0f});
  for (const Texture& t : scene.textures) {
    auto sampler = g.samplers_->forTexture(t);
    if (!sampler) return sampler.error();
    g.textureSamplers_.push_back(*sampler);
  }
  while (g.textureSamplers_.size() < g.textures_.size()) {  // the stand-in white texel
    auto sampler = g.samplers_->repeating();
    if (!sampler) return sampler.error();
    g.textureSamplers_.push_back(*sampler);
  }
  return g;
}

std::vector<VkDescriptorImageInfo> GpuScene::textureInfos() const {
  std::vector<VkDescriptorImageInfo> infos;
  for (std::size_t i = 0; i < textures_.size(); ++i)
    infos.push_back(
        {textureSamplers_[i], textures_[i].view(), VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL});
  return infos;
}

}  // namespace pc::client
