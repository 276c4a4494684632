// The renderer's frames: per-frame data, recording the passes (shadows, visibility, lighting
// with the probe field, tone mapping, overlay), submission, timings and offscreen read-back.
#include <algorithm>
#include <chrono>
#include <cstring>

#include "camera.h"
#include "common/log.h"
#include "common/split_sum_table.h"
#include "overlay_text.h"
#include "renderer_internal.h"
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
    case Rasterizer::Auto:
      return "auto";
    case Rasterizer::FixedFunction:
      return "fixed";
    case Rasterizer::Compute:
      return "compute";
  }
  return "?";
}

namespace {

// Depth attachments (shadow maps, the main pass's depth) and colour attachments, as barriers
// name them.
constexpr VkPipelineStageFlags2 kDepthStages =
    VK_PIPELINE_STAGE_2_EARLY_FRAGMENT_TESTS_BIT | VK_PIPELINE_STAGE_2_LATE_FRAGMENT_TESTS_BIT;
constexpr VkAccessFlags2 kDepthAccess =
    VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_READ_BIT | VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT;
constexpr VkPipelineStageFlags2 kColorStage = VK_PIPELINE_STAGE_2_COLOR_ATTACHMENT_OUTPUT_BIT;
constexpr VkAccessFlags2 kColorWrite = VK_ACCESS_2_COLOR_ATTACHMENT_WRITE_BIT;

// Seconds on the clock that paces fades and flashes.
double frameClock(const FrameInput& input) {
  if (input.clock) return *input.clock;
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

void setViewport(VkCommandBuffer cmd, std::uint32_t width, std::uint32_t height) {
  const VkViewport vp{0.0f, 0.0f, float(width), float(height), 0.0f, 1.0f};
  const VkRect2D scissor{{0, 0}, {width, height}};
  vkCmdSetViewport(cmd, 0, 1, &vp);
  vkCmdSetScissor(cmd, 0, 1, &scissor);
}

}  // namespace

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
  SceneState state = evaluateScene(scene, input.time);
  if (input.edited) {
    // A state of another scene (counts that differ) is left aside: the animation goes on.
    SceneState edited = state;
    if (applySceneState(*input.edited, edited)) state = std::move(edited);
  }
  std::vector<gpu::DrawData> draws = drawData(scene, gpuScene_->packed(), state);

  // The sun's cascades follow the cameras (both eyes in stereo).
  ShadowFocus focus;
  focus.cameras.assign(input.cameras.begin(), input.cameras.begin() + options_.views);
  focus.aspect = float(options_.width) / float(options_.height);
  focus.nearPlane = nearPlane_;
  LightSet lights = buildLights(scene, state, EmissiveLights::build(scene, state, *emissive_),
                                options_.shadows, focus);
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
  f.sampleFlags = options_.sampleFlags | (options_.indirectSpecular ? gpu::PC_SAMPLE_SPECULAR : 0);
  f.overlayLines = int(std::min<std::size_t>(input.overlay.size(), gpu::PC_OVERLAY_MAX_LINES));
  f.drawCount = int(draws.size());
  f.triangleCount = std::uint32_t(gpuScene_->packed().triangleIds);
  f.rasterTriangleCapacity = rasterTriangleCapacity_;
  f.rasterJobCapacity = rasterJobCapacity_;
  f.aoRadius = options_.aoRadius;
  f.foveaRadius = options_.foveaRadius;
  f.probeView = probeViewParams(slot, input);
  const SplitSumTable& table = splitSumTable();
  static_assert(sizeof f.splitSum == sizeof table);
  std::memcpy(f.splitSum, table.data(), sizeof table);
  slot.frame.write(&f, sizeof f);
  if (!input.overlay.empty()) {
    const gpu::OverlayText text = makeOverlayText(input.overlay);
    slot.overlay.write(&text, sizeof text);
  }
}

gpu::ProbeViewParams Renderer::probeViewParams(Slot& slot, const FrameInput& input) {
  const ProbeViewSettings& view = input.probeView;
  gpu::ProbeViewParams p{};
  p.mode = view.mode == ProbeViewMode::State        ? gpu::PC_PROBE_VIEW_STATE
           : view.mode == ProbeViewMode::Irradiance ? gpu::PC_PROBE_VIEW_IRRADIANCE
                                                    : gpu::PC_PROBE_VIEW_OFF;
  p.cascade = view.cascade;
  p.offsets = view.offsets ? 1 : 0;
  if (!view.on() || !field_->present()) return p;
  const std::vector<float>& flash = brickFlash_.update(*mirror_, frameClock(input));
  // A mirror whose layout differs from the renderer's (the window rebuilds it) flashes nothing.
  if (flash.size() == brickCount_ && !flash.empty()) {
    slot.brickFlash.write(flash.data(), flash.size() * sizeof(float));
    p.flash = 1;
    p.brickBase = brickFlash_.brickBase();
  }
  return p;
}

void Renderer::recordFrame(VkCommandBuffer cmd, const FrameInput& input,
                           const OutputTarget& target) {
  Slot& slot = *slots_[current_];
  updateFrameData(slot, input);
  vk::GpuTimer& timer = *slot.timer;
  vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pipelineLayout_.get(), 0, 1,
                          &slot.set, 0, nullptr);

  timer.reset(cmd);
  timer.begin(cmd, "upload");
  recordFieldUploads(cmd, input);
  timer.end(cmd);
  timer.begin(cmd, "shadows");
  recordShadowMaps(cmd, slot);
  timer.end(cmd);
  timer.begin(cmd, "main");
  recordVisibility(cmd, slot);
  timer.end(cmd);
  timer.begin(cmd, "probe");
  recordLighting(cmd, slot);
  if (input.probeView.on() && field_->present()) recordProbeView(cmd);
  timer.end(cmd);
  timer.begin(cmd, "tonemap");
  recordTonemap(cmd, target);
  timer.end(cmd);
}

// Draws every draw whose world bounds touch one of the views' frusta (a cube face sees about
// a sixth of a scene, a camera often less).
void Renderer::drawScene(VkCommandBuffer cmd, const Slot& slot,
                         std::initializer_list<glm::mat4> views) {
  const PackedScene& packed = gpuScene_->packed();
  const VkDeviceSize zero = 0;
  const VkBuffer vb = gpuScene_->vertices();
  vkCmdBindVertexBuffers(cmd, 0, 1, &vb, &zero);
  vkCmdBindIndexBuffer(cmd, gpuScene_->indices(), 0, VK_INDEX_TYPE_UINT32);
  for (std::size_t d = 0; d < packed.drawInstances.size(); ++d) {
    if (d < slot.boxLo.size() && std::none_of(views.begin(), views.end(), [&](const glm::mat4& v) {
          return boxTouchesFrustum(v, slot.boxLo[d], slot.boxHi[d]);
        }))
      continue;
    const MeshRange& m = packed.meshes[scene_->instances[packed.drawInstances[d]].mesh];
    // firstInstance carries the draw's index: the shaders read draws[gl_InstanceIndex].
    vkCmdDrawIndexed(cmd, m.indexCount, 1, m.firstIndex, m.vertexOffset, std::uint32_t(d));
    ++stats_.drawCalls;
    stats_.triangles += m.indexCount / 3;
  }
}

void Renderer::recordFieldUploads(VkCommandBuffer cmd, const FrameInput& input) {
  const FieldUploadStats uploads =
      field_->recordUploads(cmd, current_, *mirror_, frameClock(input));
  stats_.bricksUploaded = uploads.bricks;
  stats_.bricksFading = uploads.fading;
}

// Layout changes of the shadow layers drawn this frame (all layers the first time, when the
// arrays are undefined), to depth attachments or back to sampled; the others keep their depth
// and stay readable.
void Renderer::recordShadowBarriers(VkCommandBuffer cmd, const Slot& slot, bool toAttachment) {
  std::vector<VkImageMemoryBarrier2> barriers;
  auto add = [&](VkImage image, std::uint32_t layer, std::uint32_t count) {
    VkImageMemoryBarrier2 b{VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER_2};
    if (toAttachment) {
      b.srcStageMask = kShaderStages;      // read by the lighting pass (compute)
      b.srcAccessMask = VK_ACCESS_2_NONE;  // earlier reads only: an execution dependency
      b.dstStageMask = kDepthStages;
      b.dstAccessMask = kDepthAccess;
      b.oldLayout =
          slot.shadowsFresh ? VK_IMAGE_LAYOUT_UNDEFINED : VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL;
      b.newLayout = VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL;
    } else {
      b.srcStageMask = kDepthStages;
      b.srcAccessMask = kDepthAccess;
      b.dstStageMask = kShaderStages;
      b.dstAccessMask = VK_ACCESS_2_SHADER_SAMPLED_READ_BIT;
      b.oldLayout = VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL;
      b.newLayout = VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL;
    }
    b.srcQueueFamilyIndex = b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    b.image = image;
    b.subresourceRange = {VK_IMAGE_ASPECT_DEPTH_BIT, 0, 1, layer, count};
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
}

// The shadow maps: only the layers whose light or casters changed (ShadowCache).
void Renderer::recordShadowMaps(VkCommandBuffer cmd, const Slot& slot) {
  recordShadowBarriers(cmd, slot, true);
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
    vkCmdPushConstants(cmd, pipelineLayout_.get(), VK_SHADER_STAGE_VERTEX_BIT, 0, sizeof push,
                       &push);
    drawScene(cmd, slot, {v.viewProj});
    vkCmdEndRendering(cmd);
  }
  recordShadowBarriers(cmd, slot, false);
}

// The visibility buffer drawn by the fixed-function pipeline, the depth pre-pass first where
// it is on.
void Renderer::recordFixedFunctionRaster(VkCommandBuffer cmd, const Slot& slot) {
  const std::uint32_t w = std::uint32_t(options_.width), h = std::uint32_t(options_.height);
  // Contents are discarded: the previous frame's probe pass read them (compute stage).
  imageBarriers(
      cmd, {{visibility_.image.get(), VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
             VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
             VK_ACCESS_2_NONE, kColorStage, kColorWrite},
            {depth_.image.get(), VK_IMAGE_ASPECT_DEPTH_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
             VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL, kDepthStages, VK_ACCESS_2_NONE, kDepthStages,
             kDepthAccess}});
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
    drawScene(cmd, slot, {slot.cameraViews[0], slot.cameraViews[1]});
  }
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, scenePipeline_.get());
  drawScene(cmd, slot, {slot.cameraViews[0], slot.cameraViews[1]});
  vkCmdEndRendering(cmd);
}

// The main pass, the visibility buffer: drawn by the compute rasterizer or the fixed-function
// pipeline, then made readable for the lighting pass.
void Renderer::recordVisibility(VkCommandBuffer cmd, Slot& slot) {
  if (computeRaster())
    recordComputeRaster(cmd, slot);
  else
    recordFixedFunctionRaster(cmd, slot);
  // The compute rasterizer leaves the visibility image a never-drawn placeholder.
  ImageBarrier visibilityRead{visibility_.image.get(),
                              VK_IMAGE_ASPECT_COLOR_BIT,
                              VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL,
                              VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL,
                              kColorStage,
                              kColorWrite,
                              VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                              VK_ACCESS_2_SHADER_SAMPLED_READ_BIT};
  if (computeRaster()) visibilityRead.oldLayout = VK_IMAGE_LAYOUT_UNDEFINED;
  imageBarriers(cmd, {visibilityRead,
                      {hdr_.image.get(), VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
                       VK_IMAGE_LAYOUT_GENERAL,
                       VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT | VK_PIPELINE_STAGE_2_COPY_BIT,
                       VK_ACCESS_2_NONE, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                       VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT}});
}

// The lighting pass: direct light and the field, per distinct sample (compute).
void Renderer::recordLighting(VkCommandBuffer cmd, const Slot& slot) {
  const std::uint32_t w = std::uint32_t(options_.width), h = std::uint32_t(options_.height);
  // Bound here: the field's write pass binds its own compute set during the uploads.
  vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipelineLayout_.get(), 0, 1,
                          &slot.set, 0, nullptr);
  const std::uint32_t gx = (w + 7) / 8, gy = (h + 7) / 8, views = std::uint32_t(options_.views);
  if (options_.aoRadius > 0.0f) {
    // The surfaces under the pixel centres, which the occlusion of every pixel reads around
    // it: written once the previous frame's lighting pass is done reading them.
    const VkPipelineStageFlags2 compute = VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT;
    vk::memoryBarrier(cmd, compute, VK_ACCESS_2_NONE, compute, VK_ACCESS_2_NONE);
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, aoSurfacesPipeline_.get());
    vkCmdDispatch(cmd, gx, gy, views);
    vk::memoryBarrier(cmd, compute, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT, compute,
                      VK_ACCESS_2_SHADER_STORAGE_READ_BIT);
  }
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, indirectPipeline_.get());
  vkCmdDispatch(cmd, gx, gy, views);
}

// The probe debug view over the lit frame: after the lighting pass's writes, in the same
// descriptor set (bound for compute by recordLighting).
void Renderer::recordProbeView(VkCommandBuffer cmd) {
  const std::uint32_t w = std::uint32_t(options_.width), h = std::uint32_t(options_.height);
  const VkPipelineStageFlags2 compute = VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT;
  vk::memoryBarrier(cmd, compute, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT, compute,
                    VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT);
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, probeViewPipeline_.get());
  vkCmdDispatch(cmd, (w + 7) / 8, (h + 7) / 8, std::uint32_t(options_.views));
}

// Tone mapping and the overlay into `target`, left in its final layout.
void Renderer::recordTonemap(VkCommandBuffer cmd, const OutputTarget& target) {
  const std::uint32_t w = std::uint32_t(options_.width), h = std::uint32_t(options_.height);
  auto pipeline = tonemapPipeline(target.format);
  imageBarriers(cmd, {{hdr_.image.get(), VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_GENERAL,
                       VK_IMAGE_LAYOUT_GENERAL, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                       VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT,
                       VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT | VK_PIPELINE_STAGE_2_COPY_BIT,
                       VK_ACCESS_2_SHADER_SAMPLED_READ_BIT | VK_ACCESS_2_TRANSFER_READ_BIT},
                      {target.image, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
                       VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, kColorStage, VK_ACCESS_2_NONE,
                       kColorStage, kColorWrite}});
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
                  target.finalLayout, kColorStage, kColorWrite,
                  present ? VK_PIPELINE_STAGE_2_NONE : VK_PIPELINE_STAGE_2_COPY_BIT,
                  present ? VK_ACCESS_2_NONE : VK_ACCESS_2_TRANSFER_READ_BIT}});
}

void Renderer::recordComputeRaster(VkCommandBuffer cmd, Slot& slot) {
  const VkPipelineStageFlags2 compute = VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT;
  const VkAccessFlags2 readWrite =
      VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT;
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
