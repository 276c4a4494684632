// Recording an update's GPU work: command buffer and submission, the field upload, and the
// wavefront's passes (trace, shade, shadow rays, resolve, blend).
#include "vulkan_tracer_impl.h"

namespace pc {

void VulkanTracer::Impl::begin() {
  checkCall(vkResetCommandBuffer(cmd, 0), "vkResetCommandBuffer");
  VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  checkCall(vkBeginCommandBuffer(cmd, &bi), "vkBeginCommandBuffer");
  timer.reset(cmd);
  // Host writes (parameters, requests, instance records), and the earlier submissions' writes
  // (the field the last update or slice blended), before any GPU access.
  vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_HOST_BIT | VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT,
                    VK_ACCESS_2_HOST_WRITE_BIT | VK_ACCESS_2_MEMORY_WRITE_BIT,
                    VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT,
                    VK_ACCESS_2_MEMORY_READ_BIT | VK_ACCESS_2_MEMORY_WRITE_BIT);
  recordMirrorCopies();
}

void VulkanTracer::Impl::submitAndWait() {
  checkCall(vkEndCommandBuffer(cmd), "vkEndCommandBuffer");
  VkFence f = fence.get();
  checkCall(vkResetFences(ctx->device(), 1, &f), "vkResetFences");
  ++submissions;
  if (submissions == failSubmission) {
    // VulkanTracerOptions::failSubmission: what a device lost in this submission reports.
    fail(vk::vkErrorMessage("vkQueueSubmit", VK_ERROR_DEVICE_LOST) + " (simulated)");
  }
  checkCall(vk::submitOne(ctx->queue(), cmd, f), "vkQueueSubmit");
  checkCall(vkWaitForFences(ctx->device(), 1, &f, VK_TRUE, UINT64_MAX), "vkWaitForFences");
}

// Uploads what the host changed since the GPU last saw the field: all atlases when this is a
// different field (or version) than the GPU holds, probe records when they differ. `staging`
// keeps the staging buffers alive until the submission finished.
void VulkanTracer::Impl::recordFieldSync(const Field& field, std::vector<vk::Buffer>& staging) {
  const bool atlases = syncedField != &field || syncedVersion != field.version;
  bool recordsDiffer = atlases || syncedRecords.size() != field.probes.size();
  for (std::size_t i = 0; !recordsDiffer && i < field.probes.size(); ++i)
    recordsDiffer = !sameRecord(field.probes[i], syncedRecords[i]);
  if (!atlases && !recordsDiffer) return;
  timer.begin(cmd, "upload");
  auto upload = [&](const vk::Buffer& dst, const void* data, std::size_t bytes) {
    vk::Buffer s = orFail(
        vk::Buffer::create(*ctx, bytes, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, vk::MemoryUsage::Upload),
        "staging");
    s.write(data, bytes);
    VkBufferCopy copy{0, 0, bytes};
    if (bytes > 0) vkCmdCopyBuffer(cmd, s.get(), dst.get(), 1, &copy);
    staging.push_back(std::move(s));
  };
  if (atlases) {
    // rgb texels widened to the GPU's vec4s (field_buffers.glsl).
    const std::vector<float>& rgb = field.irradiance.texels;
    std::vector<float> rgbw(rgb.size() / 3 * 4, 0.0f);
    for (std::size_t t = 0; t < rgb.size() / 3; ++t)
      std::memcpy(&rgbw[4 * t], &rgb[3 * t], 3 * sizeof(float));
    upload(irradiance, rgbw.data(), rgbw.size() * sizeof(float));
    upload(depth, field.depth.texels.data(), field.depth.texels.size() * sizeof(float));
    upload(occlusion, field.occlusion.texels.data(), field.occlusion.texels.size() * sizeof(float));
  }
  std::vector<GpuProbeRecord> gpuRecords(field.probes.size());
  for (std::size_t i = 0; i < field.probes.size(); ++i) gpuRecords[i] = toGpu(field.probes[i]);
  upload(records, gpuRecords.data(), gpuRecords.size() * sizeof(GpuProbeRecord));
  vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT,
                    traceStage | kComputeStage, kShaderRW);
  timer.end(cmd);
}

// Invocations one launch may have: the compute limits and the ray-tracing invocation limit.
std::uint64_t VulkanTracer::Impl::maxLaunchWidth() const {
  const auto& limits = ctx->properties().limits;
  return std::min<std::uint64_t>(
      std::uint64_t(limits.maxComputeWorkGroupCount[0]) * limits.maxComputeWorkGroupSize[0],
      ctx->rayTracingProperties().maxRayDispatchInvocationCount);
}

void VulkanTracer::Impl::recordTrace(int probeCount, int rayCount) {
  if (sdf) return recordSdfTrace(probeCount, rayCount);
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_RAY_TRACING_KHR, tracePipeline.get());
  vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_RAY_TRACING_KHR, pipelineLayout.get(), 0, 1,
                          &traceSet, 0, nullptr);
  // One-dimensional launches (gpu_trace.h: PC_TRACE_TILE_PROBES); whole tiles per launch but
  // the last, so launch order runs on across launches.
  const std::uint64_t rays = std::uint64_t(std::max(rayCount, 1));
  const int maxProbes = std::max(PC_TRACE_TILE_PROBES,
                                 int(std::min<std::uint64_t>(maxLaunchWidth() / rays, 1u << 30)) /
                                     PC_TRACE_TILE_PROBES * PC_TRACE_TILE_PROBES);
  for (int base = 0; base < probeCount; base += maxProbes) {
    const TracePush push{base, std::min(probeCount - base, maxProbes), 0, 0};
    vkCmdPushConstants(cmd, pipelineLayout.get(), shaderStages, 0, sizeof push, &push);
    ctx->rt().cmdTraceRays(cmd, &traceTable.raygen, &traceTable.miss, &traceTable.hit,
                           &traceTable.callable, std::uint32_t(std::uint64_t(push.count) * rays), 1,
                           1);
  }
}

// A dispatch of `groups` workgroups, in rows of PC_DISPATCH_ROWS (the shaders flatten it).
void VulkanTracer::Impl::dispatchRows(std::uint64_t groups) {
  if (groups == 0) return;
  const std::uint64_t rows = (groups + PC_DISPATCH_ROWS - 1) / PC_DISPATCH_ROWS;
  vkCmdDispatch(cmd, std::uint32_t(std::min<std::uint64_t>(groups, PC_DISPATCH_ROWS)),
                std::uint32_t(rows), 1);
}

void VulkanTracer::Impl::recordShade(int probeCount, int rayCount, int slotBase) {
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, shadePipeline.get());
  vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipelineLayout.get(), 0, 1,
                          &traceSet, 0, nullptr);
  const TracePush push{0, 0, slotBase, 0};
  vkCmdPushConstants(cmd, pipelineLayout.get(), shaderStages, 0, sizeof push, &push);
  const std::uint64_t rays = std::uint64_t(probeCount) * std::uint64_t(rayCount);
  dispatchRows((rays + PC_SHADE_THREADS - 1) / PC_SHADE_THREADS);
}

void VulkanTracer::Impl::recordResolve(int probeCount, int rayCount) {
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, resolvePipeline.get());
  vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipelineLayout.get(), 0, 1,
                          &traceSet, 0, nullptr);
  const std::uint64_t rays = std::uint64_t(probeCount) * std::uint64_t(rayCount);
  dispatchRows((rays + PC_SHADE_THREADS - 1) / PC_SHADE_THREADS);
}

// Each slot's shadow list (a light's, or an emissive sample's) has its length only on the GPU
// (its counters, laid out as a VkTraceRaysIndirectCommandKHR). Where the device launches from
// a buffer and the longest list fits one launch, each slot's launch is exactly its list: every
// launch index is a real ray. Elsewhere the launches cover the most a list can hold and the
// ray-generation shader returns past its end, at a cost per invocation. The launches do not
// depend on each other, so nothing separates them.
void VulkanTracer::Impl::recordShadowTrace(int slots, std::uint64_t rayCount, int slotBase) {
  if (sdf) return recordSdfShadows(slots, rayCount, slotBase);
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_RAY_TRACING_KHR, shadowPipeline.get());
  vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_RAY_TRACING_KHR, pipelineLayout.get(), 0, 1,
                          &traceSet, 0, nullptr);
  const std::uint64_t maxWidth = std::min<std::uint64_t>(maxLaunchWidth(), 1u << 30);
  // Per-slot timestamps (VulkanTracerOptions::shadowSlotTimes) in single rounds only: several
  // rounds are one timed span, which they would cut.
  const bool slotTimes = shadowSlotTimes && roundSlots >= shadowSlots();
  for (int slot = 0; slot < slots; ++slot) {
    const std::uint64_t listStart = std::uint64_t(slot) * rayCount;
    if (slotTimes) {
      timer.end(cmd);  // the previous slot's pair
      timer.begin(cmd, "shadow slot " + std::to_string(slotBase + slot));
    }
    if (ctx->rt().cmdTraceRaysIndirect && rayCount <= maxWidth && !boundedShadowLaunch) {
      const TracePush push{int(listStart), int(rayCount), slotBase, 0};
      vkCmdPushConstants(cmd, pipelineLayout.get(), shaderStages, 0, sizeof push, &push);
      ctx->rt().cmdTraceRaysIndirect(
          cmd, &shadowTable.raygen, &shadowTable.miss, &shadowTable.hit, &shadowTable.callable,
          counters.address() + VkDeviceAddress(slotBase + slot) * PC_COUNTER_WORDS * 4);
      continue;
    }
    for (std::uint64_t first = 0; first < rayCount; first += maxWidth) {
      const TracePush push{int(listStart + first), int(std::min(rayCount - first, maxWidth)),
                           slotBase, 0};
      vkCmdPushConstants(cmd, pipelineLayout.get(), shaderStages, 0, sizeof push, &push);
      ctx->rt().cmdTraceRays(cmd, &shadowTable.raygen, &shadowTable.miss, &shadowTable.hit,
                             &shadowTable.callable, std::uint32_t(push.count), 1, 1);
    }
  }
}

// The wavefront (gpu_trace.h): trace, shade, shadow rays, then the blend adds the visible light
// and blends; with more shadow slots than a round holds, shade and shadow rays once per round,
// each round's light added to the rays by the resolve pass.
void VulkanTracer::Impl::recordWavefront(int n, int rayCount) {
  const int slots = shadowSlots();
  const int rounds = pcShadowRounds(slots, roundSlots);
  if (rounds != loggedRounds) {
    if (rounds > 1)
      logInfo("vulkan tracer: " + std::to_string(slots) +
              " shadow slots (lights and emissive samples) in " + std::to_string(rounds) +
              " rounds of " + std::to_string(roundSlots) + ": their records for " +
              std::to_string(std::uint64_t(n) * std::uint64_t(rayCount)) +
              " probe rays exceed the " + std::to_string(shadowMemoryBudget >> 20) +
              " MiB shadow memory budget or, in one buffer, the " +
              std::to_string(maxBufferBytes >> 20) + " MiB storage-buffer range");
    loggedRounds = std::max(rounds, 1);
  }
  timer.begin(cmd, "trace");
  recordTrace(n, rayCount);
  timer.end(cmd);
  vk::memoryBarrier(cmd, traceStage, kShaderRW, kComputeStage, kShaderRW);

  // Several rounds are timed as one span (the timer holds a bounded number of passes).
  const bool roundTimes = rounds <= 1;
  if (!roundTimes) timer.begin(cmd, "shadow rounds");
  for (int round = 0; round < std::max(rounds, 1); ++round) {
    const int slotBase = round * roundSlots;
    if (roundTimes) timer.begin(cmd, "shade");
    recordShade(n, rayCount, slotBase);
    if (roundTimes) timer.end(cmd);
    // The shadow launch may read its size from the counters the shade pass appended to: an
    // indirect-command read, which a plain shader-read barrier does not cover.
    vk::memoryBarrier(cmd, kComputeStage, kShaderRW,
                      traceStage | kComputeStage | VK_PIPELINE_STAGE_2_DRAW_INDIRECT_BIT,
                      kShaderRW | VK_ACCESS_2_INDIRECT_COMMAND_READ_BIT);

    if (slots > 0) {
      if (roundTimes) timer.begin(cmd, "shadow trace");
      recordShadowTrace(std::min(roundSlots, slots - slotBase),
                        std::uint64_t(n) * std::uint64_t(rayCount), slotBase);
      if (roundTimes) timer.end(cmd);
      vk::memoryBarrier(cmd, traceStage, kShaderRW, kComputeStage, kShaderRW);
    }
    if (rounds > 1) {
      // The round's light into the rays, before the next round's shade pass reuses the
      // slots' records (and the blend reads the rays).
      recordResolve(n, rayCount);
      vk::memoryBarrier(cmd, kComputeStage, kShaderRW, kComputeStage, kShaderRW);
    }
  }
  if (!roundTimes) timer.end(cmd);

  timer.begin(cmd, "blend");
  const int groupProbes = pcBlendProbes(rayCount);
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, blendPipeline.get());
  vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipelineLayout.get(), 0, 1, &set, 0,
                          nullptr);
  dispatchRows(std::uint64_t((n + groupProbes - 1) / groupProbes));
  timer.end(cmd);
  vk::memoryBarrier(cmd, kComputeStage, kShaderRW, kComputeStage, kShaderRW);
}

}  // namespace pc
