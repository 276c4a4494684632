#include "renderer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>

#include "camera.h"
#include "common/log.h"
#include "overlay_text.h"
#include "vk_util.h"

namespace pc::client {

std::optional<Rasterizer> parseRasterizer(std::string_view name) {
  if (name == "auto") return Rasterizer::Auto;
  if (name == "fixed") return Rasterizer::FixedFunction;
  if (name == "compute") return Rasterizer::Compute;
  return std::nullopt;
}

const char* rasterizerName(Rasterizer r) {
  switch (r) {
    case Rasterizer::Auto: return "auto";
    case Rasterizer::FixedFunction: return "fixed";
    case Rasterizer::Compute: return "compute";
  }
  return "?";
}

namespace {

// The main pass writes per sample, and on GPUs with few graphics units (an H100) those writes
// bound it: a visibility buffer (the triangle's id, 4 bytes) plus depth, instead of a G-buffer
// (20 bytes with depth); the lighting pass rebuilds the surface (client_surface.glsl).
constexpr VkFormat kVisibilityFormat = VK_FORMAT_R32_UINT;
constexpr VkFormat kDepthFormat = VK_FORMAT_D32_SFLOAT;
constexpr VkFormat kHdrFormat = VK_FORMAT_R32G32B32A32_SFLOAT;
constexpr VkFormat kOffscreenFormat = VK_FORMAT_R8G8B8A8_UNORM;
constexpr VkFormat kLargeShadowFormat = VK_FORMAT_D32_SFLOAT;
constexpr VkFormat kSmallShadowFormat = VK_FORMAT_D16_UNORM;  // many small maps: half the memory

constexpr VkPipelineStageFlags2 kShaderStages =
    VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT | VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT;

struct ShaderStage {
  VkShaderStageFlagBits stage;
  VkShaderModule module;
  const VkSpecializationInfo* specialization = nullptr;
};

std::vector<VkPipelineShaderStageCreateInfo> stageInfos(std::initializer_list<ShaderStage> stages) {
  std::vector<VkPipelineShaderStageCreateInfo> out;
  for (const ShaderStage& s : stages) {
    VkPipelineShaderStageCreateInfo info{VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
    info.stage = s.stage;
    info.module = s.module;
    info.pName = "main";
    info.pSpecializationInfo = s.specialization;
    out.push_back(info);
  }
  return out;
}

// The fixed-function state the client's graphics pipelines share, filled per pipeline.
struct GraphicsDesc {
  std::vector<VkPipelineShaderStageCreateInfo> stages;
  bool vertexInput = true;  // the packed Vertex layout's position (else no vertex buffer)
  std::vector<VkFormat> colorFormats;
  VkFormat depthFormat = VK_FORMAT_UNDEFINED;
  VkCompareOp depthCompare = VK_COMPARE_OP_GREATER;
  bool depthWrite = true;
  bool colorWrites = true;  // false: depth only, the color attachments untouched
  bool depthBias = false;
  VkSampleCountFlagBits samples = VK_SAMPLE_COUNT_1_BIT;
  std::uint32_t viewMask = 0;
};

Result<vk::UniquePipeline> createGraphicsPipeline(const vk::Context& ctx, VkPipelineLayout layout,
                                                  const GraphicsDesc& d) {
  VkVertexInputBindingDescription binding{0, sizeof(Vertex), VK_VERTEX_INPUT_RATE_VERTEX};
  // Positions only: the lighting pass reads normals and texture coordinates from the
  // vertex buffer itself.
  const VkVertexInputAttributeDescription position{0, 0, VK_FORMAT_R32G32B32_SFLOAT,
                                                   offsetof(Vertex, position)};
  VkPipelineVertexInputStateCreateInfo vertexInput{
      VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO};
  if (d.vertexInput) {
    vertexInput.vertexBindingDescriptionCount = 1;
    vertexInput.pVertexBindingDescriptions = &binding;
    vertexInput.vertexAttributeDescriptionCount = 1;
    vertexInput.pVertexAttributeDescriptions = &position;
  }
  VkPipelineInputAssemblyStateCreateInfo assembly{
      VK_STRUCTURE_TYPE_PIPELINE_INPUT_ASSEMBLY_STATE_CREATE_INFO};
  assembly.topology = VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST;
  VkPipelineViewportStateCreateInfo viewport{VK_STRUCTURE_TYPE_PIPELINE_VIEWPORT_STATE_CREATE_INFO};
  viewport.viewportCount = 1;
  viewport.scissorCount = 1;
  VkPipelineRasterizationStateCreateInfo raster{
      VK_STRUCTURE_TYPE_PIPELINE_RASTERIZATION_STATE_CREATE_INFO};
  raster.polygonMode = VK_POLYGON_MODE_FILL;
  raster.cullMode = VK_CULL_MODE_NONE;  // surfaces are two-sided, as in the CPU renders
  // Front faces are counter-clockwise as the viewer sees them (glTF, OBJ). The projection's
  // y flip and Vulkan's y-down framebuffer cancel in the spec's signed-area rule, so this is
  // the scene's own winding.
  raster.frontFace = VK_FRONT_FACE_COUNTER_CLOCKWISE;
  raster.lineWidth = 1.0f;
  raster.depthBiasEnable = d.depthBias ? VK_TRUE : VK_FALSE;
  raster.depthBiasConstantFactor = 2.0f;
  raster.depthBiasSlopeFactor = 2.0f;
  VkPipelineMultisampleStateCreateInfo multisample{
      VK_STRUCTURE_TYPE_PIPELINE_MULTISAMPLE_STATE_CREATE_INFO};
  multisample.rasterizationSamples = d.samples;
  VkPipelineDepthStencilStateCreateInfo depth{
      VK_STRUCTURE_TYPE_PIPELINE_DEPTH_STENCIL_STATE_CREATE_INFO};
  depth.depthTestEnable = d.depthFormat != VK_FORMAT_UNDEFINED;
  depth.depthWriteEnable = depth.depthTestEnable && d.depthWrite;
  depth.depthCompareOp = d.depthCompare;
  std::vector<VkPipelineColorBlendAttachmentState> blends(d.colorFormats.size());
  for (auto& b : blends) {
    b = {};
    if (d.colorWrites) {
      b.colorWriteMask = VK_COLOR_COMPONENT_R_BIT | VK_COLOR_COMPONENT_G_BIT |
                         VK_COLOR_COMPONENT_B_BIT | VK_COLOR_COMPONENT_A_BIT;
    }
  }
  VkPipelineColorBlendStateCreateInfo blend{
      VK_STRUCTURE_TYPE_PIPELINE_COLOR_BLEND_STATE_CREATE_INFO};
  blend.attachmentCount = std::uint32_t(blends.size());
  blend.pAttachments = blends.data();
  const VkDynamicState dynamics[2] = {VK_DYNAMIC_STATE_VIEWPORT, VK_DYNAMIC_STATE_SCISSOR};
  VkPipelineDynamicStateCreateInfo dynamic{VK_STRUCTURE_TYPE_PIPELINE_DYNAMIC_STATE_CREATE_INFO};
  dynamic.dynamicStateCount = 2;
  dynamic.pDynamicStates = dynamics;
  VkPipelineRenderingCreateInfo rendering{VK_STRUCTURE_TYPE_PIPELINE_RENDERING_CREATE_INFO};
  rendering.viewMask = d.viewMask;
  rendering.colorAttachmentCount = std::uint32_t(d.colorFormats.size());
  rendering.pColorAttachmentFormats = d.colorFormats.data();
  rendering.depthAttachmentFormat = d.depthFormat;

  VkGraphicsPipelineCreateInfo info{VK_STRUCTURE_TYPE_GRAPHICS_PIPELINE_CREATE_INFO};
  info.pNext = &rendering;
  info.stageCount = std::uint32_t(d.stages.size());
  info.pStages = d.stages.data();
  info.pVertexInputState = &vertexInput;
  info.pInputAssemblyState = &assembly;
  info.pViewportState = &viewport;
  info.pRasterizationState = &raster;
  info.pMultisampleState = &multisample;
  info.pDepthStencilState = &depth;
  info.pColorBlendState = &blend;
  info.pDynamicState = &dynamic;
  info.layout = layout;
  VkPipeline pipeline = VK_NULL_HANDLE;
  PC_VK_TRY(vkCreateGraphicsPipelines(ctx.device(), VK_NULL_HANDLE, 1, &info, nullptr, &pipeline));
  return vk::UniquePipeline(ctx.device(), pipeline);
}

Result<vk::UniqueSampler> createSampler(const vk::Context& ctx, VkFilter filter, bool compare) {
  VkSamplerCreateInfo si{VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO};
  si.magFilter = si.minFilter = filter;
  si.mipmapMode = VK_SAMPLER_MIPMAP_MODE_NEAREST;
  si.addressModeU = si.addressModeV = si.addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE;
  si.compareEnable = compare ? VK_TRUE : VK_FALSE;
  si.compareOp = VK_COMPARE_OP_LESS_OR_EQUAL;  // lit where the receiver is not behind the map
  si.maxLod = 0.0f;
  VkSampler sampler = VK_NULL_HANDLE;
  PC_VK_TRY(vkCreateSampler(ctx.device(), &si, nullptr, &sampler));
  return vk::UniqueSampler(ctx.device(), sampler);
}

void setViewport(VkCommandBuffer cmd, std::uint32_t width, std::uint32_t height) {
  const VkViewport vp{0.0f, 0.0f, float(width), float(height), 0.0f, 1.0f};
  const VkRect2D scissor{{0, 0}, {width, height}};
  vkCmdSetViewport(cmd, 0, 1, &vp);
  vkCmdSetScissor(cmd, 0, 1, &scissor);
}

}  // namespace

struct Renderer::Slot {
  VkCommandBuffer cmd = VK_NULL_HANDLE;
  vk::UniqueFence fence;
  vk::Buffer frame, draws, lights, matrices, overlay;
  vk::Buffer rasterStats;  // the compute rasterizer's counters, copied back at the frame's end
  VkDescriptorSet set = VK_NULL_HANDLE;
  std::optional<vk::GpuTimer> timer;
  std::vector<ShadowView> shadowViews;  // the layers this frame redraws
  bool shadowsFresh = false;            // the arrays have never been drawn: undefined layout
  std::vector<glm::vec3> boxLo, boxHi;  // world bounds of every draw this frame (culling)
  glm::mat4 cameraViews[2];             // the eyes' view-projections (mono: both the same)
  bool submitted = false;
};

Renderer::~Renderer() {
  if (ctx_) ctx_->waitIdle();
}

VkResult Renderer::waitIdle() const { return ctx_->waitIdle(); }

Result<std::unique_ptr<Renderer>> Renderer::create(const vk::Context& ctx, const Scene& scene,
                                                   FieldMirror& mirror,
                                                   const RendererOptions& options) {
  if (options.width <= 0 || options.height <= 0) return Error{"render size must be positive"};
  if (options.views != 1 && options.views != 2) return Error{"views must be 1 or 2"};
  if (options.msaa != 2 && options.msaa != 4 && options.msaa != 8)
    return Error{"msaa must be 2, 4 or 8 samples"};
  if (options.views == 2 && !ctx.options().multiview)
    return Error{"stereo needs a Vulkan context created with multiview"};
  VkPhysicalDeviceFeatures features{};
  vkGetPhysicalDeviceFeatures(ctx.physicalDevice(), &features);
  if (!features.geometryShader)
    return Error{"the Vulkan device lacks the geometryShader feature, which the client's "
                 "visibility buffer needs for primitive ids in fragment shaders"};
  RendererOptions resolved = options;
  {
    VkPhysicalDeviceVulkan12Features v12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
    VkPhysicalDeviceFeatures2 f2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
    f2.pNext = &v12;
    vkGetPhysicalDeviceFeatures2(ctx.physicalDevice(), &f2);
    const bool computeCapable = f2.features.shaderInt64 && v12.shaderBufferInt64Atomics;
    if (options.rasterizer == Rasterizer::Compute && !computeCapable)
      return Error{"the compute rasterizer needs shaderInt64 and shaderBufferInt64Atomics, "
                   "which this Vulkan device lacks (use the fixed-function rasterizer)"};
    if (options.rasterizer == Rasterizer::Auto)
      resolved.rasterizer = computeCapable ? Rasterizer::Compute : Rasterizer::FixedFunction;
  }
  std::unique_ptr<Renderer> r(new Renderer);
  r->ctx_ = &ctx;
  r->scene_ = &scene;
  r->mirror_ = &mirror;
  r->options_ = resolved;

  const float diagonal = std::max(glm::length(scene.boundsMax - scene.boundsMin), 1e-3f);
  r->nearPlane_ = 5e-4f * diagonal;
  if (options.ambient) {
    r->ambient_ = *options.ambient;
  } else {
    // A plain ambient term: the irradiance an open sky would give (pi x its mean radiance),
    // or a dim grey in closed, sky-less scenes so their shapes stay visible.
    const Sky& sky = scene.sky;
    const glm::vec3 mean = 0.5f * sky.horizon + 0.25f * (sky.zenith + sky.ground);
    r->ambient_ = sky.isBlack() ? glm::vec3(0.1f) : 3.14159265f * mean;
  }

  auto gpuScene = GpuScene::create(ctx, scene, options.textureMipmaps);
  if (!gpuScene) return gpuScene.error();
  r->gpuScene_.emplace(std::move(gpuScene).value());
  // Visibility ids are 32-bit with 0 for the sky (client_frame.h, DrawData).
  if (r->gpuScene_->packed().triangleIds >= 0xFFFFFFFFull)
    return Error{"scene has too many triangles over its instances for 32-bit visibility ids"};
  {
    // The compute rasterizer's work lists: a clipped triangle yields a few pieces, most of
    // them small enough for their own thread; tile jobs are capped at 4M (32 MiB). What does
    // not fit is counted (FrameTimings::rasterDropped), never written out of bounds.
    const bool on = r->computeRaster();
    const std::uint64_t pieces = 2 * r->gpuScene_->packed().triangleIds * std::uint64_t(options.views);
    r->rasterTriangleCapacity_ = on ? std::uint32_t(std::min<std::uint64_t>(pieces + 1024, 1u << 22)) : 1;
    r->rasterJobCapacity_ = on ? (1u << 22) : 1;
    const VkBufferUsageFlags storage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
    auto make = [&](std::size_t bytes, VkBufferUsageFlags usage, vk::Buffer& out) -> Status {
      auto b = vk::Buffer::create(ctx, bytes, usage, vk::MemoryUsage::DeviceLocal);
      if (!b) return b.error();
      out = std::move(b).value();
      return Status::success();
    };
    for (Status st :
         {make(r->rasterTriangleCapacity_ * sizeof(gpu::RasterTriangle), storage, r->rasterTriangles_),
          make(r->rasterJobCapacity_ * sizeof(glm::uvec2), storage, r->rasterJobs_),
          make(sizeof(gpu::RasterCounters),
               storage | VK_BUFFER_USAGE_TRANSFER_DST_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT |
                   VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT,
               r->rasterCounters_)}) {
      if (!st) return st.error();
    }
  }

  auto field = FieldGpu::create(ctx, mirror.desc(), kFrameSlots, options.bricksPerFrame,
                                options.fieldFadeSeconds);
  if (!field) return field.error();
  r->field_.emplace(std::move(field).value());
  // The field present at start-up (a baked file) goes up before the first frame; later bricks
  // stream in through the frames' upload budget.
  mirror.markAllPending();
  Status uploaded = r->field_->uploadAll(mirror);
  if (!uploaded) return uploaded.error();

  // Light and shadow layer counts are fixed by the scene (animation moves lights, never adds).
  const SceneState state0 = evaluateScene(scene, 0.0);
  const LightSet lights0 =
      buildLights(scene, state0, EmissiveLights::build(scene, state0), options.shadows);
  r->lightCount_ = int(lights0.lights.size());
  r->matrixCount_ = int(lights0.matrices.size());
  for (int a = 0; a < kShadowArrays; ++a) r->shadowLayers_[a] = lights0.layers[a];
  r->areaLights_ = lights0.areaLightCount;
  r->shadowCache_.reset(r->shadowLayers_);
  // Object-space bounds of every draw's mesh: which shadow layers a moving instance can touch.
  {
    const PackedScene& packed = r->gpuScene_->packed();
    for (int instance : packed.drawInstances) {
      const MeshRange& m = packed.meshes[scene.instances[std::size_t(instance)].mesh];
      LocalBounds b{glm::vec3(INFINITY), glm::vec3(-INFINITY)};
      for (std::uint32_t i = m.firstIndex; i < m.firstIndex + m.indexCount; ++i) {
        const glm::vec3 p =
            packed.vertices[std::size_t(packed.indices[i] + m.vertexOffset)].position;
        b.lo = glm::min(b.lo, p);
        b.hi = glm::max(b.hi, p);
      }
      r->drawBounds_.push_back(b);
    }
  }

  auto linear = createSampler(ctx, VK_FILTER_LINEAR, false);
  if (!linear) return linear.error();
  r->linearSampler_ = std::move(linear).value();
  auto nearest = createSampler(ctx, VK_FILTER_NEAREST, false);
  if (!nearest) return nearest.error();
  r->nearestSampler_ = std::move(nearest).value();
  auto shadow = createSampler(ctx, VK_FILTER_LINEAR, true);
  if (!shadow) return shadow.error();
  r->shadowSampler_ = std::move(shadow).value();

  // Shadow maps: at least one layer each, so the descriptors are always valid. Emitter maps
  // are many and small: D16 halves their memory.
  auto shadowArray = [&](int a, int size, bool large) -> Status {
    ShadowArray& sa = r->shadowArrays_[a];
    sa.size = size;
    sa.large = large;
    const VkFormat format = large ? kLargeShadowFormat : kSmallShadowFormat;
    const int layers = r->shadowLayers_[a];
    vk::Image& image = sa.image;
    vk::UniqueImageView& arrayView = sa.view;
    std::vector<vk::UniqueImageView>& layerViews = sa.layerViews;
    vk::ImageDesc d;
    d.format = format;
    d.width = d.height = std::uint32_t(size);
    d.layers = std::uint32_t(std::max(1, layers));
    d.usage = VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT | VK_IMAGE_USAGE_SAMPLED_BIT;
    auto img = vk::Image::create(ctx, d);
    if (!img) return img.error();
    image = std::move(img).value();
    auto view = makeView(ctx, image.get(), format, VK_IMAGE_VIEW_TYPE_2D_ARRAY,
                         VK_IMAGE_ASPECT_DEPTH_BIT, 0, d.layers);
    if (!view) return view.error();
    arrayView = std::move(view).value();
    for (std::uint32_t l = 0; l < d.layers; ++l) {
      auto lv = makeView(ctx, image.get(), format, VK_IMAGE_VIEW_TYPE_2D, VK_IMAGE_ASPECT_DEPTH_BIT,
                         l, 1);
      if (!lv) return lv.error();
      layerViews.push_back(std::move(lv).value());
    }
    return Status::success();
  };
  Status s = shadowArray(kLargeShadowArray, options.shadows.largeSize, true);
  if (!s) return s.error();
  s = shadowArray(kSmallShadowArray, options.shadows.smallSize, false);
  if (!s) return s.error();
  s = shadowArray(kPointShadowArray, options.shadows.pointSize, true);
  if (!s) return s.error();

  auto pool = vk::CommandPool::create(ctx);
  if (!pool) return pool.error();
  r->commandPool_.emplace(std::move(pool).value());

  s = r->createTargets();
  if (!s) return s.error();
  s = r->createPipelines();
  if (!s) return s.error();

  const std::size_t drawCount =
      std::max<std::size_t>(1, r->gpuScene_->packed().drawInstances.size());
  for (int i = 0; i < kFrameSlots; ++i) {
    auto slot = std::make_unique<Slot>();
    auto cmd = r->commandPool_->allocate();
    if (!cmd) return cmd.error();
    slot->cmd = *cmd;
    VkFenceCreateInfo fi{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    fi.flags = VK_FENCE_CREATE_SIGNALED_BIT;
    VkFence fence = VK_NULL_HANDLE;
    PC_VK_TRY(vkCreateFence(ctx.device(), &fi, nullptr, &fence));
    slot->fence = vk::UniqueFence(ctx.device(), fence);
    auto buffer = [&](std::size_t bytes, VkBufferUsageFlags usage, vk::Buffer& out) -> Status {
      auto b = vk::Buffer::create(ctx, bytes, usage, vk::MemoryUsage::Upload);
      if (!b) return b.error();
      out = std::move(b).value();
      return Status::success();
    };
    const VkBufferUsageFlags storage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
    for (Status st :
         {buffer(sizeof(gpu::FrameUniforms), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT, slot->frame),
          buffer(drawCount * sizeof(gpu::DrawData), storage, slot->draws),
          buffer(std::max(1, r->lightCount_) * sizeof(gpu::GpuLight), storage, slot->lights),
          buffer(std::max(1, r->matrixCount_) * sizeof(glm::mat4), storage, slot->matrices),
          buffer(sizeof(gpu::OverlayText), storage, slot->overlay)}) {
      if (!st) return st.error();
    }
    auto stats = vk::Buffer::create(ctx, sizeof(gpu::RasterCounters),
                                    VK_BUFFER_USAGE_TRANSFER_DST_BIT, vk::MemoryUsage::Readback);
    if (!stats) return stats.error();
    slot->rasterStats = std::move(stats).value();
    auto timer = vk::GpuTimer::create(ctx, 16);
    if (!timer) return timer.error();
    slot->timer.emplace(std::move(timer).value());
    r->slots_.push_back(std::move(slot));
  }

  // One descriptor set per slot: the slot's own buffers, the shared images.
  const std::uint32_t textures = std::uint32_t(r->gpuScene_->textureCount());
  const VkDescriptorPoolSize sizes[] = {
      {VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 2 * kFrameSlots},
      {VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 11 * kFrameSlots},
      {VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, (8 + textures) * kFrameSlots},
      {VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 1 * kFrameSlots}};
  VkDescriptorPoolCreateInfo pi{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  pi.maxSets = kFrameSlots;
  pi.poolSizeCount = 4;
  pi.pPoolSizes = sizes;
  VkDescriptorPool dp = VK_NULL_HANDLE;
  PC_VK_TRY(vkCreateDescriptorPool(ctx.device(), &pi, nullptr, &dp));
  r->descriptorPool_ = vk::UniqueDescriptorPool(ctx.device(), dp);
  for (auto& slot : r->slots_) {
    VkDescriptorSetAllocateInfo ai{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
    ai.descriptorPool = dp;
    ai.descriptorSetCount = 1;
    const VkDescriptorSetLayout layout = r->setLayout_.get();
    ai.pSetLayouts = &layout;
    PC_VK_TRY(vkAllocateDescriptorSets(ctx.device(), &ai, &slot->set));
  }
  s = r->writeDescriptors();
  if (!s) return s.error();
  return r;
}

Status Renderer::createTargets() {
  const std::uint32_t w = std::uint32_t(options_.width), h = std::uint32_t(options_.height);
  const std::uint32_t layers = std::uint32_t(options_.views);
  const auto samples = static_cast<VkSampleCountFlagBits>(options_.msaa);
  auto make = [&](Target& t, VkFormat format, VkSampleCountFlagBits count, VkImageUsageFlags usage,
                  VkImageAspectFlags aspect, bool sideBySide = false, bool placeholder = false) -> Status {
    vk::ImageDesc d;
    d.format = format;
    d.width = placeholder ? 1 : sideBySide ? 2 * w : w;
    d.height = placeholder ? 1 : h;
    d.layers = sideBySide ? 1 : layers;
    d.samples = count;
    d.usage = usage;
    auto image = vk::Image::create(*ctx_, d);
    if (!image) return image.error();
    t.image = std::move(image).value();
    auto view =
        makeView(*ctx_, t.image.get(), format, VK_IMAGE_VIEW_TYPE_2D_ARRAY, aspect, 0, d.layers);
    if (!view) return view.error();
    t.arrayView = std::move(view).value();
    return Status::success();
  };
  const VkImageUsageFlags colorSampled =
      VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_SAMPLED_BIT;
  const VkImageAspectFlags color = VK_IMAGE_ASPECT_COLOR_BIT;
  for (Status s :
       // With the compute rasterizer the raster targets are 1x1 placeholders (the lighting
      // pass's descriptors must stay valid).
      {make(visibility_, kVisibilityFormat, samples, colorSampled, color, false,
            computeRaster()),
        make(depth_, kDepthFormat, samples, VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT,
             VK_IMAGE_ASPECT_DEPTH_BIT, false, computeRaster()),
        make(hdr_, kHdrFormat, VK_SAMPLE_COUNT_1_BIT,
             VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_SAMPLED_BIT |
                 VK_IMAGE_USAGE_TRANSFER_SRC_BIT,
             color),
        make(offscreen_, kOffscreenFormat, VK_SAMPLE_COUNT_1_BIT,
             VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT, color,
             sideBySide())}) {
    if (!s) return s;
  }
  const std::size_t visBytes = computeRaster()
                                   ? std::size_t(w) * h * layers * std::size_t(options_.msaa) * 8
                                   : 8;
  auto vis = vk::Buffer::create(*ctx_, visBytes,
                                VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                vk::MemoryUsage::DeviceLocal);
  if (!vis) return vis.error();
  visSamples_ = std::move(vis).value();
  auto rb = vk::Buffer::create(*ctx_, std::size_t(w) * h * layers * (16 + 4),
                               VK_BUFFER_USAGE_TRANSFER_DST_BIT, vk::MemoryUsage::Readback);
  if (!rb) return rb.error();
  readback_ = std::move(rb).value();
  return Status::success();
}

Status Renderer::createPipelines() {
  // ---- layout: one set for everything (client_frame.h), the shadow pass's matrix pushed ----
  const std::uint32_t textures = std::uint32_t(gpuScene_->textureCount());
  struct B {
    int binding;
    VkDescriptorType type;
    std::uint32_t count;
  };
  const B bindings[] = {
      {gpu::PC_BIND_FRAME, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1},
      {gpu::PC_BIND_FIELD_DESC, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1},
      {gpu::PC_BIND_DRAWS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1},
      {gpu::PC_BIND_LIGHTS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1},
      {gpu::PC_BIND_SHADOW_MATRICES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1},
      {gpu::PC_BIND_PROBES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1},
      {gpu::PC_BIND_IRRADIANCE, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1},
      {gpu::PC_BIND_DEPTH, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1},
      {gpu::PC_BIND_OCCLUSION, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1},
      {gpu::PC_BIND_SHADOW_MAPS, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, kShadowArrays},
      {gpu::PC_BIND_TEXTURES, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, textures},
      {gpu::PC_BIND_G_VISIBILITY, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1},
      {gpu::PC_BIND_VERTICES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1},
      {gpu::PC_BIND_INDICES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1},
      {gpu::PC_BIND_VIS_SAMPLES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1},
      {gpu::PC_BIND_RASTER_TRIANGLES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1},
      {gpu::PC_BIND_RASTER_JOBS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1},
      {gpu::PC_BIND_RASTER_COUNTERS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1},
      {gpu::PC_BIND_HDR_IMAGE, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 1},
      {gpu::PC_BIND_HDR_TEXTURE, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1},
      {gpu::PC_BIND_OVERLAY, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1}};
  std::vector<VkDescriptorSetLayoutBinding> list;
  for (const B& b : bindings) {
    VkDescriptorSetLayoutBinding lb{};
    lb.binding = std::uint32_t(b.binding);
    lb.descriptorType = b.type;
    lb.descriptorCount = b.count;
    lb.stageFlags =
        VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT | VK_SHADER_STAGE_COMPUTE_BIT;
    list.push_back(lb);
  }
  VkDescriptorSetLayoutCreateInfo li{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
  li.bindingCount = std::uint32_t(list.size());
  li.pBindings = list.data();
  VkDescriptorSetLayout setLayout = VK_NULL_HANDLE;
  PC_VK_TRY(vkCreateDescriptorSetLayout(ctx_->device(), &li, nullptr, &setLayout));
  setLayout_ = vk::UniqueDescriptorSetLayout(ctx_->device(), setLayout);
  const VkPushConstantRange push{VK_SHADER_STAGE_VERTEX_BIT, 0, sizeof(gpu::ShadowPush)};
  VkPipelineLayoutCreateInfo pli{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
  pli.setLayoutCount = 1;
  pli.pSetLayouts = &setLayout;
  pli.pushConstantRangeCount = 1;
  pli.pPushConstantRanges = &push;
  VkPipelineLayout pipelineLayout = VK_NULL_HANDLE;
  PC_VK_TRY(vkCreatePipelineLayout(ctx_->device(), &pli, nullptr, &pipelineLayout));
  pipelineLayout_ = vk::UniquePipelineLayout(ctx_->device(), pipelineLayout);

  auto load = [&](const char* name) { return vk::loadShader(*ctx_, name); };
  auto sceneVert = load("client_scene.vert.spv");
  if (!sceneVert) return sceneVert.error();
  auto sceneFrag = load("client_scene.frag.spv");
  if (!sceneFrag) return sceneFrag.error();
  auto shadowVert = load("client_shadow.vert.spv");
  if (!shadowVert) return shadowVert.error();
  auto shadowFrag = load("client_shadow.frag.spv");
  if (!shadowFrag) return shadowFrag.error();
  auto indirect = load("client_indirect.comp.spv");
  if (!indirect) return indirect.error();

  // Some drawn material is a cut-out (Material::isCutOut): the rasterizers and shadow maps
  // test coverage (client_surface.glsl), and the fixed-function path drops its pre-pass.
  const bool cutOuts = scene_->hasCutOuts();

  // Specialization constants the client's shaders share (those a shader lacks are ignored):
  // 0 samples per pixel, 1 the scene's texture count, 2 whether the visibility ids come from
  // the compute rasterizer's buffer, 3 whether the scene has cut-outs (client_surface.glsl).
  struct Constants {
    std::int32_t samples, textures;
    VkBool32 visBuffer, cutOuts;
  } const constants{options_.msaa, std::int32_t(textures), computeRaster() ? VK_TRUE : VK_FALSE,
                    cutOuts ? VK_TRUE : VK_FALSE};
  const VkSpecializationMapEntry entries[4] = {
      {0, offsetof(Constants, samples), sizeof(std::int32_t)},
      {1, offsetof(Constants, textures), sizeof(std::int32_t)},
      {2, offsetof(Constants, visBuffer), sizeof(VkBool32)},
      {3, offsetof(Constants, cutOuts), sizeof(VkBool32)}};
  const VkSpecializationInfo spec{4, entries, sizeof constants, &constants};

  const std::uint32_t viewMask = options_.views == 2 ? 0b11u : 0u;
  GraphicsDesc scene;
  scene.stages = stageInfos({{VK_SHADER_STAGE_VERTEX_BIT, sceneVert->get()},
                             {VK_SHADER_STAGE_FRAGMENT_BIT, sceneFrag->get(), &spec}});
  scene.colorFormats = {kVisibilityFormat};
  scene.depthFormat = kDepthFormat;
  scene.depthCompare = VK_COMPARE_OP_GREATER;  // reversed depth: nearer is larger
  scene.samples = static_cast<VkSampleCountFlagBits>(options_.msaa);
  scene.viewMask = viewMask;
  // Without a fragment shader the pre-pass cannot leave cut-outs' open texels out of depth:
  // scenes with cut-outs draw the visibility pass alone.
  if (options_.depthPrepass && !computeRaster() && !cutOuts) {
    // Same vertex shader (invariant position), no fragment shader, no color writes.
    GraphicsDesc prepass = scene;
    prepass.stages = stageInfos({{VK_SHADER_STAGE_VERTEX_BIT, sceneVert->get()}});
    prepass.colorWrites = false;
    auto p = createGraphicsPipeline(*ctx_, pipelineLayout, prepass);
    if (!p) return p.error();
    prepassPipeline_ = std::move(p).value();
    scene.depthCompare = VK_COMPARE_OP_EQUAL;  // only the nearest surface of each sample
    scene.depthWrite = false;
  }
  auto scenePipeline = createGraphicsPipeline(*ctx_, pipelineLayout, scene);
  if (!scenePipeline) return scenePipeline.error();
  scenePipeline_ = std::move(scenePipeline).value();

  GraphicsDesc shadow;
  shadow.stages = cutOuts
                      ? stageInfos({{VK_SHADER_STAGE_VERTEX_BIT, shadowVert->get(), &spec},
                                    {VK_SHADER_STAGE_FRAGMENT_BIT, shadowFrag->get(), &spec}})
                      : stageInfos({{VK_SHADER_STAGE_VERTEX_BIT, shadowVert->get(), &spec}});
  shadow.depthCompare = VK_COMPARE_OP_LESS_OR_EQUAL;
  shadow.depthBias = true;
  shadow.depthFormat = kLargeShadowFormat;
  auto large = createGraphicsPipeline(*ctx_, pipelineLayout, shadow);
  if (!large) return large.error();
  largeShadowPipeline_ = std::move(large).value();
  shadow.depthFormat = kSmallShadowFormat;
  auto small = createGraphicsPipeline(*ctx_, pipelineLayout, shadow);
  if (!small) return small.error();
  smallShadowPipeline_ = std::move(small).value();

  auto computePipeline = [&](VkShaderModule module, const VkSpecializationInfo* spec,
                             vk::UniquePipeline& out) -> Status {
    VkComputePipelineCreateInfo ci{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
    ci.stage = stageInfos({{VK_SHADER_STAGE_COMPUTE_BIT, module, spec}})[0];
    ci.layout = pipelineLayout;
    VkPipeline compute = VK_NULL_HANDLE;
    PC_VK_TRY(vkCreateComputePipelines(ctx_->device(), VK_NULL_HANDLE, 1, &ci, nullptr, &compute));
    out = vk::UniquePipeline(ctx_->device(), compute);
    return Status::success();
  };
  Status s = computePipeline(indirect->get(), &spec, indirectPipeline_);
  if (!s) return s;
  if (computeRaster()) {
    auto raster = load("client_raster.comp.spv");
    if (!raster) return raster.error();
    auto args = load("client_raster_args.comp.spv");
    if (!args) return args.error();
    auto tiles = load("client_raster_tiles.comp.spv");
    if (!tiles) return tiles.error();
    for (Status st : {computePipeline(raster->get(), &spec, rasterPipeline_),
                      computePipeline(args->get(), nullptr, rasterArgsPipeline_),
                      computePipeline(tiles->get(), &spec, rasterTilesPipeline_)}) {
      if (!st) return st;
    }
  }
  return Status::success();
}

Result<VkPipeline> Renderer::tonemapPipeline(VkFormat format) {
  auto it = tonemapPipelines_.find(format);
  if (it != tonemapPipelines_.end()) return it->second.get();
  auto vert = vk::loadShader(*ctx_, "client_fullscreen.vert.spv");
  if (!vert) return vert.error();
  auto frag = vk::loadShader(*ctx_, "client_tonemap.frag.spv");
  if (!frag) return frag.error();
  const VkBool32 sideBySideSpec = sideBySide() ? VK_TRUE : VK_FALSE;
  const VkSpecializationMapEntry entry{0, 0, sizeof(VkBool32)};
  const VkSpecializationInfo spec{1, &entry, sizeof sideBySideSpec, &sideBySideSpec};
  GraphicsDesc d;
  d.stages = stageInfos({{VK_SHADER_STAGE_VERTEX_BIT, vert->get()},
                         {VK_SHADER_STAGE_FRAGMENT_BIT, frag->get(), &spec}});
  d.vertexInput = false;
  d.colorFormats = {format};
  // Side by side: one plain pass over the double-width target, eyes picked by column.
  d.viewMask = options_.views == 2 && !sideBySide() ? 0b11u : 0u;
  auto p = createGraphicsPipeline(*ctx_, pipelineLayout_.get(), d);
  if (!p) return p.error();
  VkPipeline handle = p->get();
  tonemapPipelines_.emplace(format, std::move(p).value());
  return handle;
}

Status Renderer::writeDescriptors() {
  const VkSampler linear = linearSampler_.get();
  VkDescriptorImageInfo shadows[kShadowArrays];
  for (int a = 0; a < kShadowArrays; ++a)
    shadows[a] = {shadowSampler_.get(), shadowArrays_[a].view.get(),
                  VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
  const std::vector<VkDescriptorImageInfo> textures = gpuScene_->textureInfos();
  const VkDescriptorImageInfo irradiance = field_->irradiance(linear);
  const VkDescriptorImageInfo depth = field_->depth(linear);
  const VkDescriptorImageInfo occlusion = field_->occlusion(linear);
  auto sampled = [&](const Target& t, VkImageLayout layout) {
    return VkDescriptorImageInfo{linear, t.arrayView.get(), layout};
  };
  const VkImageLayout readOnly = VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL;
  // Integer ids are only fetched, never filtered.
  const VkDescriptorImageInfo gVisibility{nearestSampler_.get(), visibility_.arrayView.get(),
                                          readOnly};
  const VkDescriptorBufferInfo vertices{gpuScene_->vertices(), 0, VK_WHOLE_SIZE};
  const VkDescriptorBufferInfo indices{gpuScene_->indices(), 0, VK_WHOLE_SIZE};
  const VkDescriptorBufferInfo visSamples = visSamples_.descriptor();
  const VkDescriptorBufferInfo rasterTriangles = rasterTriangles_.descriptor();
  const VkDescriptorBufferInfo rasterJobs = rasterJobs_.descriptor();
  const VkDescriptorBufferInfo rasterCounters = rasterCounters_.descriptor();
  const VkDescriptorImageInfo hdrImage{VK_NULL_HANDLE, hdr_.arrayView.get(),
                                       VK_IMAGE_LAYOUT_GENERAL};
  const VkDescriptorImageInfo hdrTexture = sampled(hdr_, VK_IMAGE_LAYOUT_GENERAL);
  const VkDescriptorBufferInfo fieldDesc = field_->descBuffer();
  const VkDescriptorBufferInfo probes = field_->probes();

  for (auto& slot : slots_) {
    const VkDescriptorBufferInfo frame = slot->frame.descriptor(), draws = slot->draws.descriptor(),
                                 lights = slot->lights.descriptor(),
                                 matrices = slot->matrices.descriptor(),
                                 overlay = slot->overlay.descriptor();
    std::vector<VkWriteDescriptorSet> writes;
    auto buffer = [&](int binding, VkDescriptorType type, const VkDescriptorBufferInfo* info) {
      VkWriteDescriptorSet w{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
      w.dstSet = slot->set;
      w.dstBinding = std::uint32_t(binding);
      w.descriptorCount = 1;
      w.descriptorType = type;
      w.pBufferInfo = info;
      writes.push_back(w);
    };
    auto image = [&](int binding, VkDescriptorType type, const VkDescriptorImageInfo* info,
                     std::uint32_t count) {
      VkWriteDescriptorSet w{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
      w.dstSet = slot->set;
      w.dstBinding = std::uint32_t(binding);
      w.descriptorCount = count;
      w.descriptorType = type;
      w.pImageInfo = info;
      writes.push_back(w);
    };
    const VkDescriptorType ubo = VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER;
    const VkDescriptorType ssbo = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
    const VkDescriptorType cis = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
    buffer(gpu::PC_BIND_FRAME, ubo, &frame);
    buffer(gpu::PC_BIND_FIELD_DESC, ubo, &fieldDesc);
    buffer(gpu::PC_BIND_DRAWS, ssbo, &draws);
    buffer(gpu::PC_BIND_LIGHTS, ssbo, &lights);
    buffer(gpu::PC_BIND_SHADOW_MATRICES, ssbo, &matrices);
    buffer(gpu::PC_BIND_PROBES, ssbo, &probes);
    buffer(gpu::PC_BIND_OVERLAY, ssbo, &overlay);
    buffer(gpu::PC_BIND_VERTICES, ssbo, &vertices);
    buffer(gpu::PC_BIND_INDICES, ssbo, &indices);
    buffer(gpu::PC_BIND_VIS_SAMPLES, ssbo, &visSamples);
    buffer(gpu::PC_BIND_RASTER_TRIANGLES, ssbo, &rasterTriangles);
    buffer(gpu::PC_BIND_RASTER_JOBS, ssbo, &rasterJobs);
    buffer(gpu::PC_BIND_RASTER_COUNTERS, ssbo, &rasterCounters);
    image(gpu::PC_BIND_IRRADIANCE, cis, &irradiance, 1);
    image(gpu::PC_BIND_DEPTH, cis, &depth, 1);
    image(gpu::PC_BIND_OCCLUSION, cis, &occlusion, 1);
    image(gpu::PC_BIND_SHADOW_MAPS, cis, shadows, kShadowArrays);
    image(gpu::PC_BIND_TEXTURES, cis, textures.data(), std::uint32_t(textures.size()));
    image(gpu::PC_BIND_G_VISIBILITY, cis, &gVisibility, 1);
    image(gpu::PC_BIND_HDR_IMAGE, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, &hdrImage, 1);
    image(gpu::PC_BIND_HDR_TEXTURE, cis, &hdrTexture, 1);
    vkUpdateDescriptorSets(ctx_->device(), std::uint32_t(writes.size()), writes.data(), 0, nullptr);
  }
  return Status::success();
}

Status Renderer::resize(int width, int height) {
  if (width <= 0 || height <= 0) return Error{"render size must be positive"};
  if (width == options_.width && height == options_.height) return Status::success();
  PC_VK_TRY(ctx_->waitIdle());
  options_.width = width;
  options_.height = height;
  Status s = createTargets();
  if (!s) return s;
  return writeDescriptors();
}

void Renderer::collectTimings(Slot& slot) {
  if (!slot.submitted) return;
  FrameTimings t;
  for (const auto& [name, ms] : slot.timer->results()) {
    t.valid = true;
    if (name == "upload") t.uploadMs = ms;
    if (name == "shadows") t.shadowMs = ms;
    if (name == "main") t.mainMs = ms;
    if (name == "probe") t.probeMs = ms;
    if (name == "tonemap") t.tonemapMs = ms;
  }
  // A failed invalidate (a lost device) leaves the counters unread; the frame's next call to
  // the device reports the loss.
  if (computeRaster() && slot.rasterStats.invalidate() == VK_SUCCESS) {
    t.rasterDropped = slot.rasterStats.as<const gpu::RasterCounters>()->dropped;
    if (t.rasterDropped > 0 && !rasterDropWarned_) {
      logWarn("compute rasterizer: " + std::to_string(t.rasterDropped) +
              " triangles not drawn this frame (work lists full)");
      rasterDropWarned_ = true;
    }
  }
  timings_ = t;
  slot.submitted = false;
}

Result<VkCommandBuffer> Renderer::beginFrame() {
  current_ = (current_ + 1) % kFrameSlots;
  Slot& slot = *slots_[current_];
  const VkFence fence = slot.fence.get();
  PC_VK_TRY(vkWaitForFences(ctx_->device(), 1, &fence, VK_TRUE, UINT64_MAX));
  collectTimings(slot);
  PC_VK_TRY(vkResetFences(ctx_->device(), 1, &fence));
  PC_VK_TRY(vkResetCommandBuffer(slot.cmd, 0));
  VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  PC_VK_TRY(vkBeginCommandBuffer(slot.cmd, &bi));
  return slot.cmd;
}

void Renderer::updateFrameData(Slot& slot, const FrameInput& input) {
  const Scene& scene = *scene_;
  const SceneState state = evaluateScene(scene, input.time);
  std::vector<gpu::DrawData> draws = drawData(scene, gpuScene_->packed(), state);

  LightSet lights =
      buildLights(scene, state, EmissiveLights::build(scene, state), options_.shadows);
  // Counts are fixed at creation; a scene whose emitters changed count keeps what fits.
  const int lightCount = std::min(int(lights.lights.size()), lightCount_);
  const int matrixCount = std::min(int(lights.matrices.size()), matrixCount_);
  if (lightCount > 0) slot.lights.write(lights.lights.data(), lightCount * sizeof(gpu::GpuLight));
  if (matrixCount > 0) slot.matrices.write(lights.matrices.data(), matrixCount * sizeof(glm::mat4));
  std::vector<ShadowView> views;
  for (const ShadowView& v : lights.views) {
    if (v.layer < shadowLayers_[v.array]) views.push_back(v);
  }
  std::vector<glm::mat4> models(draws.size());
  slot.boxLo.resize(draws.size());
  slot.boxHi.resize(draws.size());
  for (std::size_t d = 0; d < draws.size(); ++d) {
    models[d] = draws[d].model;
    worldBox(models[d], drawBounds_[d], slot.boxLo[d], slot.boxHi[d]);
  }
  slot.shadowsFresh = shadowCache_.fresh();
  slot.shadowViews = shadowCache_.select(views, models, drawBounds_);
  stats_ = {};
  stats_.lights = lightCount;
  stats_.shadowViews = int(views.size());
  stats_.shadowViewsDrawn = int(slot.shadowViews.size());
  stats_.msaa = options_.msaa;

  gpu::FrameUniforms f{};
  for (int v = 0; v < options_.views; ++v) {
    const ViewMatrices m =
        viewMatrices(input.cameras[v], options_.width, options_.height, nearPlane_);
    f.views[v].viewProj = m.viewProj;
    f.views[v].invViewProjFromEye = m.invViewProjFromEye;
    f.views[v].position = glm::vec4(m.position, 1.0f);
    slot.cameraViews[v] = m.viewProj;
  }
  if (options_.views == 1) slot.cameraViews[1] = slot.cameraViews[0];
  // Which views each draw can touch: the compute rasterizer skips the others' triangles.
  for (std::size_t d = 0; d < draws.size(); ++d) {
    int mask = 0;
    for (int v = 0; v < options_.views; ++v) {
      if (boxTouchesFrustum(slot.cameraViews[v], slot.boxLo[d], slot.boxHi[d])) mask |= 1 << v;
    }
    draws[d].textures.z = mask;
  }
  if (!draws.empty()) slot.draws.write(draws.data(), draws.size() * sizeof(gpu::DrawData));
  f.skyZenith = glm::vec4(scene.sky.zenith, 0.0f);
  f.skyHorizon = glm::vec4(scene.sky.horizon, 0.0f);
  f.skyGround = glm::vec4(scene.sky.ground, 0.0f);
  f.ambient = glm::vec4(ambient_, 0.0f);
  f.viewport = glm::vec2(float(options_.width), float(options_.height));
  f.exposure = scene.exposure;
  f.lightCount = lightCount;
  f.viewCount = options_.views;
  f.fieldPresent = field_->present() && options_.sampleField ? 1 : 0;
  f.sampleFlags = options_.sampleFlags;
  f.overlayLines = int(std::min<std::size_t>(input.overlay.size(), gpu::PC_OVERLAY_MAX_LINES));
  f.drawCount = int(draws.size());
  f.triangleCount = std::uint32_t(gpuScene_->packed().triangleIds);
  f.rasterTriangleCapacity = rasterTriangleCapacity_;
  f.rasterJobCapacity = rasterJobCapacity_;
  slot.frame.write(&f, sizeof f);
  if (!input.overlay.empty()) {
    const gpu::OverlayText text = makeOverlayText(input.overlay);
    slot.overlay.write(&text, sizeof text);
  }
}

void Renderer::recordFrame(VkCommandBuffer cmd, const FrameInput& input,
                           const OutputTarget& target) {
  Slot& slot = *slots_[current_];
  updateFrameData(slot, input);
  vk::GpuTimer& timer = *slot.timer;
  const std::uint32_t w = std::uint32_t(options_.width), h = std::uint32_t(options_.height);
  const VkPipelineLayout layout = pipelineLayout_.get();
  const PackedScene& packed = gpuScene_->packed();
  // Draws every draw whose world bounds touch one of the views' frusta (a cube face sees about
  // a sixth of a scene, a camera often less).
  auto drawScene = [&](std::initializer_list<glm::mat4> views) {
    const VkDeviceSize zero = 0;
    const VkBuffer vb = gpuScene_->vertices();
    vkCmdBindVertexBuffers(cmd, 0, 1, &vb, &zero);
    vkCmdBindIndexBuffer(cmd, gpuScene_->indices(), 0, VK_INDEX_TYPE_UINT32);
    for (std::size_t d = 0; d < packed.drawInstances.size(); ++d) {
      if (d < slot.boxLo.size() &&
          std::none_of(views.begin(), views.end(), [&](const glm::mat4& v) {
            return boxTouchesFrustum(v, slot.boxLo[d], slot.boxHi[d]);
          }))
        continue;
      const MeshRange& m = packed.meshes[scene_->instances[packed.drawInstances[d]].mesh];
      // firstInstance carries the draw's index: the shaders read draws[gl_InstanceIndex].
      vkCmdDrawIndexed(cmd, m.indexCount, 1, m.firstIndex, m.vertexOffset, std::uint32_t(d));
      ++stats_.drawCalls;
      stats_.triangles += m.indexCount / 3;
    }
  };
  vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, layout, 0, 1, &slot.set, 0,
                          nullptr);

  timer.reset(cmd);
  timer.begin(cmd, "upload");
  const double clock =
      input.clock
          ? *input.clock
          : std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch())
                .count();
  const FieldUploadStats uploads = field_->recordUploads(cmd, current_, *mirror_, clock);
  stats_.bricksUploaded = uploads.bricks;
  stats_.bricksFading = uploads.fading;
  timer.end(cmd);

  // ---- shadow maps (only the layers whose light or casters changed: ShadowCache) ----
  timer.begin(cmd, "shadows");
  const VkPipelineStageFlags2 depthStages =
      VK_PIPELINE_STAGE_2_EARLY_FRAGMENT_TESTS_BIT | VK_PIPELINE_STAGE_2_LATE_FRAGMENT_TESTS_BIT;
  const VkAccessFlags2 depthAccess = VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_READ_BIT |
                                     VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT;
  const VkImageAspectFlags depthAspect = VK_IMAGE_ASPECT_DEPTH_BIT;
  // Layout changes of the layers drawn this frame (all layers the first time, when the arrays
  // are undefined); the others keep their depth and stay readable.
  auto shadowBarriers = [&](bool toAttachment) {
    std::vector<VkImageMemoryBarrier2> barriers;
    auto add = [&](VkImage image, std::uint32_t layer, std::uint32_t count) {
      VkImageMemoryBarrier2 b{VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER_2};
      if (toAttachment) {
        b.srcStageMask = kShaderStages;   // read by the lighting pass (compute)
        b.srcAccessMask = VK_ACCESS_2_NONE;  // earlier reads only: an execution dependency
        b.dstStageMask = depthStages;
        b.dstAccessMask = depthAccess;
        b.oldLayout = slot.shadowsFresh ? VK_IMAGE_LAYOUT_UNDEFINED
                                        : VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL;
        b.newLayout = VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL;
      } else {
        b.srcStageMask = depthStages;
        b.srcAccessMask = depthAccess;
        b.dstStageMask = kShaderStages;
        b.dstAccessMask = VK_ACCESS_2_SHADER_SAMPLED_READ_BIT;
        b.oldLayout = VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL;
        b.newLayout = VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL;
      }
      b.srcQueueFamilyIndex = b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
      b.image = image;
      b.subresourceRange = {depthAspect, 0, 1, layer, count};
      barriers.push_back(b);
    };
    if (slot.shadowsFresh) {
      for (const ShadowArray& sa : shadowArrays_) add(sa.image.get(), 0, VK_REMAINING_ARRAY_LAYERS);
    } else {
      for (const ShadowView& v : slot.shadowViews)
        add(shadowArrays_[v.array].image.get(), std::uint32_t(v.layer), 1);
    }
    if (barriers.empty()) return;
    VkDependencyInfo di{VK_STRUCTURE_TYPE_DEPENDENCY_INFO};
    di.imageMemoryBarrierCount = std::uint32_t(barriers.size());
    di.pImageMemoryBarriers = barriers.data();
    vkCmdPipelineBarrier2(cmd, &di);
  };
  shadowBarriers(true);
  for (const ShadowView& v : slot.shadowViews) {
    const ShadowArray& sa = shadowArrays_[v.array];
    const bool large = sa.large;
    const std::uint32_t size = std::uint32_t(sa.size);
    VkRenderingAttachmentInfo depth{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
    depth.imageView = sa.layerViews[std::size_t(v.layer)].get();
    depth.imageLayout = VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL;
    depth.loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
    depth.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
    depth.clearValue.depthStencil = {1.0f, 0};
    VkRenderingInfo ri{VK_STRUCTURE_TYPE_RENDERING_INFO};
    ri.renderArea = {{0, 0}, {size, size}};
    ri.layerCount = 1;
    ri.pDepthAttachment = &depth;
    vkCmdBeginRendering(cmd, &ri);
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS,
                      large ? largeShadowPipeline_.get() : smallShadowPipeline_.get());
    setViewport(cmd, size, size);
    const gpu::ShadowPush push{v.fromOrigin, glm::vec4(v.origin, 0.0f)};
    vkCmdPushConstants(cmd, layout, VK_SHADER_STAGE_VERTEX_BIT, 0, sizeof push, &push);
    drawScene({v.viewProj});
    vkCmdEndRendering(cmd);
  }
  shadowBarriers(false);
  timer.end(cmd);

  // ---- main pass: the visibility buffer ----
  timer.begin(cmd, "main");
  const VkPipelineStageFlags2 colorStage = VK_PIPELINE_STAGE_2_COLOR_ATTACHMENT_OUTPUT_BIT;
  const VkAccessFlags2 colorWrite = VK_ACCESS_2_COLOR_ATTACHMENT_WRITE_BIT;
  auto toColor = [&](const Target& t) {
    // Contents are discarded: the previous frame's probe pass read them (compute stage).
    return ImageBarrier{t.image.get(),
                        VK_IMAGE_ASPECT_COLOR_BIT,
                        VK_IMAGE_LAYOUT_UNDEFINED,
                        VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL,
                        VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                        VK_ACCESS_2_NONE,
                        colorStage,
                        colorWrite};
  };
  if (computeRaster()) {
    recordComputeRaster(cmd, slot);
  } else {
    imageBarriers(cmd, {toColor(visibility_),
                        {depth_.image.get(), depthAspect, VK_IMAGE_LAYOUT_UNDEFINED,
                         VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL, depthStages, VK_ACCESS_2_NONE,
                         depthStages, depthAccess}});
    VkRenderingAttachmentInfo visibility{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
    visibility.imageView = visibility_.arrayView.get();
    visibility.imageLayout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL;
    visibility.loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;  // id 0: the sky
    visibility.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
    visibility.clearValue.color.uint32[0] = 0;
    VkRenderingAttachmentInfo depth{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
    depth.imageView = depth_.arrayView.get();
    depth.imageLayout = VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL;
    depth.loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
    depth.storeOp = VK_ATTACHMENT_STORE_OP_DONT_CARE;
    depth.clearValue.depthStencil = {0.0f, 0};  // reversed depth: 0 is infinitely far
    VkRenderingInfo ri{VK_STRUCTURE_TYPE_RENDERING_INFO};
    ri.renderArea = {{0, 0}, {w, h}};
    ri.layerCount = 1;
    ri.viewMask = options_.views == 2 ? 0b11u : 0u;
    ri.colorAttachmentCount = 1;
    ri.pColorAttachments = &visibility;
    ri.pDepthAttachment = &depth;
    vkCmdBeginRendering(cmd, &ri);
    setViewport(cmd, w, h);
    if (prepassPipeline_) {
      vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, prepassPipeline_.get());
      drawScene({slot.cameraViews[0], slot.cameraViews[1]});
    }
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, scenePipeline_.get());
    drawScene({slot.cameraViews[0], slot.cameraViews[1]});
    vkCmdEndRendering(cmd);
  }
  auto toRead = [&](const Target& t) {
    return ImageBarrier{t.image.get(),
                        VK_IMAGE_ASPECT_COLOR_BIT,
                        VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL,
                        VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL,
                        colorStage,
                        colorWrite,
                        VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                        VK_ACCESS_2_SHADER_SAMPLED_READ_BIT};
  };
  // The compute rasterizer leaves the visibility image a never-drawn placeholder.
  ImageBarrier visibilityRead = toRead(visibility_);
  if (computeRaster()) visibilityRead.oldLayout = VK_IMAGE_LAYOUT_UNDEFINED;
  imageBarriers(cmd, {visibilityRead,
                      {hdr_.image.get(), VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
                       VK_IMAGE_LAYOUT_GENERAL,
                       VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT | VK_PIPELINE_STAGE_2_COPY_BIT,
                       VK_ACCESS_2_NONE, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                       VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT}});
  timer.end(cmd);

  // ---- lighting pass: direct light and the field, per distinct sample (compute) ----
  timer.begin(cmd, "probe");
  // Bound here: the field's write pass binds its own compute set during the uploads.
  vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, layout, 0, 1, &slot.set, 0, nullptr);
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, indirectPipeline_.get());
  vkCmdDispatch(cmd, (w + 7) / 8, (h + 7) / 8, std::uint32_t(options_.views));
  timer.end(cmd);

  // ---- tone mapping and overlay ----
  timer.begin(cmd, "tonemap");
  auto pipeline = tonemapPipeline(target.format);
  imageBarriers(cmd, {{hdr_.image.get(), VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_GENERAL,
                       VK_IMAGE_LAYOUT_GENERAL, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                       VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT,
                       VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT | VK_PIPELINE_STAGE_2_COPY_BIT,
                       VK_ACCESS_2_SHADER_SAMPLED_READ_BIT | VK_ACCESS_2_TRANSFER_READ_BIT},
                      {target.image, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
                       VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, colorStage, VK_ACCESS_2_NONE,
                       colorStage, colorWrite}});
  VkRenderingAttachmentInfo out{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
  out.imageView = target.view;
  out.imageLayout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL;
  out.loadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE;  // every pixel is written
  out.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
  const std::uint32_t outWidth = sideBySide() ? 2 * w : w;
  VkRenderingInfo ti{VK_STRUCTURE_TYPE_RENDERING_INFO};
  ti.renderArea = {{0, 0}, {outWidth, h}};
  ti.layerCount = 1;
  ti.viewMask = options_.views == 2 && !sideBySide() ? 0b11u : 0u;
  ti.colorAttachmentCount = 1;
  ti.pColorAttachments = &out;
  if (pipeline) {
    vkCmdBeginRendering(cmd, &ti);
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, *pipeline);
    setViewport(cmd, outWidth, h);
    vkCmdDraw(cmd, 3, 1, 0, 0);
    vkCmdEndRendering(cmd);
  } else {
    logError("tone mapping pipeline: " + pipeline.error().message);
  }
  const bool present = target.finalLayout == VK_IMAGE_LAYOUT_PRESENT_SRC_KHR;
  imageBarriers(cmd,
                {{target.image, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL,
                  target.finalLayout, colorStage, colorWrite,
                  present ? VK_PIPELINE_STAGE_2_NONE : VK_PIPELINE_STAGE_2_COPY_BIT,
                  present ? VK_ACCESS_2_NONE : VK_ACCESS_2_TRANSFER_READ_BIT}});
  timer.end(cmd);
}

void Renderer::recordComputeRaster(VkCommandBuffer cmd, Slot& slot) {
  const VkPipelineStageFlags2 compute = VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT;
  const VkAccessFlags2 readWrite = VK_ACCESS_2_SHADER_STORAGE_READ_BIT |
                                   VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT;
  const VkPipelineLayout layout = pipelineLayout_.get();
  // The previous frame's lighting pass and tile pass are done with the buffers before they
  // are cleared.
  vk::memoryBarrier(
      cmd, compute | VK_PIPELINE_STAGE_2_DRAW_INDIRECT_BIT | VK_PIPELINE_STAGE_2_COPY_BIT,
      VK_ACCESS_2_NONE, VK_PIPELINE_STAGE_2_ALL_TRANSFER_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT);
  // A buffer fill is a "transfer" operation of no named stage (the validation layer places it
  // in the copy stage, not the clear stage): barriers name all transfer stages.
  vkCmdFillBuffer(cmd, visSamples_.get(), 0, VK_WHOLE_SIZE, 0);  // depth 0, id 0: the sky
  vkCmdFillBuffer(cmd, rasterCounters_.get(), 0, VK_WHOLE_SIZE, 0);
  vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_ALL_TRANSFER_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT,
                    compute, readWrite);
  vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, layout, 0, 1, &slot.set, 0, nullptr);
  // Triangle pass: enough groups for one triangle per thread, up to the dimension limit (the
  // shader strides over the rest).
  const std::uint64_t groups =
      (gpuScene_->packed().triangleIds + gpu::PC_RASTER_GROUP - 1) / gpu::PC_RASTER_GROUP;
  stats_.triangles += gpuScene_->packed().triangleIds * std::uint64_t(options_.views);
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, rasterPipeline_.get());
  vkCmdDispatch(cmd, std::uint32_t(std::clamp<std::uint64_t>(groups, 1, gpu::PC_RASTER_MAX_GROUPS)),
                std::uint32_t(options_.views), 1);
  vk::memoryBarrier(cmd, compute, readWrite, compute, readWrite);
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, rasterArgsPipeline_.get());
  vkCmdDispatch(cmd, 1, 1, 1);
  vk::memoryBarrier(cmd, compute, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT,
                    compute | VK_PIPELINE_STAGE_2_DRAW_INDIRECT_BIT,
                    readWrite | VK_ACCESS_2_INDIRECT_COMMAND_READ_BIT);
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, rasterTilesPipeline_.get());
  vkCmdDispatchIndirect(cmd, rasterCounters_.get(), offsetof(gpu::RasterCounters, dispatch));
  // The lighting pass reads the samples; the host reads how many triangles were dropped.
  vk::memoryBarrier(cmd, compute, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT,
                    compute | VK_PIPELINE_STAGE_2_COPY_BIT,
                    VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_TRANSFER_READ_BIT);
  const VkBufferCopy region{0, 0, sizeof(gpu::RasterCounters)};
  vkCmdCopyBuffer(cmd, rasterCounters_.get(), slot.rasterStats.get(), 1, &region);
  vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT,
                    VK_PIPELINE_STAGE_2_HOST_BIT, VK_ACCESS_2_HOST_READ_BIT);
}

Status Renderer::endFrame(VkSemaphore wait, VkSemaphore signal) {
  Slot& slot = *slots_[current_];
  PC_VK_TRY(vkEndCommandBuffer(slot.cmd));
  VkCommandBufferSubmitInfo cb{VK_STRUCTURE_TYPE_COMMAND_BUFFER_SUBMIT_INFO};
  cb.commandBuffer = slot.cmd;
  VkSemaphoreSubmitInfo waitInfo{VK_STRUCTURE_TYPE_SEMAPHORE_SUBMIT_INFO};
  waitInfo.semaphore = wait;
  waitInfo.stageMask = VK_PIPELINE_STAGE_2_COLOR_ATTACHMENT_OUTPUT_BIT;
  VkSemaphoreSubmitInfo signalInfo{VK_STRUCTURE_TYPE_SEMAPHORE_SUBMIT_INFO};
  signalInfo.semaphore = signal;
  signalInfo.stageMask = VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT;
  VkSubmitInfo2 si{VK_STRUCTURE_TYPE_SUBMIT_INFO_2};
  si.commandBufferInfoCount = 1;
  si.pCommandBufferInfos = &cb;
  si.waitSemaphoreInfoCount = wait ? 1 : 0;
  si.pWaitSemaphoreInfos = &waitInfo;
  si.signalSemaphoreInfoCount = signal ? 1 : 0;
  si.pSignalSemaphoreInfos = &signalInfo;
  PC_VK_TRY(vkQueueSubmit2(ctx_->queue(), 1, &si, slot.fence.get()));
  slot.submitted = true;
  return Status::success();
}

Status Renderer::renderFrame(const FrameInput& input) {
  auto cmd = beginFrame();
  if (!cmd) return cmd.error();
  recordFrame(*cmd, input,
              {offscreen_.image.get(), offscreen_.arrayView.get(), kOffscreenFormat,
               VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL});
  return endFrame();
}

Result<Renderer::Readback> Renderer::renderOffscreen(const FrameInput& input) {
  auto cmd = beginFrame();
  if (!cmd) return cmd.error();
  OutputTarget target{offscreen_.image.get(), offscreen_.arrayView.get(), kOffscreenFormat,
                      VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL};
  recordFrame(*cmd, input, target);
  const std::uint32_t w = std::uint32_t(options_.width), h = std::uint32_t(options_.height);
  const std::uint32_t views = std::uint32_t(options_.views);
  const VkDeviceSize hdrBytes = VkDeviceSize(w) * h * views * 16;
  VkBufferImageCopy region{};
  region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, views};
  region.imageExtent = {w, h, 1};
  vkCmdCopyImageToBuffer(*cmd, hdr_.image.get(), VK_IMAGE_LAYOUT_GENERAL, readback_.get(), 1,
                         &region);
  region.bufferOffset = hdrBytes;
  if (sideBySide()) {
    region.imageSubresource.layerCount = 1;
    region.imageExtent.width = 2 * w;
  }
  vkCmdCopyImageToBuffer(*cmd, offscreen_.image.get(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                         readback_.get(), 1, &region);
  vk::memoryBarrier(*cmd, VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT,
                    VK_PIPELINE_STAGE_2_HOST_BIT, VK_ACCESS_2_HOST_READ_BIT);
  Status s = endFrame();
  if (!s) return s.error();
  Slot& slot = *slots_[current_];
  const VkFence fence = slot.fence.get();
  PC_VK_TRY(vkWaitForFences(ctx_->device(), 1, &fence, VK_TRUE, UINT64_MAX));
  PC_VK_TRY(readback_.invalidate());
  collectTimings(slot);

  Readback out;
  const auto* hdr = readback_.as<const float>();
  const auto* ldr = reinterpret_cast<const std::uint8_t*>(readback_.as<const char>() + hdrBytes);
  for (std::uint32_t v = 0; v < views; ++v) {
    Image linear{int(w), int(h)};
    Image8 display;
    display.width = int(w);
    display.height = int(h);
    display.rgb.resize(std::size_t(w) * h * 3);
    const std::size_t base = std::size_t(v) * w * h;
    for (std::size_t i = 0; i < std::size_t(w) * h; ++i) {
      const float* p = hdr + (base + i) * 4;
      linear.pixels[i] = glm::vec3(p[0], p[1], p[2]);
      // Side by side: one image of 2w columns, the left eye in the first w.
      const std::size_t at = sideBySide() ? (i / w) * 2 * w + v * w + i % w : base + i;
      const std::uint8_t* q = ldr + at * 4;
      std::memcpy(&display.rgb[i * 3], q, 3);
    }
    out.linear.push_back(std::move(linear));
    out.display.push_back(std::move(display));
  }
  return out;
}

}  // namespace pc::client
