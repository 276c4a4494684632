// The field on the GPU: the three atlases as sampled images (linear filtering, the borders
// make it exact), the probe records as a buffer and the FieldDesc as uniforms.
//
// Bricks the mirror holds but the GPU lacks are uploaded a bounded number per frame through
// the frame slot's staging buffer, interiors only: they land in per-probe "new value" buffers,
// and a compute pass (client_field_write.comp) writes the brick's bordered tiles into the
// atlases, deriving the borders on the GPU. An upload touches only the changed brick's tiles
// and the frame never waits for it.
//
// A brick the GPU already held fades in: for `fadeSeconds` the pass moves its tiles part of
// the way toward the new values each frame (what is shown at time t is the old value mixed
// with the new one by t / fadeSeconds), so arriving data does not pop. Probe records (states,
// relocation offsets) switch at once. First arrivals are written as they are.
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include "common/field.h"
#include "common/result.h"
#include "common/vulkan/context.h"
#include "field_mirror.h"

namespace pc::client {

struct FieldUploadStats {
  int bricks = 0;         // uploaded this frame
  int fading = 0;         // bricks still fading in after this frame
  std::size_t bytes = 0;  // staged this frame
};

// The atlases as the GPU holds them, converted to float (tests, tools).
struct FieldAtlases {
  Atlas irradiance, depth, occlusion;
};

class FieldGpu {
 public:
  // Atlases laid out as `desc` says; without a desc, 1x1 placeholders keep every descriptor
  // valid and the shaders use the ambient term. `fadeSeconds` <= 0: changed bricks pop in.
  static Result<FieldGpu> create(const vk::Context& ctx, const std::optional<gpu::FieldDesc>& desc,
                                 int frameSlots, int bricksPerFrame, double fadeSeconds = 0.0);

  bool present() const { return present_; }
  // Once per frame: records the uploads of up to bricksPerFrame pending bricks of `mirror`
  // (using the staging buffer of `slot`, which the caller knows the GPU has finished with)
  // and the tile writes of new and fading bricks. `now` (seconds, any steady clock) paces
  // the fades.
  FieldUploadStats recordUploads(VkCommandBuffer cmd, int slot, FieldMirror& mirror, double now);
  // Uploads everything pending now without fading, waiting for the GPU: for start-up only,
  // before frames run.
  Status uploadAll(FieldMirror& mirror);
  // Reads the atlases back (waits for the GPU to go idle first).
  Result<FieldAtlases> download() const;

  VkDescriptorImageInfo irradiance(VkSampler s) const;
  VkDescriptorImageInfo depth(VkSampler s) const;
  VkDescriptorImageInfo occlusion(VkSampler s) const;
  VkDescriptorBufferInfo probes() const { return probes_.descriptor(); }
  VkDescriptorBufferInfo descBuffer() const { return desc_.descriptor(); }

 private:
  struct Fade {
    BrickId id;
    double start = 0;    // when its upload was recorded
    double applied = 0;  // share of the way the atlas has been moved so far
  };
  Status createWritePass(int frameSlots);
  // Records the staging copies and the write pass for `bricks` (uploaded now, written exactly
  // where `fade` is false) plus the running fades.
  FieldUploadStats record(VkCommandBuffer cmd, int slot, FieldMirror& mirror,
                          const std::vector<BrickId>& bricks, double now, bool fade);

  const vk::Context* ctx_ = nullptr;
  bool present_ = false;
  gpu::FieldDesc fieldDesc_{};
  vk::Image irradiance_, depth_, occlusion_;  // GENERAL layout throughout
  vk::Buffer probes_, desc_;
  vk::Buffer irradianceNew_, depthNew_, occlusionNew_;  // interiors per probe slot
  std::vector<vk::Buffer> staging_;                     // one per frame slot
  std::vector<vk::Buffer> writeLists_;                  // FieldWrite[] per frame slot
  int bricksPerFrame_ = 0;
  int maxWrites_ = 0;  // FieldWrite entries per frame (uploads plus fades)
  double fadeSeconds_ = 0;
  std::vector<std::vector<bool>> held_;  // [cascade][brick]: the atlases hold a version
  std::uint64_t placesSerial_ = 0;       // FieldMirror::placesSerial the GPU copy has
  // Records the moved cascades' places (the desc) and all their probe records, when the
  // mirror's cascades moved since the last frame (common/field_scroll.h).
  void recordPlaces(VkCommandBuffer cmd, FieldMirror& mirror);
  std::vector<Fade> fades_;

  vk::UniqueSampler nearest_;
  vk::UniqueDescriptorSetLayout setLayout_;
  vk::UniquePipelineLayout pipelineLayout_;
  vk::UniqueDescriptorPool descriptorPool_;
  std::vector<VkDescriptorSet> sets_;  // per frame slot
  vk::UniquePipeline writePipeline_;
};

// Bytes of staging one brick needs (interiors of all atlases and the probe records).
std::size_t brickUploadBytes();

}  // namespace pc::client
