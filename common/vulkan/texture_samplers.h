// Samplers for the scene's textures: one per pair of wrap modes the textures use
// (Texture::wrapU/wrapV), all with linear filtering. The GPU tracer reads level 0 as
// Texture::sample does; the client's lighting pass reads mip chains (trilinear, anisotropic
// where the device has it).
#pragma once

#include <map>
#include <utility>

#include "common/result.h"
#include "common/scene.h"
#include "context.h"

namespace pc::vk {

struct TextureSamplerDesc {
  bool mipmaps = false;        // false: level 0 only
  float maxAnisotropy = 0.0f;  // 0: off; else capped by the device's limit (if it has the feature)
};

class TextureSamplers {
 public:
  TextureSamplers(const Context& ctx, TextureSamplerDesc desc) : ctx_(&ctx), desc_(desc) {}
  // The sampler for `texture`'s wrap modes, made on first use.
  Result<VkSampler> forTexture(const Texture& texture);
  // The sampler of repeating textures (stand-ins where a scene has no texture).
  Result<VkSampler> repeating();

 private:
  Result<VkSampler> get(TextureWrap u, TextureWrap v);
  const Context* ctx_;
  TextureSamplerDesc desc_;
  std::map<std::pair<TextureWrap, TextureWrap>, UniqueSampler> samplers_;
};

}  // namespace pc::vk
