// The field on the GPU: the three atlases as sampled images (linear filtering, the borders
// make it exact), the probe records as a buffer and the FieldDesc as uniforms. Bricks the
// mirror holds but the GPU lacks are uploaded a bounded number per frame, each through its
// frame slot's staging buffer with one buffer-to-image copy region per run of its tiles, so
// an upload touches only the changed tiles and the frame never waits for it.
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include "common/result.h"
#include "common/vulkan/context.h"
#include "field_mirror.h"

namespace pc::client {

struct FieldUploadStats {
  int bricks = 0;
  std::size_t bytes = 0;
};

class FieldGpu {
 public:
  // Atlases laid out as `desc` says; without a desc, 1x1 placeholders keep every descriptor
  // valid and the shaders use the ambient term.
  static Result<FieldGpu> create(const vk::Context& ctx, const std::optional<gpu::FieldDesc>& desc,
                                 int frameSlots, int bricksPerFrame);

  bool present() const { return present_; }
  // Records the uploads of up to bricksPerFrame pending bricks of `mirror` into `cmd`, using
  // the staging buffer of `slot` (which the caller knows the GPU has finished with).
  FieldUploadStats recordUploads(VkCommandBuffer cmd, int slot, FieldMirror& mirror);
  // Uploads everything pending now, waiting for the GPU: for start-up only, before frames run.
  Status uploadAll(FieldMirror& mirror);

  VkDescriptorImageInfo irradiance(VkSampler s) const;
  VkDescriptorImageInfo depth(VkSampler s) const;
  VkDescriptorImageInfo occlusion(VkSampler s) const;
  VkDescriptorBufferInfo probes() const { return probes_.descriptor(); }
  VkDescriptorBufferInfo descBuffer() const { return desc_.descriptor(); }

 private:
  const vk::Context* ctx_ = nullptr;
  bool present_ = false;
  gpu::FieldDesc fieldDesc_{};
  vk::Image irradiance_, depth_, occlusion_;
  vk::Buffer probes_, desc_;
  std::vector<vk::Buffer> staging_;  // one per frame slot
  int bricksPerFrame_ = 0;
  bool initialized_ = false;  // atlases left UNDEFINED until the first upload or clear
};

// Bytes of staging one brick needs (all atlases and probe records).
std::size_t brickUploadBytes();

}  // namespace pc::client
