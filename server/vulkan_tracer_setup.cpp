// The Vulkan tracer's creation: device and queues, the scene's buffers, textures and
// acceleration structures, descriptor layouts and pipelines.
#include "vulkan_tracer_impl.h"

namespace pc {

namespace {

Result<BindingTable> makeBindingTable(const vk::Context& ctx, VkPipeline pipeline,
                                      std::uint32_t missCount) {
  const auto& props = ctx.rayTracingProperties();
  const std::uint32_t handleSize = props.shaderGroupHandleSize;
  const VkDeviceSize stride = alignUp(handleSize, props.shaderGroupHandleAlignment);
  const VkDeviceSize base = props.shaderGroupBaseAlignment;
  const std::uint32_t groupCount = 1 + missCount + 1;
  std::vector<std::uint8_t> handles(std::size_t(groupCount) * handleSize);
  PC_VK_TRY(ctx.rt().getRayTracingShaderGroupHandles(ctx.device(), pipeline, 0, groupCount,
                                                     handles.size(), handles.data()));
  const VkDeviceSize raygenSize = alignUp(stride, base);
  const VkDeviceSize missSize = alignUp(stride * missCount, base);
  const VkDeviceSize hitSize = alignUp(stride, base);
  std::vector<std::uint8_t> table(raygenSize + missSize + hitSize, 0);
  std::memcpy(&table[0], &handles[0], handleSize);
  for (std::uint32_t m = 0; m < missCount; ++m)
    std::memcpy(&table[raygenSize + m * stride], &handles[(1 + m) * handleSize], handleSize);
  std::memcpy(&table[raygenSize + missSize], &handles[(1 + missCount) * handleSize], handleSize);
  // The table's start must be aligned to the base alignment too: over-allocate and offset.
  auto staging = vk::Buffer::create(
      ctx, table.size() + base,
      VK_BUFFER_USAGE_SHADER_BINDING_TABLE_BIT_KHR | VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT,
      vk::MemoryUsage::Upload);
  if (!staging) return staging.error();
  BindingTable t;
  t.buffer = std::move(staging).value();
  const VkDeviceAddress start = alignUp(t.buffer.address(), base);
  t.buffer.write(table.data(), table.size(), start - t.buffer.address());
  t.raygen = {start, raygenSize, raygenSize};
  t.miss = {start + raygenSize, stride, missSize};
  t.hit = {start + raygenSize + missSize, stride, hitSize};
  return t;
}

}  // namespace

Status VulkanTracer::Impl::init(const VulkanTracerOptions& vulkan) {
  vk::ContextOptions co;
  // Compute and ray tracing need nothing of 1.3: a 1.2 device runs every backend it has the
  // extensions for (the SDF backend: any 1.2 device with descriptor indexing).
  co.apiVersion = VK_API_VERSION_1_2;
  co.validation = vulkan.validation;
  sdf = vulkan.tracing == VulkanTracing::DistanceField;
  co.rayTracing = !sdf;
  if (sdf) {
    traceStage = kComputeStage;
    shaderStages = VK_SHADER_STAGE_COMPUTE_BIT;
    sdfVoxels = std::max(PC_SDF_BRICK_CELLS, vulkan.sdfVoxels);
  }
  co.allowCpuDevice = vulkan.allowCpuDevice;
  co.deviceNameFilter = vulkan.deviceNameFilter;
  boundedShadowLaunch = vulkan.boundedShadowLaunch;
  failSubmission = vulkan.failSubmission;
  shadowSlotTimes = vulkan.shadowSlotTimes;
  co.pipelineStatistics = vulkan.pipelineStatistics;
  auto c = vk::Context::create(co);
  if (!c) return c.error();
  ctx = std::move(c).value();
  auto pool = vk::CommandPool::create(*ctx);
  if (!pool) return pool.error();
  commandPool = std::move(pool).value();
  auto cb = commandPool.allocate();
  if (!cb) return cb.error();
  cmd = *cb;
  VkFenceCreateInfo fci{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
  VkFence f = VK_NULL_HANDLE;
  PC_VK_TRY(vkCreateFence(ctx->device(), &fci, nullptr, &f));
  fence = vk::UniqueFence(ctx->device(), f);
  // The shade pass appends shadow rays a subgroup at a time (ballot).
  VkPhysicalDeviceSubgroupProperties subgroup{
      VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_SUBGROUP_PROPERTIES};
  VkPhysicalDeviceProperties2 props2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
  props2.pNext = &subgroup;
  vkGetPhysicalDeviceProperties2(ctx->physicalDevice(), &props2);
  if (!(subgroup.supportedOperations & VK_SUBGROUP_FEATURE_BALLOT_BIT) ||
      !(subgroup.supportedStages & VK_SHADER_STAGE_COMPUTE_BIT))
    return Error{"the Vulkan device lacks subgroup ballot in compute shaders"};
  if (sdf) {
    // The context enables descriptor indexing where the device has it (the shade pass's
    // texture array); ray tracing requires it, the SDF backend checks it here.
    VkPhysicalDeviceVulkan12Features v12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
    VkPhysicalDeviceFeatures2 features{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
    features.pNext = &v12;
    vkGetPhysicalDeviceFeatures2(ctx->physicalDevice(), &features);
    if (!v12.runtimeDescriptorArray || !v12.descriptorBindingPartiallyBound ||
        !v12.shaderSampledImageArrayNonUniformIndexing ||
        !v12.descriptorBindingVariableDescriptorCount)
      return Error{"the Vulkan device " + ctx->deviceName() + " lacks descriptor indexing"};
  }
  auto t = vk::GpuTimer::create(*ctx, 16);
  if (!t) return t.error();
  timer = std::move(t).value();
  if (Status s = uploadScene(); !s) return s;
  if (Status s = createPipelines(); !s) return s;
  if (vulkan.ldmOcclusion) {
    auto made = LdmOcclusion::create(*ctx, vulkan.ldm);
    if (!made) return made.error();
    ldm = std::move(made).value();
  }
  const VkPhysicalDeviceMemoryProperties& mp = ctx->memoryProperties();
  VkDeviceSize largestHeap = 0;
  for (std::uint32_t h = 0; h < mp.memoryHeapCount; ++h)
    if (mp.memoryHeaps[h].flags & VK_MEMORY_HEAP_DEVICE_LOCAL_BIT)
      largestHeap = std::max(largestHeap, mp.memoryHeaps[h].size);
  shadowMemoryBudget = vulkan.shadowMemoryBudget;
  if (shadowMemoryBudget == 0)
    shadowMemoryBudget =
        std::size_t(std::min<VkDeviceSize>(largestHeap / 4, VkDeviceSize(8) << 30));
  maxBufferBytes = std::size_t(ctx->properties().limits.maxStorageBufferRange);
  if (vulkan.maxStorageBufferBytes > 0)
    maxBufferBytes = std::min(maxBufferBytes, vulkan.maxStorageBufferBytes);
  // A pass's probe rays: each per-ray buffer (bound whole) within the storage-buffer range,
  // and their records with one shadow slot's within a quarter of the device-local memory.
  const std::size_t widestRecord =
      std::max({sizeof(GpuHit), std::size_t(16), sizeof(GpuShadowRay)});
  const std::size_t rayBytes =
      sizeof(GpuHit) + 16 + 4 + sizeof(GpuShadowRay) + sizeof(GpuShadowLight);
  maxPassRays =
      std::max<std::size_t>(1, std::min<std::size_t>(maxBufferBytes / widestRecord,
                                                     std::size_t(largestHeap / 4) / rayBytes));
  if (vulkan.maxPassRays > 0) maxPassRays = std::min(maxPassRays, vulkan.maxPassRays);
  ensureRequestCapacity(1, 1, 0);
  return Status::success();
}

Status VulkanTracer::Impl::uploadScene() {
  const Scene& s = *scene;
  std::vector<GpuVertex> verts;
  std::vector<std::uint32_t> idx;
  std::vector<GpuMesh> gpuMeshes;
  std::vector<MeshRange> ranges;
  for (const Mesh& m : s.meshes) {
    GpuMesh gm{};
    gm.firstVertex = int(verts.size());
    gm.firstIndex = int(idx.size());
    gm.material = m.material >= 0 && std::size_t(m.material) < s.materials.size() ? m.material : -1;
    MeshRange r;
    r.firstVertex = std::uint32_t(verts.size());
    r.vertexCount = std::uint32_t(m.positions.size());
    r.firstIndex = std::uint32_t(idx.size());
    bool valid = true;
    for (std::uint32_t i : m.indices) valid = valid && i < m.positions.size();
    r.triangleCount = valid ? std::uint32_t(m.triangleCount()) : 0;
    r.cutOut = gm.material >= 0 && s.materials[gm.material].isCutOut();
    if (!valid) return Error{"mesh '" + m.name + "' has an index past its vertices"};
    const bool normals = m.normals.size() == m.positions.size();
    const bool uvs = m.uvs.size() == m.positions.size();
    for (std::size_t v = 0; v < m.positions.size(); ++v) {
      GpuVertex gv{};
      gv.position = m.positions[v];
      gv.normal = normals ? m.normals[v] : glm::vec3(0.0f);
      gv.u = uvs ? m.uvs[v].x : 0.0f;
      gv.v = uvs ? m.uvs[v].y : 0.0f;
      verts.push_back(gv);
    }
    idx.insert(idx.end(), m.indices.begin(),
               m.indices.begin() + std::ptrdiff_t(r.triangleCount) * 3);
    gpuMeshes.push_back(gm);
    ranges.push_back(r);
  }

  // Static instances: world-space copies of their meshes' vertices, transformed as the Embree
  // scene transforms them (cpu/embree_scene.cpp), each a geometry of the one static structure
  // and a mesh entry past the scene's meshes (indices are shared with the object-space mesh).
  // Their shading records come first; animated instances' follow.
  std::vector<MeshRange> staticRanges;
  std::vector<bool> meshNeeded(s.meshes.size(), false);
  for (std::size_t i = 0; i < s.instances.size(); ++i) {
    const Instance& inst = s.instances[i];
    const int mesh = inst.mesh >= 0 && std::size_t(inst.mesh) < s.meshes.size() ? inst.mesh : -1;
    if (mesh < 0 || ranges[mesh].triangleCount == 0) continue;  // nothing to hit
    if (inst.animation >= 0) {
      meshNeeded[mesh] = true;
      continue;
    }
    const Mesh& m = s.meshes[mesh];
    const glm::mat3 normalMatrix = glm::transpose(glm::inverse(glm::mat3(inst.transform)));
    MeshRange r = ranges[mesh];
    r.firstVertex = std::uint32_t(verts.size());
    GpuMesh gm = gpuMeshes[mesh];
    gm.firstVertex = int(verts.size());
    for (std::size_t v = 0; v < m.positions.size(); ++v) {
      GpuVertex gv = verts[ranges[mesh].firstVertex + v];
      gv.position = glm::vec3(inst.transform * glm::vec4(m.positions[v], 1.0f));
      const glm::vec3 n = normalMatrix * gv.normal;
      const float len = glm::length(n);
      gv.normal = len > 0.0f ? n / len : glm::vec3(0.0f);
      verts.push_back(gv);
    }
    staticRanges.push_back(r);
    staticMeshes.push_back(int(gpuMeshes.size()));
    gpuMeshes.push_back(gm);
    recordInstance.push_back(int(i));
  }
  staticCount = int(recordInstance.size());
  for (std::size_t i = 0; i < s.instances.size(); ++i) {
    const Instance& inst = s.instances[i];
    const int mesh = inst.mesh >= 0 && std::size_t(inst.mesh) < s.meshes.size() ? inst.mesh : -1;
    if (mesh >= 0 && ranges[mesh].triangleCount > 0 && inst.animation >= 0)
      recordInstance.push_back(int(i));
  }

  const VkBufferUsageFlags asInput =
      sdf ? 0 : VK_BUFFER_USAGE_ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_BIT_KHR;
  auto vb =
      vk::uploadBuffer(*ctx, verts.data(), verts.size() * sizeof(GpuVertex), kStorage | asInput);
  if (!vb) return vb.error();
  vertices = std::move(vb).value();
  auto ib = vk::uploadBuffer(*ctx, idx.data(), idx.size() * 4, kStorage | asInput);
  if (!ib) return ib.error();
  indices = std::move(ib).value();
  auto mb = vk::uploadBuffer(*ctx, gpuMeshes.data(), gpuMeshes.size() * sizeof(GpuMesh), kStorage);
  if (!mb) return mb.error();
  meshes = std::move(mb).value();

  // The SDF backend builds its distance field at the first update (ensureSdf) instead.
  const std::size_t animated = recordInstance.size() - std::size_t(staticCount);
  if (!sdf) {
    auto as = SceneAccel::build(*ctx, vertices, sizeof(GpuVertex), indices, staticRanges, ranges,
                                meshNeeded, 1 + animated);
    if (!as) return as.error();
    accel = std::move(as).value();
  }

  // Textures: 8-bit sRGB, decoded to linear before filtering, as Texture::sample does; data
  // textures (Texture::linear: metallic-roughness) read as they are.
  for (const Texture& t : s.textures) {
    vk::ImageDesc d;
    const bool ok =
        t.width > 0 && t.height > 0 && t.rgba.size() >= std::size_t(t.width) * t.height * 4;
    d.format = t.linear ? VK_FORMAT_R8G8B8A8_UNORM : VK_FORMAT_R8G8B8A8_SRGB;
    d.width = ok ? std::uint32_t(t.width) : 1;
    d.height = ok ? std::uint32_t(t.height) : 1;
    auto img = vk::Image::create(*ctx, d);
    if (!img) return img.error();
    const std::uint8_t white[4] = {255, 255, 255, 255};  // Texture::sample's answer for bad data
    Status st = ok ? img->upload(t.rgba.data(), std::size_t(t.width) * t.height * 4)
                   : img->upload(white, 4);
    if (!st) return st;
    textures.push_back(std::move(img).value());
  }
  if (textures.empty()) {  // the array binding needs one descriptor
    auto img = vk::Image::create(*ctx, vk::ImageDesc{VK_FORMAT_R8G8B8A8_SRGB, 1, 1});
    if (!img) return img.error();
    const std::uint8_t white[4] = {255, 255, 255, 255};
    if (Status st = img->upload(white, 4); !st) return st;
    textures.push_back(std::move(img).value());
  }
  // Level 0, bilinear, each texture with its wrap modes, as Texture::sample reads it.
  samplers.emplace(*ctx, vk::TextureSamplerDesc{});
  for (const Texture& t : s.textures) {
    auto smp = samplers->forTexture(t);
    if (!smp) return smp.error();
    textureSamplers.push_back(*smp);
  }
  if (textureSamplers.empty()) {
    auto smp = samplers->repeating();
    if (!smp) return smp.error();
    textureSamplers.push_back(*smp);
  }

  // Materials; `sampled` is filled per state (the emissive rule depends on the geometry).
  auto mat =
      vk::Buffer::create(*ctx, std::max<std::size_t>(s.materials.size(), 1) * sizeof(GpuMaterial),
                         kHostInput, vk::MemoryUsage::Upload);
  if (!mat) return mat.error();
  materials = std::move(mat).value();
  auto ins = vk::Buffer::create(
      *ctx, std::max<std::size_t>(recordInstance.size(), 1) * sizeof(GpuInstance), kHostInput,
      vk::MemoryUsage::Upload);
  if (!ins) return ins.error();
  instances = std::move(ins).value();
  return Status::success();
}

Status VulkanTracer::Impl::createPipelines() {
  // ---- one descriptor set layout for every pipeline ----
  std::vector<VkDescriptorSetLayoutBinding> bindings;
  std::vector<VkDescriptorBindingFlags> flags;
  for (int b = 0; b < PC_BINDING_COUNT; ++b) {
    // Each backend's own: the TLAS, or the distance field's buffers.
    const bool sdfBinding = b == PC_BIND_SDF_GRID || b == PC_BIND_SDF_BRICKS ||
                            b == PC_BIND_SDF_TRIANGLES || b == PC_BIND_SDF_OUTSIDE ||
                            b == PC_BIND_SDF_LISTS;
    if (sdf ? b == PC_BIND_TLAS : sdfBinding) continue;
    VkDescriptorSetLayoutBinding lb{};
    lb.binding = std::uint32_t(b);
    lb.descriptorCount = 1;
    // Any-hit: cut-outs read the scene's records and textures (probe_cutout.rahit).
    lb.stageFlags = sdf ? shaderStages : shaderStages | VK_SHADER_STAGE_ANY_HIT_BIT_KHR;
    lb.descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
    VkDescriptorBindingFlags f = 0;
    if (b == PC_BIND_TLAS) lb.descriptorType = VK_DESCRIPTOR_TYPE_ACCELERATION_STRUCTURE_KHR;
    if (b == PC_BIND_TEXTURES) {
      lb.descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
      lb.descriptorCount = std::uint32_t(textures.size());
      f = VK_DESCRIPTOR_BINDING_PARTIALLY_BOUND_BIT |
          VK_DESCRIPTOR_BINDING_VARIABLE_DESCRIPTOR_COUNT_BIT;
    }
    bindings.push_back(lb);
    flags.push_back(f);
  }
  auto created = vk::createDescriptorSetLayout(*ctx, bindings, flags);
  if (!created) return created.error();
  setLayout = std::move(created).value();
  const VkDescriptorSetLayout dsl = setLayout.get();

  std::vector<VkDescriptorPoolSize> sizes = {
      {VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 2 * std::uint32_t(PC_BINDING_COUNT)},
      {VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER,
       2 * std::max<std::uint32_t>(std::uint32_t(textures.size()), 1)}};
  if (!sdf) sizes.push_back({VK_DESCRIPTOR_TYPE_ACCELERATION_STRUCTURE_KHR, 2});
  VkDescriptorPoolCreateInfo pci{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  pci.maxSets = 2;
  pci.poolSizeCount = std::uint32_t(sizes.size());
  pci.pPoolSizes = sizes.data();
  VkDescriptorPool dp = VK_NULL_HANDLE;
  PC_VK_TRY(vkCreateDescriptorPool(ctx->device(), &pci, nullptr, &dp));
  descriptorPool = vk::UniqueDescriptorPool(ctx->device(), dp);
  const std::uint32_t textureCount = std::uint32_t(textures.size());
  VkDescriptorSetVariableDescriptorCountAllocateInfo vci{
      VK_STRUCTURE_TYPE_DESCRIPTOR_SET_VARIABLE_DESCRIPTOR_COUNT_ALLOCATE_INFO};
  const std::uint32_t textureCounts[2] = {textureCount, textureCount};
  vci.descriptorSetCount = 2;
  vci.pDescriptorCounts = textureCounts;
  const VkDescriptorSetLayout layouts[2] = {dsl, dsl};
  VkDescriptorSetAllocateInfo sai{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
  sai.pNext = &vci;
  sai.descriptorPool = dp;
  sai.descriptorSetCount = 2;
  sai.pSetLayouts = layouts;
  VkDescriptorSet sets[2] = {};
  PC_VK_TRY(vkAllocateDescriptorSets(ctx->device(), &sai, sets));
  set = sets[0];
  snapshotSet = sets[1];
  traceSet = set;

  auto layout = vk::createPipelineLayout(*ctx, dsl, shaderStages, sizeof(TracePush));
  if (!layout) return layout.error();
  pipelineLayout = std::move(layout).value();
  const VkPipelineLayout pl = pipelineLayout.get();

  // ---- ray tracing: stages raygen, miss..., closest hit, and in scenes with cut-outs any
  // hit; groups: raygen, the misses, then one triangle hit group of the hit shaders. Scenes
  // without cut-outs keep the pipelines they had before cut-outs existed: no any-hit shader,
  // opaque ray flags (specialization constant 0 of the ray generation shaders). ----
  const bool cutOuts = scene->hasCutOuts();
  const VkBool32 cutOutsSpec = cutOuts ? VK_TRUE : VK_FALSE;
  const VkSpecializationMapEntry cutOutsEntry{0, 0, sizeof(VkBool32)};
  const VkSpecializationInfo raygenSpec{1, &cutOutsEntry, sizeof cutOutsSpec, &cutOutsSpec};
  if (sdf) {
    if (Status st = createSdfPipelines(cutOuts); !st) return st;
    return createComputePasses();
  }
  auto makeRayPipeline = [&](const char* raygen,
                             std::vector<const char*> misses) -> Result<vk::UniquePipeline> {
    std::vector<vk::UniqueShaderModule> modules;
    std::vector<const char*> names = {raygen};
    names.insert(names.end(), misses.begin(), misses.end());
    names.push_back("probe_trace.rchit.spv");
    const std::size_t closestHit = names.size() - 1;
    if (cutOuts) names.push_back("probe_cutout.rahit.spv");
    const std::size_t anyHit = cutOuts ? names.size() - 1 : names.size();
    std::vector<VkPipelineShaderStageCreateInfo> stages;
    std::vector<VkRayTracingShaderGroupCreateInfoKHR> groups;
    for (std::size_t i = 0; i < names.size(); ++i) {
      auto m = vk::loadShader(*ctx, names[i]);
      if (!m) return m.error();
      modules.push_back(std::move(m).value());
      VkPipelineShaderStageCreateInfo st{VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
      st.stage = i == 0            ? VK_SHADER_STAGE_RAYGEN_BIT_KHR
                 : i == closestHit ? VK_SHADER_STAGE_CLOSEST_HIT_BIT_KHR
                 : i == anyHit     ? VK_SHADER_STAGE_ANY_HIT_BIT_KHR
                                   : VK_SHADER_STAGE_MISS_BIT_KHR;
      st.module = modules.back().get();
      st.pName = "main";
      if (i == 0) st.pSpecializationInfo = &raygenSpec;
      stages.push_back(st);
      if (i == anyHit) continue;  // in the closest hit's group
      VkRayTracingShaderGroupCreateInfoKHR g{
          VK_STRUCTURE_TYPE_RAY_TRACING_SHADER_GROUP_CREATE_INFO_KHR};
      g.generalShader = g.closestHitShader = g.anyHitShader = g.intersectionShader =
          VK_SHADER_UNUSED_KHR;
      if (i == closestHit) {
        g.type = VK_RAY_TRACING_SHADER_GROUP_TYPE_TRIANGLES_HIT_GROUP_KHR;
        g.closestHitShader = std::uint32_t(closestHit);
        if (cutOuts) g.anyHitShader = std::uint32_t(anyHit);
      } else {
        g.type = VK_RAY_TRACING_SHADER_GROUP_TYPE_GENERAL_KHR;
        g.generalShader = std::uint32_t(i);
      }
      groups.push_back(g);
    }
    VkRayTracingPipelineCreateInfoKHR rci{VK_STRUCTURE_TYPE_RAY_TRACING_PIPELINE_CREATE_INFO_KHR};
    rci.stageCount = std::uint32_t(stages.size());
    rci.pStages = stages.data();
    rci.groupCount = std::uint32_t(groups.size());
    rci.pGroups = groups.data();
    rci.maxPipelineRayRecursionDepth = 1;  // every ray leaves from ray generation
    rci.layout = pl;
    if (ctx->capturesStatistics()) rci.flags |= VK_PIPELINE_CREATE_CAPTURE_STATISTICS_BIT_KHR;
    VkPipeline p = VK_NULL_HANDLE;
    PC_VK_TRY(ctx->rt().createRayTracingPipelines(ctx->device(), VK_NULL_HANDLE, VK_NULL_HANDLE, 1,
                                                  &rci, nullptr, &p));
    logStatistics(raygen, p);
    return vk::UniquePipeline(ctx->device(), p);
  };
  auto trace = makeRayPipeline("probe_trace.rgen.spv", {"probe_trace.rmiss.spv"});
  if (!trace) return trace.error();
  tracePipeline = std::move(trace).value();
  // Shadow rays skip closest-hit shaders; the hit group is there for a complete binding table.
  auto shadow = makeRayPipeline("probe_shadow.rgen.spv", {"shadow.rmiss.spv"});
  if (!shadow) return shadow.error();
  shadowPipeline = std::move(shadow).value();
  auto tt = makeBindingTable(*ctx, tracePipeline.get(), 1);
  if (!tt) return tt.error();
  traceTable = std::move(tt).value();
  auto st = makeBindingTable(*ctx, shadowPipeline.get(), 1);
  if (!st) return st.error();
  shadowTable = std::move(st).value();
  return createComputePasses();
}

// The compute passes both backends share: shade, resolve, blend, brick changes and packing.
Status VulkanTracer::Impl::createComputePasses() {
  auto shade = computePipeline("probe_shade.comp.spv",
                               {{1, options.shadowRouletteShare > 0.0f ? 1 : 0}});  // kRoulette
  if (!shade) return shade.error();
  shadePipeline = std::move(shade).value();
  auto ch = computePipeline("brick_changes.comp.spv", {});
  if (!ch) return ch.error();
  changesPipeline = std::move(ch).value();
  auto rs = computePipeline("probe_resolve.comp.spv", {});
  if (!rs) return rs.error();
  resolvePipeline = std::move(rs).value();
  auto pk = computePipeline("brick_pack.comp.spv", {});
  if (!pk) return pk.error();
  packPipeline = std::move(pk).value();
  return ensureBlendPipeline(FieldSettings{}.raysPerProbe);
}

Result<vk::UniquePipeline> VulkanTracer::Impl::computePipeline(
    const char* name, const std::vector<SpecConstant>& constants) {
  auto p = vk::createComputePipeline(
      *ctx, name, pipelineLayout.get(), constants,
      ctx->capturesStatistics() ? VK_PIPELINE_CREATE_CAPTURE_STATISTICS_BIT_KHR : 0);
  if (p) logStatistics(name, p->get());
  return p;
}

void VulkanTracer::Impl::logStatistics(const char* name, VkPipeline pipeline) const {
  for (const std::string& line : ctx->pipelineStatistics(pipeline))
    logInfo(std::string(name) + " " + line);
}

Status VulkanTracer::Impl::ensureBlendPipeline(int rayCount) {
  const int scratch = pcBlendScratch(pcBlendProbes(rayCount), rayCount);
  if (blendPipeline && scratch == blendScratch) return Status::success();
  auto blend = computePipeline("probe_blend.comp.spv", {{1, scratch}});  // kScratch
  if (!blend) return blend.error();
  blendPipeline = std::move(blend).value();
  blendScratch = scratch;
  return Status::success();
}

}  // namespace pc
