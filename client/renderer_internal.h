// Internals of the renderer shared by its source files and by nothing else: renderer_setup.cpp
// (creation: targets, pipelines, descriptors) and renderer.cpp (recording and submitting frames).
#pragma once

#include <optional>
#include <vector>

#include "renderer.h"

namespace pc::client {

// The main pass writes per sample, and on GPUs with few graphics units (an H100) those writes
// bound it: a visibility buffer (the triangle's id, 4 bytes) plus depth, instead of a G-buffer
// (20 bytes with depth); the lighting pass rebuilds the surface (client_surface.glsl).
inline constexpr VkFormat kVisibilityFormat = VK_FORMAT_R32_UINT;
inline constexpr VkFormat kDepthFormat = VK_FORMAT_D32_SFLOAT;
inline constexpr VkFormat kHdrFormat = VK_FORMAT_R32G32B32A32_SFLOAT;
inline constexpr VkFormat kOffscreenFormat = VK_FORMAT_R8G8B8A8_UNORM;
inline constexpr VkFormat kLargeShadowFormat = VK_FORMAT_D32_SFLOAT;
inline constexpr VkFormat kSmallShadowFormat =
    VK_FORMAT_D16_UNORM;  // many small maps: half the memory

inline constexpr VkPipelineStageFlags2 kShaderStages =
    VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT | VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT;

struct Renderer::Slot {
  VkCommandBuffer cmd = VK_NULL_HANDLE;
  vk::UniqueFence fence;
  vk::Buffer frame, draws, lights, matrices, overlay;
  vk::Buffer brickFlash;   // float per brick (the probe view)
  vk::Buffer rasterStats;  // the compute rasterizer's counters, copied back at the frame's end
  VkDescriptorSet set = VK_NULL_HANDLE;
  std::optional<vk::GpuTimer> timer;
  std::vector<ShadowView> shadowViews;  // the layers this frame redraws
  bool shadowsFresh = false;            // the arrays have never been drawn: undefined layout
  std::vector<glm::vec3> boxLo, boxHi;  // world bounds of every draw this frame (culling)
  glm::mat4 cameraViews[2];             // the eyes' view-projections (mono: both the same)
  bool submitted = false;
};

}  // namespace pc::client
