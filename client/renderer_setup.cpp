// The renderer's creation: render targets, pipelines (graphics and compute) and descriptors,
// remade on resize.
#include <algorithm>

#include "overlay_text.h"
#include "renderer_internal.h"
#include "vk_util.h"

namespace pc::client {

namespace {

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
  // A small slope term: occluders the light grazes (a ceiling under a low sun) would otherwise
  // move behind receivers millimetres away at a junction and let light through along it; the
  // receivers' normal offset (light_pack.cpp) keeps surfaces from shadowing themselves.
  raster.depthBiasConstantFactor = 2.0f;
  raster.depthBiasSlopeFactor = 0.5f;
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

}  // namespace

Renderer::~Renderer() {
  if (ctx_) ctx_->waitIdle();
}

VkResult Renderer::waitIdle() const { return ctx_->waitIdle(); }

namespace {

// The options checked against the device, with the rasterizer Auto picks.
Result<RendererOptions> checkedOptions(const vk::Context& ctx, const RendererOptions& options) {
  if (options.width <= 0 || options.height <= 0) return Error{"render size must be positive"};
  if (options.views != 1 && options.views != 2) return Error{"views must be 1 or 2"};
  if (options.msaa != 2 && options.msaa != 4 && options.msaa != 8)
    return Error{"msaa must be 2, 4 or 8 samples"};
  if (options.views == 2 && !ctx.options().multiview)
    return Error{"stereo needs a Vulkan context created with multiview"};
  VkPhysicalDeviceFeatures features{};
  vkGetPhysicalDeviceFeatures(ctx.physicalDevice(), &features);
  if (!features.geometryShader)
    return Error{
        "the Vulkan device lacks the geometryShader feature, which the client's "
        "visibility buffer needs for primitive ids in fragment shaders"};
  RendererOptions resolved = options;
  VkPhysicalDeviceVulkan12Features v12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
  VkPhysicalDeviceFeatures2 f2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
  f2.pNext = &v12;
  vkGetPhysicalDeviceFeatures2(ctx.physicalDevice(), &f2);
  const bool computeCapable = f2.features.shaderInt64 && v12.shaderBufferInt64Atomics;
  if (options.rasterizer == Rasterizer::Compute && !computeCapable)
    return Error{
        "the compute rasterizer needs shaderInt64 and shaderBufferInt64Atomics, "
        "which this Vulkan device lacks (use the fixed-function rasterizer)"};
  if (options.rasterizer == Rasterizer::Auto)
    resolved.rasterizer = computeCapable ? Rasterizer::Compute : Rasterizer::FixedFunction;
  return resolved;
}

}  // namespace

Result<std::unique_ptr<Renderer>> Renderer::create(const vk::Context& ctx, const Scene& scene,
                                                   FieldMirror& mirror,
                                                   const RendererOptions& options) {
  auto resolved = checkedOptions(ctx, options);
  if (!resolved) return resolved.error();
  std::unique_ptr<Renderer> r(new Renderer);
  r->ctx_ = &ctx;
  r->scene_ = &scene;
  r->emissive_.emplace(scene);
  r->mirror_ = &mirror;
  r->options_ = *resolved;
  r->chooseViewDefaults();
  // Each step uses what the ones before it made: the shadow arrays the light counts, the
  // frame slots the draws and the lights, the descriptors all of it.
  if (Status s = r->createSceneBuffers(); !s) return s.error();
  if (Status s = r->createField(); !s) return s.error();
  r->countLights();
  r->measureDraws();
  if (Status s = r->createSamplers(); !s) return s.error();
  if (Status s = r->createShadowArrays(); !s) return s.error();
  auto pool = vk::CommandPool::create(ctx);
  if (!pool) return pool.error();
  r->commandPool_.emplace(std::move(pool).value());
  if (Status s = r->createTargets(); !s) return s.error();
  if (Status s = r->createPipelines(); !s) return s.error();
  for (int i = 0; i < kFrameSlots; ++i) {
    if (Status s = r->createFrameSlot(); !s) return s.error();
  }
  if (Status s = r->createDescriptorSets(); !s) return s.error();
  if (Status s = r->writeDescriptors(); !s) return s.error();
  return r;
}

void Renderer::chooseViewDefaults() {
  const Scene& scene = *scene_;
  const float diagonal = std::max(glm::length(scene.boundsMax - scene.boundsMin), 1e-3f);
  nearPlane_ = 5e-4f * diagonal;
  if (options_.ambient) {
    ambient_ = *options_.ambient;
  } else {
    ambient_ = scene.sky.ambientIrradiance();
  }
}

// The scene's geometry and textures, and the compute rasterizer's work lists.
Status Renderer::createSceneBuffers() {
  const vk::Context& ctx = *ctx_;
  auto gpuScene = GpuScene::create(ctx, *scene_, options_.textureMipmaps);
  if (!gpuScene) return gpuScene.error();
  gpuScene_.emplace(std::move(gpuScene).value());
  // Visibility ids are 32-bit with 0 for the sky (client_frame.h, DrawData).
  if (gpuScene_->packed().triangleIds >= 0xFFFFFFFFull)
    return Error{"scene has too many triangles over its instances for 32-bit visibility ids"};
  // The compute rasterizer's work lists: a clipped triangle yields a few pieces, most of
  // them small enough for their own thread; tile jobs are capped at 4M (32 MiB). What does
  // not fit is counted (FrameTimings::rasterDropped), never written out of bounds.
  const bool on = computeRaster();
  const std::uint64_t pieces = 2 * gpuScene_->packed().triangleIds * std::uint64_t(options_.views);
  rasterTriangleCapacity_ =
      on ? std::uint32_t(std::min<std::uint64_t>(pieces + 1024, 1u << 22)) : 1;
  rasterJobCapacity_ = on ? (1u << 22) : 1;
  const VkBufferUsageFlags storage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
  auto make = [&](std::size_t bytes, VkBufferUsageFlags usage, vk::Buffer& out) -> Status {
    auto b = vk::Buffer::create(ctx, bytes, usage, vk::MemoryUsage::DeviceLocal);
    if (!b) return b.error();
    out = std::move(b).value();
    return Status::success();
  };
  for (Status st :
       {make(rasterTriangleCapacity_ * sizeof(gpu::RasterTriangle), storage, rasterTriangles_),
        make(rasterJobCapacity_ * sizeof(glm::uvec2), storage, rasterJobs_),
        make(sizeof(gpu::RasterCounters),
             storage | VK_BUFFER_USAGE_TRANSFER_DST_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT |
                 VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT,
             rasterCounters_)}) {
    if (!st) return st.error();
  }
  return Status::success();
}

Status Renderer::createField() {
  const std::optional<gpu::FieldDesc> desc = mirror_->desc();
  brickCount_ = 0;
  for (int k = 0; desc && k < desc->cascadeCount; ++k)
    brickCount_ += std::size_t(gpu::pcBrickCount(desc->cascades[k]));
  auto field = FieldGpu::create(*ctx_, desc, kFrameSlots, options_.bricksPerFrame,
                                options_.fieldFadeSeconds);
  if (!field) return field.error();
  field_.emplace(std::move(field).value());
  // The field present at start-up (a baked file) goes up before the first frame; later bricks
  // stream in through the frames' upload budget.
  mirror_->markAllPending();
  return field_->uploadAll(*mirror_);
}

void Renderer::countLights() {
  const Scene& scene = *scene_;
  // Light and shadow layer counts are fixed by the scene (animation moves lights, never adds).
  const SceneState state0 = evaluateScene(scene, 0.0);
  const LightSet lights0 = buildLights(
      scene, state0, EmissiveLights::build(scene, state0, *emissive_), options_.shadows);
  lightCount_ = int(lights0.lights.size());
  matrixCount_ = int(lights0.matrices.size());
  for (int a = 0; a < kShadowArrays; ++a) shadowLayers_[a] = lights0.layers[a];
  areaLights_ = lights0.areaLightCount;
  shadowCache_.reset(shadowLayers_);
}

void Renderer::measureDraws() {
  // Object-space bounds of every draw's mesh: which shadow layers a moving instance can touch.
  const PackedScene& packed = gpuScene_->packed();
  for (int instance : packed.drawInstances) {
    const MeshRange& m = packed.meshes[scene_->instances[std::size_t(instance)].mesh];
    LocalBounds b{glm::vec3(INFINITY), glm::vec3(-INFINITY)};
    for (std::uint32_t i = m.firstIndex; i < m.firstIndex + m.indexCount; ++i) {
      const glm::vec3 p = packed.vertices[std::size_t(packed.indices[i] + m.vertexOffset)].position;
      b.lo = glm::min(b.lo, p);
      b.hi = glm::max(b.hi, p);
    }
    drawBounds_.push_back(b);
  }
}

Status Renderer::createSamplers() {
  auto linear = createSampler(*ctx_, VK_FILTER_LINEAR, false);
  if (!linear) return linear.error();
  linearSampler_ = std::move(linear).value();
  auto nearest = createSampler(*ctx_, VK_FILTER_NEAREST, false);
  if (!nearest) return nearest.error();
  nearestSampler_ = std::move(nearest).value();
  auto shadow = createSampler(*ctx_, VK_FILTER_LINEAR, true);
  if (!shadow) return shadow.error();
  shadowSampler_ = std::move(shadow).value();
  return Status::success();
}

// Shadow maps: at least one layer each, so the descriptors are always valid. Emitter maps
// are many and small: D16 halves their memory.
Status Renderer::createShadowArrays() {
  if (Status s = createShadowArray(kLargeShadowArray, options_.shadows.largeSize, true); !s)
    return s;
  if (Status s = createShadowArray(kSmallShadowArray, options_.shadows.smallSize, false); !s)
    return s;
  return createShadowArray(kPointShadowArray, options_.shadows.pointSize, true);
}

Status Renderer::createShadowArray(int a, int size, bool large) {
  ShadowArray& sa = shadowArrays_[a];
  sa.size = size;
  sa.large = large;
  const VkFormat format = large ? kLargeShadowFormat : kSmallShadowFormat;
  const int layers = shadowLayers_[a];
  vk::ImageDesc d;
  d.format = format;
  d.width = d.height = std::uint32_t(size);
  d.layers = std::uint32_t(std::max(1, layers));
  d.usage = VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT | VK_IMAGE_USAGE_SAMPLED_BIT;
  auto img = vk::Image::create(*ctx_, d);
  if (!img) return img.error();
  sa.image = std::move(img).value();
  auto view = makeView(*ctx_, sa.image.get(), format, VK_IMAGE_VIEW_TYPE_2D_ARRAY,
                       VK_IMAGE_ASPECT_DEPTH_BIT, 0, d.layers);
  if (!view) return view.error();
  sa.view = std::move(view).value();
  for (std::uint32_t l = 0; l < d.layers; ++l) {
    auto lv = makeView(*ctx_, sa.image.get(), format, VK_IMAGE_VIEW_TYPE_2D,
                       VK_IMAGE_ASPECT_DEPTH_BIT, l, 1);
    if (!lv) return lv.error();
    sa.layerViews.push_back(std::move(lv).value());
  }
  return Status::success();
}

// One frame slot: its command buffer, fence, per-frame buffers and timer.
Status Renderer::createFrameSlot() {
  const vk::Context& ctx = *ctx_;
  const std::size_t drawCount = std::max<std::size_t>(1, gpuScene_->packed().drawInstances.size());
  auto slot = std::make_unique<Slot>();
  auto cmd = commandPool_->allocate();
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
        buffer(std::max(1, lightCount_) * sizeof(gpu::GpuLight), storage, slot->lights),
        buffer(std::max(1, matrixCount_) * sizeof(glm::mat4), storage, slot->matrices),
        buffer(sizeof(gpu::OverlayText), storage, slot->overlay),
        buffer(std::max<std::size_t>(1, brickCount_) * sizeof(float), storage, slot->brickFlash)}) {
    if (!st) return st.error();
  }
  auto stats = vk::Buffer::create(ctx, sizeof(gpu::RasterCounters),
                                  VK_BUFFER_USAGE_TRANSFER_DST_BIT, vk::MemoryUsage::Readback);
  if (!stats) return stats.error();
  slot->rasterStats = std::move(stats).value();
  auto timer = vk::GpuTimer::create(ctx, 16);
  if (!timer) return timer.error();
  slot->timer.emplace(std::move(timer).value());
  slots_.push_back(std::move(slot));
  return Status::success();
}

// One descriptor set per slot: the slot's own buffers, the shared images.
Status Renderer::createDescriptorSets() {
  const VkDevice device = ctx_->device();
  const std::uint32_t textures = std::uint32_t(gpuScene_->textureCount());
  const VkDescriptorPoolSize sizes[] = {
      {VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 2 * kFrameSlots},
      {VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 13 * kFrameSlots},
      {VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, (8 + textures) * kFrameSlots},
      {VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 1 * kFrameSlots}};
  VkDescriptorPoolCreateInfo pi{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  pi.maxSets = kFrameSlots;
  pi.poolSizeCount = 4;
  pi.pPoolSizes = sizes;
  VkDescriptorPool dp = VK_NULL_HANDLE;
  PC_VK_TRY(vkCreateDescriptorPool(device, &pi, nullptr, &dp));
  descriptorPool_ = vk::UniqueDescriptorPool(device, dp);
  for (auto& slot : slots_) {
    VkDescriptorSetAllocateInfo ai{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
    ai.descriptorPool = dp;
    ai.descriptorSetCount = 1;
    const VkDescriptorSetLayout layout = setLayout_.get();
    ai.pSetLayouts = &layout;
    PC_VK_TRY(vkAllocateDescriptorSets(device, &ai, &slot->set));
  }
  return Status::success();
}

Status Renderer::createTargets() {
  const std::uint32_t w = std::uint32_t(options_.width), h = std::uint32_t(options_.height);
  const std::uint32_t layers = std::uint32_t(options_.views);
  const auto samples = static_cast<VkSampleCountFlagBits>(options_.msaa);
  auto make = [&](Target& t, VkFormat format, VkSampleCountFlagBits count, VkImageUsageFlags usage,
                  VkImageAspectFlags aspect, bool sideBySide = false,
                  bool placeholder = false) -> Status {
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
       {make(visibility_, kVisibilityFormat, samples, colorSampled, color, false, computeRaster()),
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
  const std::size_t visBytes =
      computeRaster() ? std::size_t(w) * h * layers * std::size_t(options_.msaa) * 8 : 8;
  auto vis = vk::Buffer::create(
      *ctx_, visBytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
      vk::MemoryUsage::DeviceLocal);
  if (!vis) return vis.error();
  visSamples_ = std::move(vis).value();
  // Two vec4s per pixel and view; a placeholder when the occlusion is off.
  const std::size_t aoBytes = options_.aoRadius > 0.0f ? std::size_t(w) * h * layers * 32 : 32;
  auto ao = vk::Buffer::create(*ctx_, aoBytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                               vk::MemoryUsage::DeviceLocal);
  if (!ao) return ao.error();
  aoSurfaces_ = std::move(ao).value();
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
      {gpu::PC_CLIENT_BIND_FRAME, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1},
      {gpu::PC_CLIENT_BIND_FIELD_DESC, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1},
      {gpu::PC_CLIENT_BIND_DRAWS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1},
      {gpu::PC_CLIENT_BIND_LIGHTS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1},
      {gpu::PC_CLIENT_BIND_SHADOW_MATRICES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1},
      {gpu::PC_CLIENT_BIND_PROBES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1},
      {gpu::PC_CLIENT_BIND_IRRADIANCE, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1},
      {gpu::PC_CLIENT_BIND_DEPTH, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1},
      {gpu::PC_CLIENT_BIND_OCCLUSION, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1},
      {gpu::PC_CLIENT_BIND_SHADOW_MAPS, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, kShadowArrays},
      {gpu::PC_CLIENT_BIND_TEXTURES, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, textures},
      {gpu::PC_CLIENT_BIND_G_VISIBILITY, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1},
      {gpu::PC_CLIENT_BIND_VERTICES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1},
      {gpu::PC_CLIENT_BIND_INDICES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1},
      {gpu::PC_CLIENT_BIND_VIS_SAMPLES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1},
      {gpu::PC_CLIENT_BIND_RASTER_TRIANGLES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1},
      {gpu::PC_CLIENT_BIND_RASTER_JOBS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1},
      {gpu::PC_CLIENT_BIND_RASTER_COUNTERS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1},
      {gpu::PC_CLIENT_BIND_AO_SURFACES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1},
      {gpu::PC_CLIENT_BIND_HDR_IMAGE, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 1},
      {gpu::PC_CLIENT_BIND_HDR_TEXTURE, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1},
      {gpu::PC_CLIENT_BIND_OVERLAY, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1},
      {gpu::PC_CLIENT_BIND_BRICK_FLASH, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1}};
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
  auto dsl = vk::createDescriptorSetLayout(*ctx_, list);
  if (!dsl) return dsl.error();
  setLayout_ = std::move(dsl).value();
  const VkDescriptorSetLayout setLayout = setLayout_.get();
  auto layout = vk::createPipelineLayout(*ctx_, setLayout, VK_SHADER_STAGE_VERTEX_BIT,
                                         sizeof(gpu::ShadowPush));
  if (!layout) return layout.error();
  pipelineLayout_ = std::move(layout).value();
  const VkPipelineLayout pipelineLayout = pipelineLayout_.get();

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
  auto aoSurfaces = load("client_ao_surfaces.comp.spv");
  if (!aoSurfaces) return aoSurfaces.error();
  auto probeView = load("client_probe_view.comp.spv");
  if (!probeView) return probeView.error();

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
  shadow.stages = cutOuts ? stageInfos({{VK_SHADER_STAGE_VERTEX_BIT, shadowVert->get(), &spec},
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
  s = computePipeline(aoSurfaces->get(), &spec, aoSurfacesPipeline_);
  if (!s) return s;
  s = computePipeline(probeView->get(), &spec, probeViewPipeline_);
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
  const VkDescriptorBufferInfo aoSurfacesInfo = aoSurfaces_.descriptor();
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
                                 overlay = slot->overlay.descriptor(),
                                 brickFlash = slot->brickFlash.descriptor();
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
    buffer(gpu::PC_CLIENT_BIND_FRAME, ubo, &frame);
    buffer(gpu::PC_CLIENT_BIND_FIELD_DESC, ubo, &fieldDesc);
    buffer(gpu::PC_CLIENT_BIND_DRAWS, ssbo, &draws);
    buffer(gpu::PC_CLIENT_BIND_LIGHTS, ssbo, &lights);
    buffer(gpu::PC_CLIENT_BIND_SHADOW_MATRICES, ssbo, &matrices);
    buffer(gpu::PC_CLIENT_BIND_PROBES, ssbo, &probes);
    buffer(gpu::PC_CLIENT_BIND_OVERLAY, ssbo, &overlay);
    buffer(gpu::PC_CLIENT_BIND_BRICK_FLASH, ssbo, &brickFlash);
    buffer(gpu::PC_CLIENT_BIND_VERTICES, ssbo, &vertices);
    buffer(gpu::PC_CLIENT_BIND_INDICES, ssbo, &indices);
    buffer(gpu::PC_CLIENT_BIND_VIS_SAMPLES, ssbo, &visSamples);
    buffer(gpu::PC_CLIENT_BIND_RASTER_TRIANGLES, ssbo, &rasterTriangles);
    buffer(gpu::PC_CLIENT_BIND_RASTER_JOBS, ssbo, &rasterJobs);
    buffer(gpu::PC_CLIENT_BIND_RASTER_COUNTERS, ssbo, &rasterCounters);
    buffer(gpu::PC_CLIENT_BIND_AO_SURFACES, ssbo, &aoSurfacesInfo);
    image(gpu::PC_CLIENT_BIND_IRRADIANCE, cis, &irradiance, 1);
    image(gpu::PC_CLIENT_BIND_DEPTH, cis, &depth, 1);
    image(gpu::PC_CLIENT_BIND_OCCLUSION, cis, &occlusion, 1);
    image(gpu::PC_CLIENT_BIND_SHADOW_MAPS, cis, shadows, kShadowArrays);
    image(gpu::PC_CLIENT_BIND_TEXTURES, cis, textures.data(), std::uint32_t(textures.size()));
    image(gpu::PC_CLIENT_BIND_G_VISIBILITY, cis, &gVisibility, 1);
    image(gpu::PC_CLIENT_BIND_HDR_IMAGE, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, &hdrImage, 1);
    image(gpu::PC_CLIENT_BIND_HDR_TEXTURE, cis, &hdrTexture, 1);
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

}  // namespace pc::client
