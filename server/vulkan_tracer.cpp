// The Vulkan tracer's Tracer calls: creation, scene state, updates (in one pass or in slices)
// and reading the changed bricks back into the host field.
#include <tbb/parallel_for.h>

#include "embree_tracer.h"
#include "vulkan_tracer_impl.h"

namespace pc {

static_assert(PC_MAX_RAYS_PER_PROBE == kMaxRaysPerProbe,
              "the blend's shared scratch holds every ray");
// The blend's threads: one per irradiance/occlusion texel, the rest share the depth texels; a
// power-of-two share of them per probe of a group for the reductions.
static_assert(PC_IRRADIANCE_TEXELS == PC_OCCLUSION_TEXELS,
              "irradiance and occlusion share their taps");
static_assert(PC_BLEND_THREADS > PC_IRRADIANCE_TEXELS * PC_IRRADIANCE_TEXELS);
// probe_blend.comp's default scratch (a literal there).
static_assert(PC_MAX_RAYS_PER_PROBE + PC_BLEND_MAX_PROBES == 1028);
static_assert(PC_BLEND_THREADS % PC_BLEND_MAX_PROBES == 0 &&
              PC_TRACE_TILE_PROBES % PC_BLEND_MAX_PROBES == 0);
// A brick's probes must lie in one atlas tile row for the packed row runs (gpu_trace.h).
static_assert(PC_ATLAS_TILES_PER_ROW % PC_PROBES_PER_BRICK == 0);

std::size_t vulkanPassRays(std::size_t maxPassRays, int shadowSlots, std::size_t shadowMemoryBudget,
                           std::size_t maxBufferBytes) {
  // Below this many rays a pass begins to leave a large GPU idle; with pandora's 4 lights on
  // the H200 each further slice of 4.2 M rays cost about 0.15 ms, each further round 0.25.
  constexpr std::size_t kFewestRoundPassRays = std::size_t(1) << 22;
  if (shadowSlots <= 1) return maxPassRays;
  const std::size_t slots = std::size_t(shadowSlots);
  const std::size_t oneRound =
      std::min(shadowMemoryBudget / (slots * (sizeof(GpuShadowRay) + sizeof(GpuShadowLight))),
               maxBufferBytes / (slots * sizeof(GpuShadowRay)));
  return std::min(maxPassRays, std::max(oneRound, kFewestRoundPassRays));
}

Result<std::unique_ptr<VulkanTracer>> VulkanTracer::create(const Scene& scene,
                                                           const TracerOptions& options,
                                                           const VulkanTracerOptions& vulkan) {
  auto impl = std::make_unique<Impl>();
  impl->scene = &scene;
  impl->surfaces.emplace(scene);
  impl->options = options;
  try {
    if (Status s = impl->init(vulkan); !s) return s.error();
  } catch (const Failure& e) {  // the first buffers (ensureRequestCapacity)
    return Error{std::string("vulkan tracer: create: ") + e.what()};
  }
  std::unique_ptr<VulkanTracer> tracer(new VulkanTracer(std::move(impl)));
  if (Status s = tracer->setState(evaluateScene(scene, 0.0)); !s) return s.error();
  return tracer;
}

VulkanTracer::VulkanTracer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

VulkanTracer::~VulkanTracer() {
  // A lost device reports an error here, and the resources go all the same.
  if (impl_ && impl_->ctx) {
    const VkResult r = impl_->ctx->waitIdle();
    if (r != VK_SUCCESS && impl_->failure.empty())
      logWarn("vulkan tracer: " + vk::vkErrorMessage("vkDeviceWaitIdle", r) + " at shutdown");
  }
}

std::string VulkanTracer::name() const {
  return std::string(impl_->sdf ? "sdf (" : "vulkan (") + impl_->ctx->deviceName() + ")";
}

const vk::Context& VulkanTracer::context() const { return *impl_->ctx; }

Status VulkanTracer::setState(const SceneState& state) {
  return impl_->guarded("setState", [&] { setStateOnce(state); });
}

void VulkanTracer::setStateOnce(const SceneState& state) {
  Impl& m = *impl_;
  const Scene& scene = *m.scene;
  m.state = state;
  // Shading records and the top level. Static instances stay where they were at time 0, as in
  // the Embree scene: their vertices are already in world space.
  auto* gi = m.instances.as<GpuInstance>();
  std::vector<TopLevelInstance> top;
  if (m.staticCount > 0) top.push_back({glm::mat4(1.0f), -1, 0u});
  for (std::size_t r = 0; r < m.recordInstance.size(); ++r) {
    const std::size_t i = std::size_t(m.recordInstance[r]);
    const bool isStatic = int(r) < m.staticCount;
    const glm::mat4 t = isStatic                              ? glm::mat4(1.0f)
                        : i < state.instanceTransforms.size() ? state.instanceTransforms[i]
                                                              : scene.instances[i].transform;
    GpuInstance g{};
    g.objectToWorld = t;
    g.normalToWorld = glm::mat4(glm::transpose(glm::inverse(glm::mat3(t))));
    g.mesh = isStatic ? m.staticMeshes[r] : scene.instances[i].mesh;
    // The Embree scene fixes the winding from the time-0 transform; so does this.
    g.side = glm::determinant(glm::mat3(scene.instances[i].transform)) < 0.0f ? -1.0f : 1.0f;
    gi[r] = g;
    if (!isStatic) top.push_back({t, scene.instances[i].mesh, std::uint32_t(r)});
  }
  if (m.sdf) {
    // The distance field is rebuilt at the next update where an animated instance moved.
    std::vector<glm::mat4> transforms;
    for (const TopLevelInstance& t : top)
      if (t.mesh >= 0) transforms.push_back(t.transform);
    if (transforms != m.sdfTransforms) m.sdfDirty = true;
    m.sdfTransforms = std::move(transforms);
  } else {
    m.accel.setInstances(top);
    m.tlasDirty = true;
  }

  // Lights, and emissive triangles by the same rule as the CPU (EmissiveLights).
  const std::vector<GpuLight> lights = packLights(state);
  const EmissiveLights emissive = EmissiveLights::build(scene, state, *m.surfaces);
  std::vector<GpuEmissiveTriangle> tris;
  for (std::size_t k = 0; k < emissive.triangles().size(); ++k) {
    const EmissiveLights::Triangle& t = emissive.triangles()[k];
    GpuEmissiveTriangle g{};
    g.p0 = t.p0;
    g.e1 = t.e1;
    g.e2 = t.e2;
    g.normal = t.normal;
    g.area = t.area;
    g.radiance = t.radiance;
    g.cdf = emissive.cdf()[k];
    tris.push_back(g);
  }
  auto* mat = m.materials.as<GpuMaterial>();
  for (std::size_t i = 0; i < scene.materials.size(); ++i) {
    const Material& s = scene.materials[i];
    const auto tex = [&](int t) {
      return t >= 0 && std::size_t(t) < scene.textures.size() ? t : -1;
    };
    GpuMaterial g{};
    g.baseColor = s.baseColor;
    g.baseColorTexture = tex(s.baseColorTexture);
    g.emissive = s.emissive * state.emissionScaleOf(int(i));  // runtime edits' factor
    g.emissiveTexture = tex(s.emissiveTexture);
    g.sampled = emissive.sampled(int(i)) ? 1 : 0;
    g.alphaTexture = tex(s.alphaTexture);
    g.alphaChannel = std::clamp(s.alphaChannel, 0, 3);
    g.alphaCutoff = s.isCutOut() ? s.alphaCutoff : 0.0f;
    g.baseAlpha = s.baseAlpha;
    g.metallic = s.metallic;
    g.roughness = s.roughness;
    g.metallicRoughnessTexture = tex(s.metallicRoughnessTexture);
    if (g.alphaTexture >= 0) {
      g.alphaWrapU = int(scene.textures[g.alphaTexture].wrapU);
      g.alphaWrapV = int(scene.textures[g.alphaTexture].wrapV);
    }
    mat[i] = g;
  }
  // Sized exactly so the parameter counts follow from the sizes; replaced only when they change.
  auto replace = [&](vk::Buffer& b, const void* data, std::size_t bytes) {
    if (b.get() && b.size() == bytes) {
      b.write(data, bytes);
      return;
    }
    checkCall(vkDeviceWaitIdle(m.ctx->device()), "vkDeviceWaitIdle");
    b = orFail(vk::Buffer::create(*m.ctx, bytes, kHostInput, vk::MemoryUsage::Upload),
               "scene state");
    b.write(data, bytes);
    m.descriptorsDirty = true;
  };
  replace(m.lights, lights.data(), lights.size() * sizeof(GpuLight));
  replace(m.emissive, tris.data(), tris.size() * sizeof(GpuEmissiveTriangle));
}

Result<UpdateStats> VulkanTracer::update(Field& field, const UpdateRequest& request) {
  // The compute blend writes octahedral tiles only; SH projection runs on the Embree path.
  for (int k = 0; k < field.cascadeCount(); ++k) {
    if (field.encoding(k) != gpu::PC_ENCODING_OCTAHEDRAL)
      return Error{"vulkan tracer: cascade " + std::to_string(k) + " is encoded " +
                   probeEncodingName(ProbeEncoding(field.encoding(k))) +
                   "; the GPU blend writes octahedral tiles only: trace SH cascades with the "
                   "Embree backend"};
  }
  return impl_->guarded("update", [&] {
    UpdateStats stats = updateOnce(field, request);
    if (impl_->ldm) impl_->applyLdmOcclusion(field, request, stats);
    return stats;
  });
}

// The host field is written only after the last submission completed, so a failure in any of
// them leaves it as the previous update left it.
UpdateStats VulkanTracer::updateOnce(Field& field, const UpdateRequest& request) {
  Impl& m = *impl_;
  UpdateStats stats;
  const auto t0 = Clock::now();
  const int rayCount = field.settings.raysPerProbe;
  const std::size_t total = request.probes.size();
  if (total == 0) return stats;
  if (Status s = m.ensureBlendPipeline(rayCount); !s) fail("blend pipeline: " + s.error().message);
  // One submission per slice of the request's probes; one slice unless the request holds more
  // probe rays than a pass (vulkanPassRays). The brick flags and list gather every slice's
  // changed bricks, packed and read back after the last.
  const std::size_t perSlice = m.sliceProbes(total, rayCount);
  const bool sliced = total > perSlice;
  if (sliced && !m.loggedSlices) {
    logInfo("vulkan tracer: an update of " + std::to_string(total) + " probes x " +
            std::to_string(rayCount) + " rays runs in " +
            std::to_string((total + perSlice - 1) / perSlice) + " slices of up to " +
            std::to_string(perSlice) + " probes: more probe rays than one pass holds (" +
            std::to_string(vulkanPassRays(m.maxPassRays, m.shadowSlots(), m.shadowMemoryBudget,
                                          m.maxBufferBytes)) +
            ")");
    m.loggedSlices = true;
  }
  m.ensureSdf();
  std::vector<vk::Buffer> staging;
  for (std::size_t first = 0; first < total; first += perSlice) {
    const int n = int(std::min(perSlice, total - first));
    const bool firstSlice = first == 0, lastSlice = first + std::size_t(n) == total;
    m.writeUpdateInputs(field, request, first, std::size_t(n), firstSlice, sliced);
    m.begin();
    VkCommandBuffer cmd = m.cmd;
    if (firstSlice) {
      m.recordFieldSync(field, staging);
      if (!m.sdf && m.tlasDirty) {
        m.timer.begin(cmd, "tlas");
        m.accel.recordTopLevelBuild(cmd);
        m.timer.end(cmd);
        m.tlasDirty = false;
      }
      // Clear the change list; the taps serve every slice.
      vkCmdFillBuffer(cmd, m.brickFlags.get(), 0, VK_WHOLE_SIZE, 0);
      const std::uint32_t header[PC_BRICK_LIST_HEADER] = {0, 1, 1};
      vkCmdUpdateBuffer(cmd, m.brickList.get(), 0, sizeof header, header);
      const VkBufferCopy tapCopy{0, 0, m.tapBytes};
      vkCmdCopyBuffer(cmd, m.tapsUpload.get(), m.taps.get(), 1, &tapCopy);
      if (sliced) {
        m.timer.begin(cmd, "snapshot");
        m.recordSnapshot();
        m.timer.end(cmd);
      }
    }
    // The shadow lists' counters start each slice empty.
    const VkBufferCopy counterCopy{0, 0, m.counters.size()};
    vkCmdCopyBuffer(cmd, m.countersInit.get(), m.counters.get(), 1, &counterCopy);
    vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_CLEAR_BIT | VK_PIPELINE_STAGE_2_COPY_BIT,
                      VK_ACCESS_2_TRANSFER_WRITE_BIT,
                      m.traceStage | kComputeStage | VK_PIPELINE_STAGE_2_DRAW_INDIRECT_BIT,
                      kShaderRW | VK_ACCESS_2_INDIRECT_COMMAND_READ_BIT);
    m.recordWavefront(n, rayCount);

    // Changed bricks: this slice's into the list; after the last, the list packed for the host.
    m.timer.begin(cmd, "changes");
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, m.changesPipeline.get());
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, m.pipelineLayout.get(), 0, 1,
                            &m.set, 0, nullptr);
    vkCmdDispatch(cmd, std::uint32_t((n + 63) / 64), 1, 1);
    if (lastSlice) {
      vk::memoryBarrier(cmd, kComputeStage, kShaderRW,
                        kComputeStage | VK_PIPELINE_STAGE_2_DRAW_INDIRECT_BIT,
                        kShaderRW | VK_ACCESS_2_INDIRECT_COMMAND_READ_BIT);
      vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, m.packPipeline.get());
      vkCmdDispatchIndirect(cmd, m.brickList.get(), 0);
    }
    m.timer.end(cmd);
    vk::memoryBarrier(cmd, kComputeStage, kShaderRW, VK_PIPELINE_STAGE_2_COPY_BIT,
                      VK_ACCESS_2_TRANSFER_READ_BIT);

    m.timer.begin(cmd, "readback");
    if (lastSlice) {
      const VkBufferCopy recordCopy{0, 0, m.records.size()};
      vkCmdCopyBuffer(cmd, m.records.get(), m.recordsReadback.get(), 1, &recordCopy);
      const VkBufferCopy listCopy{0, 0, m.brickList.size()};
      vkCmdCopyBuffer(cmd, m.brickList.get(), m.brickListReadback.get(), 1, &listCopy);
    }
    vkCmdCopyBuffer(cmd, m.counters.get(), m.countersReadback.get(), 1, &counterCopy);
    m.timer.end(cmd);
    vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_COPY_BIT | kComputeStage,
                      VK_ACCESS_2_TRANSFER_WRITE_BIT | kShaderRW, VK_PIPELINE_STAGE_2_HOST_BIT,
                      VK_ACCESS_2_HOST_READ_BIT);
    m.submitAndWait();

    checkCall(m.countersReadback.invalidate(), "vkInvalidateMappedMemoryRanges (counters)");
    const auto* counts = m.countersReadback.as<std::uint32_t>();
    for (int s = 0; s < m.shadowSlots(); ++s) {
      stats.shadowRays += counts[s * PC_COUNTER_WORDS];  // the lists' lengths
      if (m.shadowSlotTimes)
        logInfo("shadow slot " + std::to_string(s) + ": " +
                std::to_string(counts[s * PC_COUNTER_WORDS]) + " rays");
    }
    // Each pass's time summed over the slices, in the order the passes first ran.
    for (const auto& [name, ms] : m.timer.results()) {
      auto it = std::find_if(stats.gpuPasses.begin(), stats.gpuPasses.end(),
                             [&](const auto& p) { return p.first == name; });
      if (it == stats.gpuPasses.end())
        stats.gpuPasses.emplace_back(name, ms);
      else
        it->second += ms;
    }
    stats.readbackBytes += m.counters.size();
  }
  staging.clear();

  // ---- back on the host: changed bricks, records, counters ----
  const auto th = Clock::now();
  checkCall(m.brickListReadback.invalidate(), "vkInvalidateMappedMemoryRanges (brick list)");
  checkCall(m.recordsReadback.invalidate(), "vkInvalidateMappedMemoryRanges (probe records)");
  checkCall(m.packed.invalidate(), "vkInvalidateMappedMemoryRanges (packed bricks)");
  const auto* list = m.brickListReadback.as<std::uint32_t>();
  const std::uint32_t changed = list[0];
  const float* packed = m.packed.as<float>();
  const std::uint64_t next = field.version + 1;
  // Each packed brick is row runs of the atlases (gpu_trace.h): one memcpy per run, bricks in
  // parallel (they touch disjoint atlas texels).
  const int si = PC_IRRADIANCE_TEXELS + 2, sd = PC_DEPTH_TEXELS + 2, so = PC_OCCLUSION_TEXELS + 2;
  const std::size_t ri = std::size_t(PC_PROBES_PER_BRICK) * si * 3,
                    rd = std::size_t(PC_PROBES_PER_BRICK) * sd * 2,
                    ro = std::size_t(PC_PROBES_PER_BRICK) * so;
  auto unpack = [&](std::uint32_t e) {
    const int brick = int(list[PC_BRICK_LIST_HEADER + e]);
    int k = 0;
    while (k + 1 < field.cascadeCount() && brick >= m.brickOffset[k + 1]) ++k;
    const int localBrick = brick - m.brickOffset[k];
    const CascadeDesc& c = field.cascade(k);
    const int firstSlot = localBrick * PC_PROBES_PER_BRICK;
    const float* src = packed + std::size_t(e) * PC_PROBES_PER_BRICK * PC_PACKED_PROBE_FLOATS;
    const glm::ivec2 oi = pcAtlasTileOrigin(c, firstSlot, si);
    for (int y = 0; y < si; ++y, src += ri)
      std::memcpy(field.irradiance.at(oi.x, oi.y + y), src, ri * 4);
    const glm::ivec2 od = pcAtlasTileOrigin(c, firstSlot, sd);
    for (int y = 0; y < sd; ++y, src += rd)
      std::memcpy(field.depth.at(od.x, od.y + y), src, rd * 4);
    const glm::ivec2 oo = pcAtlasTileOrigin(c, firstSlot, so);
    for (int y = 0; y < so; ++y, src += ro)
      std::memcpy(field.occlusion.at(oo.x, oo.y + y), src, ro * 4);
    field.brickVersions[k][localBrick] = next;
  };
  tbb::parallel_for(tbb::blocked_range<std::uint32_t>(0, changed, 4), [&](const auto& range) {
    for (std::uint32_t e = range.begin(); e < range.end(); ++e) unpack(e);
  });
  stats.bricksChanged = int(changed);
  if (changed > 0) field.version = next;
  const auto* gpuRecords = m.recordsReadback.as<GpuProbeRecord>();
  for (std::size_t i = 0; i < field.probes.size(); ++i) {
    ProbeRecord& r = field.probes[i];
    r.offset = gpuRecords[i].offset;
    r.state = gpuRecords[i].state;
    r.updates = gpuRecords[i].updates;
  }
  m.syncedField = &field;
  m.syncedVersion = field.version;
  m.syncedRecords = field.probes;
  stats.readbackBytes +=
      std::uint64_t(changed) * PC_PROBES_PER_BRICK * PC_PACKED_PROBE_FLOATS * sizeof(float) +
      m.records.size() + m.brickList.size();
  const double hostMs = msSince(th);

  // A distance-field build this update needed comes first (as the ray tracer's "tlas").
  stats.gpuPasses.insert(stats.gpuPasses.begin(), m.sdfPasses.begin(), m.sdfPasses.end());
  m.sdfPasses.clear();
  for (const auto& [name, ms] : stats.gpuPasses) {
    stats.gpuMs += ms;
    if (name == "trace") stats.traceMs = ms;
    if (name == "shade" || name == "shadow trace" || name == "shadow rounds") stats.shadeMs += ms;
    if (name == "blend" || name == "changes") stats.blendMs += ms;
  }
  stats.gpuPasses.emplace_back("host unpack (CPU)", hostMs);
  stats.probeRays = std::uint64_t(total) * std::uint64_t(rayCount);
  stats.probesUpdated = int(total);
  stats.totalMs = msSince(t0);
  return stats;
}

Result<double> VulkanTracer::traceOnly(Field& field, const UpdateRequest& request) {
  return impl_->guarded("traceOnly", [&] { return traceOnlyOnce(field, request); });
}

double VulkanTracer::traceOnlyOnce(Field& field, const UpdateRequest& request) {
  Impl& m = *impl_;
  const std::size_t total = request.probes.size();
  const int rayCount = field.settings.raysPerProbe;
  const std::size_t perSlice = m.sliceProbes(total, rayCount);
  m.ensureSdf();
  m.sdfPasses.clear();
  std::vector<vk::Buffer> staging;
  double ms = 0.0;
  // In the update's slices; the field stays as it is, so every slice reads it as it is.
  for (std::size_t first = 0; first < total; first += perSlice) {
    const std::size_t n = std::min(perSlice, total - first);
    m.writeUpdateInputs(field, request, first, n, false, false);
    m.begin();
    if (first == 0) {
      m.recordFieldSync(field, staging);
      if (!m.sdf && m.tlasDirty) {
        m.accel.recordTopLevelBuild(m.cmd);
        m.tlasDirty = false;
      }
    }
    m.timer.begin(m.cmd, "raw trace");
    m.recordTrace(int(n), rayCount);
    m.timer.end(m.cmd);
    m.submitAndWait();
    for (const auto& [name, t] : m.timer.results())
      if (name == "raw trace") ms += t;
  }
  // The field on the GPU is what the host holds: the sync above uploaded any difference.
  m.syncedField = &field;
  m.syncedVersion = field.version;
  m.syncedRecords = field.probes;
  return ms;
}

}  // namespace pc
