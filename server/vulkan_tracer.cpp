#include "vulkan_tracer.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdlib>
#include <cstring>

#include <glm/gtc/packing.hpp>

#include "../common/log.h"
#include "../common/vulkan/texture_samplers.h"
#include "../cpu/lighting.h"
#include "../shaders/interop/gpu_trace.h"
#include "embree_tracer.h"
#include "probe_blend.h"
#include "vulkan_accel.h"

#include <tbb/parallel_for.h>

namespace pc {

using namespace pc::gpu;

static_assert(PC_MAX_RAYS_PER_PROBE == kMaxRaysPerProbe, "the blend's shared scratch holds every ray");
// The blend's threads: one per irradiance/occlusion texel, the rest share the depth texels; a
// power-of-two share of them per probe of a group for the reductions.
static_assert(PC_IRRADIANCE_TEXELS == PC_OCCLUSION_TEXELS, "irradiance and occlusion share their taps");
static_assert(PC_BLEND_THREADS > PC_IRRADIANCE_TEXELS * PC_IRRADIANCE_TEXELS);
// probe_blend.comp's default scratch (a literal there).
static_assert(PC_MAX_RAYS_PER_PROBE + PC_BLEND_MAX_PROBES == 1028);
static_assert(PC_BLEND_THREADS % PC_BLEND_MAX_PROBES == 0 && PC_TRACE_TILE_PROBES % PC_BLEND_MAX_PROBES == 0);
// A brick's probes must lie in one atlas tile row for the packed row runs (gpu_trace.h).
static_assert(PC_ATLAS_TILES_PER_ROW % PC_PROBES_PER_BRICK == 0);

namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

constexpr VkBufferUsageFlags kStorage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
// Host-written inputs: mapped host memory, copied to a device-local mirror per submission.
constexpr VkBufferUsageFlags kHostInput = kStorage | VK_BUFFER_USAGE_TRANSFER_SRC_BIT;
constexpr VkPipelineStageFlags2 kRayStage = VK_PIPELINE_STAGE_2_RAY_TRACING_SHADER_BIT_KHR;
constexpr VkPipelineStageFlags2 kComputeStage = VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT;
constexpr VkAccessFlags2 kShaderRW = VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT;

// Failures on the update path throw TracerFailure (tracer.h), never abort: a server whose GPU
// is lost or out of memory goes on with another backend, and its clients with it.
[[noreturn]] void fail(const std::string& message) {
  throw TracerFailure("vulkan tracer: " + message);
}

// The buffer, or a TracerFailure naming it: resources the update cannot do without.
template <typename T>
T orFail(Result<T> r, const char* what) {
  if (!r) fail(std::string(what) + ": " + r.error().message);
  return std::move(r).value();
}

// A call's VkResult, as a TracerFailure naming the call where it failed (a lost device, memory).
void checkCall(VkResult result, const char* call) {
  if (result != VK_SUCCESS) fail(vk::vkErrorMessage(call, result));
}

// Fails, saying why: `what` needs a buffer of `bytes`, past the storage-buffer range `range`
// that a descriptor binding the whole buffer can cover. `fix` says what to ask for instead.
[[noreturn]] void failOverRange(const std::string& what, std::size_t bytes, std::size_t range,
                                const char* fix) {
  auto size = [](std::size_t b) {
    return b >= (std::size_t(1) << 20) ? std::to_string(b >> 20) + " MiB"
                                       : std::to_string(b) + " bytes";
  };
  fail(what + " needs buffers of " + size(bytes) + ", over the device's storage-buffer range of " +
       size(range) + ": " + fix);
}

VkDeviceSize alignUp(VkDeviceSize v, VkDeviceSize a) { return (v + a - 1) / a * a; }

// A ray-tracing pipeline's shader binding table: one raygen record, the miss records, one hit
// group record, in one buffer.
struct BindingTable {
  vk::Buffer buffer;
  VkStridedDeviceAddressRegionKHR raygen{}, miss{}, hit{}, callable{};
};

Result<BindingTable> makeBindingTable(const vk::Context& ctx, VkPipeline pipeline, std::uint32_t missCount) {
  const auto& props = ctx.rayTracingProperties();
  const std::uint32_t handleSize = props.shaderGroupHandleSize;
  const VkDeviceSize stride = alignUp(handleSize, props.shaderGroupHandleAlignment);
  const VkDeviceSize base = props.shaderGroupBaseAlignment;
  const std::uint32_t groupCount = 1 + missCount + 1;
  std::vector<std::uint8_t> handles(std::size_t(groupCount) * handleSize);
  PC_VK_TRY(ctx.rt().getRayTracingShaderGroupHandles(ctx.device(), pipeline, 0, groupCount, handles.size(),
                                                     handles.data()));
  const VkDeviceSize raygenSize = alignUp(stride, base);
  const VkDeviceSize missSize = alignUp(stride * missCount, base);
  const VkDeviceSize hitSize = alignUp(stride, base);
  std::vector<std::uint8_t> table(raygenSize + missSize + hitSize, 0);
  std::memcpy(&table[0], &handles[0], handleSize);
  for (std::uint32_t m = 0; m < missCount; ++m)
    std::memcpy(&table[raygenSize + m * stride], &handles[(1 + m) * handleSize], handleSize);
  std::memcpy(&table[raygenSize + missSize], &handles[(1 + missCount) * handleSize], handleSize);
  // The table's start must be aligned to the base alignment too: over-allocate and offset.
  auto staging = vk::Buffer::create(ctx, table.size() + base,
                                    VK_BUFFER_USAGE_SHADER_BINDING_TABLE_BIT_KHR |
                                        VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT,
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

GpuProbeRecord toGpu(const ProbeRecord& r) {
  GpuProbeRecord g{};
  g.offset = r.offset;
  g.state = r.state;
  g.updates = r.updates;
  return g;
}

bool sameRecord(const ProbeRecord& a, const ProbeRecord& b) {
  return a.offset == b.offset && a.state == b.state && a.updates == b.updates;
}

}  // namespace

struct VulkanTracer::Impl {
  const Scene* scene = nullptr;
  TracerOptions options;
  std::unique_ptr<vk::Context> ctx;
  vk::CommandPool commandPool;
  VkCommandBuffer cmd = VK_NULL_HANDLE;
  vk::UniqueFence fence;
  vk::GpuTimer timer;

  // ---- scene ----
  vk::Buffer vertices, indices, meshes, instances, materials, lights, emissive;
  // Shading records (the `instances` buffer, indexed by a hit's custom index + geometry index):
  // static instances first (world-space mesh copies staticMeshes[r]), then animated ones.
  std::vector<int> recordInstance;  // record -> Scene::instances index
  std::vector<int> staticMeshes;    // static record -> its world-space GpuMesh entry
  int staticCount = 0;
  // Timing experiments (probe_blend.comp, probe_shade.comp: kVariant): PC_BLEND_VARIANT and
  // PC_SHADE_VARIANT pick a variant that drops one step; 0, the default, is the real pass.
  int blendVariant = 0;
  int shadeVariant = 0;
  int overlapVariant = 0;
  // PC_SHADOW_SLOT_TIMES=1 (diagnostics): a timestamp pair per shadow slot's launch instead of
  // one over them all, and each slot's shadow-ray count in the log.
  bool shadowSlotTimes = false;
  bool boundedShadowLaunch = false;  // VulkanTracerOptions::boundedShadowLaunch
  // Submissions made, and the one that fails as a lost device would (VulkanTracerOptions).
  int submissions = 0, failSubmission = 0;
  // The first failure's message: once set, every call fails with it (a lost device stays lost).
  std::string failure;
  // Runs `f` (a Tracer call), unless an earlier call failed; remembers a failure it throws.
  template <typename F>
  auto guarded(F&& f) {
    if (!failure.empty())
      throw TracerFailure(failure + " (failed earlier; the tracer is unusable)");
    try {
      return f();
    } catch (const TracerFailure& e) {
      failure = e.what();
      throw;
    }
  }
  SceneAccel accel;
  bool tlasDirty = true;
  std::vector<vk::Image> textures;
  std::optional<vk::TextureSamplers> samplers;
  std::vector<VkSampler> textureSamplers;  // per texture (owned by `samplers`)
  SceneState state;

  // ---- pipelines ----
  vk::UniqueDescriptorSetLayout setLayout;
  vk::UniqueDescriptorPool descriptorPool;
  VkDescriptorSet set = VK_NULL_HANDLE;
  // The same bindings but for the field's, which point at the snapshot below: what the trace
  // and shading passes of an update in slices read (traceSet: `set` or this one).
  VkDescriptorSet snapshotSet = VK_NULL_HANDLE;
  VkDescriptorSet traceSet = VK_NULL_HANDLE;
  vk::UniquePipelineLayout pipelineLayout;
  vk::UniquePipeline tracePipeline, shadowPipeline, shadePipeline, resolvePipeline, blendPipeline,
      changesPipeline, packPipeline;
  int blendScratch = 0;  // shared scratch entries the blend pipeline was made with
  BindingTable traceTable, shadowTable;

  // ---- per-update buffers ----
  vk::Buffer params, rayDirs, requests, changes, counters, countersReadback;
  vk::Buffer countersInit;  // each slot's counters as an update starts: 0, 1, 1, 0
  // The wavefront's per-ray records (gpu_trace.h), for probeCapacity x rayCapacity rays and
  // slotCapacity shadow slots each (a round's: pcShadowRounds); the compacted shadow list holds
  // at most one ray per slot. Counters for counterSlotCapacity slots (every slot of an update).
  vk::Buffer hits, rays, shadowMask, shadowLight, shadowRays;
  int slotCapacity = -1, counterSlotCapacity = -1;
  int roundSlots = 1;                  // this update's shadow slots per round
  std::size_t shadowMemoryBudget = 0;  // VulkanTracerOptions::shadowMemoryBudget
  std::size_t maxBufferBytes = 0;  // VulkanTracerOptions::maxStorageBufferBytes, or the device's
  int loggedRounds = 1;                // the rounds last reported in the log
  vk::Buffer tapsUpload, taps;  // blend taps: host-written, copied to device memory per update
  std::size_t tapBytes = 0;     // of this update's taps
  std::size_t probeCapacity = 0, rayCapacity = 0;
  // An update of more probe rays than one pass holds (maxPassRays, or fewer: vulkanPassRays)
  // runs in slices of its probes, a submission each. Each slice traces and shades against the field
  // as the update found it, copied once into the snapshot buffers, so the field is the one pass's:
  // a slice blended earlier does not light a later one.
  std::size_t maxPassRays = 0;
  vk::Buffer prevIrradiance, prevDepth, prevOcclusion, prevRecords;
  // Each field buffer and its snapshot.
  std::array<std::pair<vk::Buffer*, vk::Buffer*>, 4> snapshots() {
    return {{{&irradiance, &prevIrradiance},
             {&depth, &prevDepth},
             {&occlusion, &prevOcclusion},
             {&records, &prevRecords}}};
  }

  // ---- field on the GPU ----
  FieldDesc layoutDesc{};  // the layout the field buffers were made for
  bool haveField = false;
  vk::Buffer fieldDesc, irradiance, depth, occlusion, records, recordsReadback;
  vk::Buffer brickFlags, brickList, brickListReadback, packed;
  int brickTotal = 0;
  std::array<int, PC_MAX_CASCADES> brickOffset{};
  const Field* syncedField = nullptr;  // the Field whose atlases the GPU holds
  std::uint64_t syncedVersion = 0;
  std::vector<ProbeRecord> syncedRecords;  // the records the GPU holds
  bool descriptorsDirty = true;

  // Device-local copies of the inputs the host writes through mapped (host) memory: the
  // parameters, requests, ray directions, field description and scene state. Every pass reads
  // these, many per invocation; from host memory each such read would cross the bus. Copied
  // at the start of each submission (recordMirrorCopies); the descriptors point at the copies.
  vk::Buffer paramsGpu, rayDirsGpu, requestsGpu, fieldDescGpu, materialsGpu, instancesGpu, lightsGpu, emissiveGpu;
  std::array<std::pair<const vk::Buffer*, vk::Buffer*>, 8> mirrors() {
    return {{{&params, &paramsGpu},
             {&rayDirs, &rayDirsGpu},
             {&requests, &requestsGpu},
             {&fieldDesc, &fieldDescGpu},
             {&materials, &materialsGpu},
             {&instances, &instancesGpu},
             {&lights, &lightsGpu},
             {&emissive, &emissiveGpu}}};
  }
  void ensureMirrors();
  void recordMirrorCopies();

  Status init(const VulkanTracerOptions& vulkan);
  Status uploadScene();
  Status createPipelines();
  // A compute pipeline of `name` with its specialization constants (constant_id i = value i;
  // none when empty).
  Result<vk::UniquePipeline> computePipeline(const char* name, const std::vector<int>& constants);
  // The compiler's statistics of a pipeline, logged where the context captures them.
  void logStatistics(const char* name, VkPipeline pipeline) const;
  // The blend pipeline for `rayCount` rays per probe: its shared scratch is sized for the
  // group (blendGroupProbes) at that ray count, rebuilt when the count changes.
  int blendGroupProbes(int rayCount) const;
  Status ensureBlendPipeline(int rayCount);
  void writeDescriptors();
  int shadowSlots() const;
  void ensureRequestCapacity(std::size_t probes, int rayCount, int slots);
  bool ensureFieldBuffers(const Field& field);
  std::size_t sliceProbes(std::size_t probes, int rayCount) const;
  void ensureSnapshot();
  void recordSnapshot();
  // Writes the inputs of the request's probes [first, first + count); the blend taps too
  // where `blendTaps`. `sliced`: the update runs in slices (the snapshot is made ready).
  void writeUpdateInputs(const Field& field, const UpdateRequest& request, std::size_t first,
                         std::size_t count, bool blendTaps, bool sliced);
  void begin();
  void submitAndWait();
  void recordFieldSync(const Field& field, std::vector<vk::Buffer>& staging);
  std::uint64_t maxLaunchWidth() const;
  void recordTrace(int probeCount, int rayCount);
  void recordShade(int probeCount, int rayCount, int slotBase);
  void recordShadowTrace(int slots, std::uint64_t rayCount, int slotBase);
  void recordResolve(int probeCount, int rayCount);
  void dispatchRows(std::uint64_t groups);
  // Trace, shade, shadow rays and blend for the `probeCount` probes of the current inputs.
  void recordWavefront(int probeCount, int rayCount, bool sliced);
  bool loggedSlices = false;  // the first update in slices is reported in the log
};

// ---------------------------------------------------------------------------------------------
// Creation

Status VulkanTracer::Impl::init(const VulkanTracerOptions& vulkan) {
  vk::ContextOptions co;
  co.validation = vulkan.validation;
  co.rayTracing = true;
  co.allowCpuDevice = vulkan.allowCpuDevice;
  co.deviceNameFilter = vulkan.deviceNameFilter;
  boundedShadowLaunch = vulkan.boundedShadowLaunch;
  failSubmission = vulkan.failSubmission;
  // Diagnostics: PC_PIPELINE_STATS=1 logs each pipeline's compiler statistics (registers,
  // shared memory, ...) where the driver reports them.
  co.pipelineStatistics = std::getenv("PC_PIPELINE_STATS") != nullptr;
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
  VkPhysicalDeviceSubgroupProperties subgroup{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_SUBGROUP_PROPERTIES};
  VkPhysicalDeviceProperties2 props2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
  props2.pNext = &subgroup;
  vkGetPhysicalDeviceProperties2(ctx->physicalDevice(), &props2);
  if (!(subgroup.supportedOperations & VK_SUBGROUP_FEATURE_BALLOT_BIT) ||
      !(subgroup.supportedStages & VK_SHADER_STAGE_COMPUTE_BIT))
    return Error{"the Vulkan device lacks subgroup ballot in compute shaders"};
  auto t = vk::GpuTimer::create(*ctx, 16);
  if (!t) return t.error();
  timer = std::move(t).value();
  if (Status s = uploadScene(); !s) return s;
  if (Status s = createPipelines(); !s) return s;
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
    idx.insert(idx.end(), m.indices.begin(), m.indices.begin() + std::ptrdiff_t(r.triangleCount) * 3);
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
    if (mesh >= 0 && ranges[mesh].triangleCount > 0 && inst.animation >= 0) recordInstance.push_back(int(i));
  }

  const VkBufferUsageFlags asInput = VK_BUFFER_USAGE_ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_BIT_KHR;
  auto vb = vk::uploadBuffer(*ctx, verts.data(), verts.size() * sizeof(GpuVertex), kStorage | asInput);
  if (!vb) return vb.error();
  vertices = std::move(vb).value();
  auto ib = vk::uploadBuffer(*ctx, idx.data(), idx.size() * 4, kStorage | asInput);
  if (!ib) return ib.error();
  indices = std::move(ib).value();
  auto mb = vk::uploadBuffer(*ctx, gpuMeshes.data(), gpuMeshes.size() * sizeof(GpuMesh), kStorage);
  if (!mb) return mb.error();
  meshes = std::move(mb).value();

  const std::size_t animated = recordInstance.size() - std::size_t(staticCount);
  auto as = SceneAccel::build(*ctx, vertices, sizeof(GpuVertex), indices, staticRanges, ranges, meshNeeded,
                              1 + animated);
  if (!as) return as.error();
  accel = std::move(as).value();

  // Textures: 8-bit sRGB, decoded to linear before filtering, as Texture::sample does.
  for (const Texture& t : s.textures) {
    vk::ImageDesc d;
    const bool ok = t.width > 0 && t.height > 0 && t.rgba.size() >= std::size_t(t.width) * t.height * 4;
    d.format = VK_FORMAT_R8G8B8A8_SRGB;
    d.width = ok ? std::uint32_t(t.width) : 1;
    d.height = ok ? std::uint32_t(t.height) : 1;
    auto img = vk::Image::create(*ctx, d);
    if (!img) return img.error();
    const std::uint8_t white[4] = {255, 255, 255, 255};  // Texture::sample's answer for bad data
    Status st = ok ? img->upload(t.rgba.data(), std::size_t(t.width) * t.height * 4) : img->upload(white, 4);
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
  auto mat = vk::Buffer::create(*ctx, std::max<std::size_t>(s.materials.size(), 1) * sizeof(GpuMaterial), kHostInput,
                                vk::MemoryUsage::Upload);
  if (!mat) return mat.error();
  materials = std::move(mat).value();
  auto ins = vk::Buffer::create(*ctx, std::max<std::size_t>(recordInstance.size(), 1) * sizeof(GpuInstance), kHostInput,
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
    VkDescriptorSetLayoutBinding lb{};
    lb.binding = std::uint32_t(b);
    lb.descriptorCount = 1;
    // Any-hit: cut-outs read the scene's records and textures (probe_cutout.rahit).
    lb.stageFlags = VK_SHADER_STAGE_RAYGEN_BIT_KHR | VK_SHADER_STAGE_COMPUTE_BIT |
                    VK_SHADER_STAGE_ANY_HIT_BIT_KHR;
    lb.descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
    VkDescriptorBindingFlags f = 0;
    if (b == PC_BIND_TLAS) lb.descriptorType = VK_DESCRIPTOR_TYPE_ACCELERATION_STRUCTURE_KHR;
    if (b == PC_BIND_TEXTURES) {
      lb.descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
      lb.descriptorCount = std::uint32_t(textures.size());
      f = VK_DESCRIPTOR_BINDING_PARTIALLY_BOUND_BIT | VK_DESCRIPTOR_BINDING_VARIABLE_DESCRIPTOR_COUNT_BIT;
    }
    bindings.push_back(lb);
    flags.push_back(f);
  }
  VkDescriptorSetLayoutBindingFlagsCreateInfo bfi{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_BINDING_FLAGS_CREATE_INFO};
  bfi.bindingCount = std::uint32_t(flags.size());
  bfi.pBindingFlags = flags.data();
  VkDescriptorSetLayoutCreateInfo lci{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
  lci.pNext = &bfi;
  lci.bindingCount = std::uint32_t(bindings.size());
  lci.pBindings = bindings.data();
  VkDescriptorSetLayout dsl = VK_NULL_HANDLE;
  PC_VK_TRY(vkCreateDescriptorSetLayout(ctx->device(), &lci, nullptr, &dsl));
  setLayout = vk::UniqueDescriptorSetLayout(ctx->device(), dsl);

  const VkDescriptorPoolSize sizes[] = {
      {VK_DESCRIPTOR_TYPE_ACCELERATION_STRUCTURE_KHR, 2},
      {VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 2 * std::uint32_t(PC_BINDING_COUNT)},
      {VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER,
       2 * std::max<std::uint32_t>(std::uint32_t(textures.size()), 1)}};
  VkDescriptorPoolCreateInfo pci{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  pci.maxSets = 2;
  pci.poolSizeCount = 3;
  pci.pPoolSizes = sizes;
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

  VkPushConstantRange push{VK_SHADER_STAGE_RAYGEN_BIT_KHR | VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(TracePush)};
  VkPipelineLayoutCreateInfo plci{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
  plci.setLayoutCount = 1;
  plci.pSetLayouts = &dsl;
  plci.pushConstantRangeCount = 1;
  plci.pPushConstantRanges = &push;
  VkPipelineLayout pl = VK_NULL_HANDLE;
  PC_VK_TRY(vkCreatePipelineLayout(ctx->device(), &plci, nullptr, &pl));
  pipelineLayout = vk::UniquePipelineLayout(ctx->device(), pl);

  // ---- ray tracing: stages raygen, miss..., closest hit, and in scenes with cut-outs any
  // hit; groups: raygen, the misses, then one triangle hit group of the hit shaders. Scenes
  // without cut-outs keep the pipelines they had before cut-outs existed: no any-hit shader,
  // opaque ray flags (specialization constant 0 of the ray generation shaders). ----
  const bool cutOuts = scene->hasCutOuts();
  const VkBool32 cutOutsSpec = cutOuts ? VK_TRUE : VK_FALSE;
  const VkSpecializationMapEntry cutOutsEntry{0, 0, sizeof(VkBool32)};
  const VkSpecializationInfo raygenSpec{1, &cutOutsEntry, sizeof cutOutsSpec, &cutOutsSpec};
  auto makeRayPipeline = [&](const char* raygen, std::vector<const char*> misses) -> Result<vk::UniquePipeline> {
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
      VkRayTracingShaderGroupCreateInfoKHR g{VK_STRUCTURE_TYPE_RAY_TRACING_SHADER_GROUP_CREATE_INFO_KHR};
      g.generalShader = g.closestHitShader = g.anyHitShader = g.intersectionShader = VK_SHADER_UNUSED_KHR;
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
    PC_VK_TRY(ctx->rt().createRayTracingPipelines(ctx->device(), VK_NULL_HANDLE, VK_NULL_HANDLE, 1, &rci, nullptr, &p));
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

  auto variantOf = [](const char* variable) {
    const char* v = std::getenv(variable);
    const int n = v ? std::atoi(v) : 0;
    if (n != 0) logWarn(std::string(variable) + "=" + std::to_string(n) + ": timing experiment, fields may be wrong");
    return n;
  };
  blendVariant = variantOf("PC_BLEND_VARIANT");
  shadeVariant = variantOf("PC_SHADE_VARIANT");
  overlapVariant = variantOf("PC_OVERLAP_VARIANT");
  shadowSlotTimes = std::getenv("PC_SHADOW_SLOT_TIMES") != nullptr;
  // constant_id 0: kVariant, 1: kRoulette
  auto shade = computePipeline("probe_shade.comp.spv", {shadeVariant, options.shadowRouletteShare > 0.0f ? 1 : 0});
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

Result<vk::UniquePipeline> VulkanTracer::Impl::computePipeline(const char* name, const std::vector<int>& constants) {
  auto m = vk::loadShader(*ctx, name);
  if (!m) return m.error();
  VkComputePipelineCreateInfo cci{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
  cci.stage = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
  cci.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
  cci.stage.module = m->get();
  cci.stage.pName = "main";
  std::vector<VkSpecializationMapEntry> entries;
  for (std::size_t i = 0; i < constants.size(); ++i)
    entries.push_back({std::uint32_t(i), std::uint32_t(i * sizeof(int)), sizeof(int)});
  const VkSpecializationInfo spec{std::uint32_t(entries.size()), entries.data(), constants.size() * sizeof(int),
                                  constants.data()};
  if (!constants.empty()) cci.stage.pSpecializationInfo = &spec;
  cci.layout = pipelineLayout.get();
  if (ctx->capturesStatistics()) cci.flags |= VK_PIPELINE_CREATE_CAPTURE_STATISTICS_BIT_KHR;
  VkPipeline p = VK_NULL_HANDLE;
  PC_VK_TRY(vkCreateComputePipelines(ctx->device(), VK_NULL_HANDLE, 1, &cci, nullptr, &p));
  logStatistics(name, p);
  return vk::UniquePipeline(ctx->device(), p);
}

void VulkanTracer::Impl::logStatistics(const char* name, VkPipeline pipeline) const {
  for (const std::string& line : ctx->pipelineStatistics(pipeline)) logInfo(std::string(name) + " " + line);
}

int VulkanTracer::Impl::blendGroupProbes(int rayCount) const {
  // Variants 10 and 12 are timing experiments (probe_blend.comp).
  return blendVariant == 10 ? 1 : blendVariant == 12 ? std::min(2, pcBlendProbes(rayCount)) : pcBlendProbes(rayCount);
}

Status VulkanTracer::Impl::ensureBlendPipeline(int rayCount) {
  const int scratch = pcBlendScratch(blendGroupProbes(rayCount), rayCount);
  if (blendPipeline && scratch == blendScratch) return Status::success();
  // constant_id 0: kVariant, 1: the shared scratch's entries.
  auto blend = computePipeline("probe_blend.comp.spv", {blendVariant, scratch});
  if (!blend) return blend.error();
  blendPipeline = std::move(blend).value();
  blendScratch = scratch;
  return Status::success();
}

// ---------------------------------------------------------------------------------------------
// Buffers and descriptors

int VulkanTracer::Impl::shadowSlots() const {
  return pcShadowSlots(int(state.lights.size()), int(emissive.size() / sizeof(GpuEmissiveTriangle)),
                       options.emissiveSamples);
}

void VulkanTracer::Impl::ensureRequestCapacity(std::size_t probes, int rayCount, int slots) {
  probes = std::max<std::size_t>(probes, 1);
  const std::size_t perProbe = std::size_t(std::max(rayCount, 1));
  // Buffers grow to the most probes and rays per probe asked for; where both at once would
  // pass what a pass holds (after a change of rays per probe), they are made for this request
  // alone.
  const std::size_t passRays =
      vulkanPassRays(maxPassRays, slots, shadowMemoryBudget, maxBufferBytes);
  const bool fits = probes <= probeCapacity && perProbe <= rayCapacity;
  std::size_t capProbes = std::max(probes, probeCapacity),
              capRays = std::max(perProbe, rayCapacity);
  if (fits) {
    capProbes = probeCapacity;
    capRays = rayCapacity;
  } else if (capProbes * capRays > std::max(passRays, probes * perProbe)) {
    capProbes = probes;
    capRays = perProbe;
  }
  // A round holds as many slots as the memory budget allows for the buffers' rays (at least
  // one, at most every slot).
  const std::size_t records = capProbes * capRays;
  const std::size_t slotBytes = records * (sizeof(GpuShadowRay) + sizeof(GpuShadowLight));
  // Each per-ray buffer is bound whole, so none may pass the device's storage-buffer range: a
  // round's slots share one shadow-ray buffer, so they are held to it as to the budget.
  const std::size_t slotsInRange = maxBufferBytes / (records * sizeof(GpuShadowRay));
  roundSlots = std::max(
      1, std::min({slots, int(std::min<std::size_t>(shadowMemoryBudget / slotBytes, 1u << 20)),
                   int(std::min<std::size_t>(slotsInRange, 1u << 20))}));
  // Past the range even with one slot a round (or without slots): the update is refused, as
  // buffers it cannot do without are.
  const std::size_t widestRecord =
      std::max({sizeof(GpuHit), std::size_t(16), slots > 0 ? sizeof(GpuShadowRay) : 0});
  if (records * widestRecord > maxBufferBytes)
    failOverRange(
        "a pass of " + std::to_string(capProbes) + " probes x " + std::to_string(capRays) + " rays",
        records * widestRecord, maxBufferBytes, "use fewer rays per probe");
  if (fits && roundSlots <= slotCapacity && slots <= counterSlotCapacity) return;
  probeCapacity = capProbes;
  rayCapacity = capRays;
  slotCapacity = roundSlots;  // not more: the budget is for these rays
  counterSlotCapacity = std::max(slots, counterSlotCapacity);
  using vk::MemoryUsage;
  const std::size_t rayRecords = probeCapacity * rayCapacity;
  params = orFail(vk::Buffer::create(*ctx, sizeof(UpdateParams), kHostInput, MemoryUsage::Upload),
                  "params");
  rayDirs = orFail(vk::Buffer::create(*ctx, rayCapacity * 16, kHostInput, MemoryUsage::Upload),
                   "ray directions");
  requests = orFail(vk::Buffer::create(*ctx, probeCapacity * 8, kHostInput, MemoryUsage::Upload),
                    "requests");
  hits = orFail(
      vk::Buffer::create(*ctx, rayRecords * sizeof(GpuHit), kStorage, MemoryUsage::DeviceLocal),
      "hits");
  rays = orFail(vk::Buffer::create(*ctx, rayRecords * 16, kStorage, MemoryUsage::DeviceLocal),
                "ray results");
  const std::size_t maskWords = std::max<std::size_t>(rayRecords * std::size_t(pcShadowMaskWords(slotCapacity)), 1);
  shadowMask = orFail(vk::Buffer::create(*ctx, maskWords * 4, kStorage, MemoryUsage::DeviceLocal),
                      "shadow masks");
  const std::size_t slotRecords = std::max<std::size_t>(rayRecords * std::size_t(slotCapacity), 1);
  shadowLight = orFail(vk::Buffer::create(*ctx, slotRecords * sizeof(GpuShadowLight), kStorage,
                                          MemoryUsage::DeviceLocal),
                       "shadow light");
  shadowRays = orFail(vk::Buffer::create(*ctx, slotRecords * sizeof(GpuShadowRay), kStorage,
                                         MemoryUsage::DeviceLocal),
                      "shadow rays");
  changes = orFail(vk::Buffer::create(*ctx, probeCapacity * 4, kStorage, MemoryUsage::DeviceLocal),
                   "changes");
  const std::size_t counterBytes =
      std::size_t(PC_COUNTER_WORDS) * 4 * std::size_t(std::max(counterSlotCapacity, 1));
  counters = orFail(
      vk::Buffer::create(*ctx, counterBytes,
                         kStorage | VK_BUFFER_USAGE_TRANSFER_SRC_BIT |
                             VK_BUFFER_USAGE_TRANSFER_DST_BIT | VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT,
                         MemoryUsage::DeviceLocal),
      "counters");
  countersReadback = orFail(vk::Buffer::create(*ctx, counterBytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                               MemoryUsage::Readback),
                            "counter readback");
  countersInit = orFail(
      vk::Buffer::create(*ctx, counterBytes, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, MemoryUsage::Upload),
      "counter start");
  {
    std::vector<std::uint32_t> init(counterBytes / 4);
    for (std::size_t s = 0; s < init.size() / PC_COUNTER_WORDS; ++s) {
      init[s * PC_COUNTER_WORDS + 1] = 1;
      init[s * PC_COUNTER_WORDS + 2] = 1;
    }
    countersInit.write(init.data(), counterBytes);
  }
  // At most every ray feeds every texel: the bound of the tap table.
  const std::size_t tapCapacity = (2 * PC_TAP_TEXELS + PC_TAP_TEXELS * (rayCapacity + 3)) * sizeof(std::uint32_t);
  tapsUpload = orFail(
      vk::Buffer::create(*ctx, tapCapacity, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, MemoryUsage::Upload),
      "tap upload");
  taps = orFail(vk::Buffer::create(*ctx, tapCapacity, kStorage | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                   MemoryUsage::DeviceLocal),
                "taps");
  descriptorsDirty = true;
}

// Makes the field buffers match `field`'s layout; true when they were (re)created.
bool VulkanTracer::Impl::ensureFieldBuffers(const Field& field) {
  if (haveField && std::memcmp(&layoutDesc, &field.desc, sizeof(FieldDesc)) == 0) return false;
  using vk::MemoryUsage;
  const VkBufferUsageFlags rw = kStorage | VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
  auto bytes = [](const Atlas& a) { return a.texels.size() * sizeof(float); };
  brickTotal = 0;
  brickOffset.fill(0);
  for (int k = 0; k < field.cascadeCount(); ++k) {
    brickOffset[k] = brickTotal;
    brickTotal += pcBrickCount(field.cascade(k));
  }
  for (int k = field.cascadeCount(); k < PC_MAX_CASCADES; ++k) brickOffset[k] = brickTotal;
  const std::size_t bricks = std::size_t(std::max(brickTotal, 1));
  const std::size_t packedBytes =
      bricks * PC_PROBES_PER_BRICK * PC_PACKED_PROBE_FLOATS * sizeof(float);
  // Every field buffer is bound whole, so none may pass the storage-buffer range; the packed
  // bricks (every tile of the field with its borders, when all change) are the largest.
  const std::size_t widest = std::max(bytes(field.irradiance) / 3 * 4, packedBytes);
  if (widest > maxBufferBytes)
    failOverRange("a field of " + std::to_string(field.probes.size()) + " probes", widest,
                  maxBufferBytes, "use fewer probes (the sidecar's volumes)");
  fieldDesc = orFail(vk::Buffer::create(*ctx, sizeof(FieldDesc), kHostInput, MemoryUsage::Upload),
                     "field desc");
  // The irradiance atlas holds a vec4 per texel on the GPU (field_buffers.glsl).
  irradiance = orFail(
      vk::Buffer::create(*ctx, bytes(field.irradiance) / 3 * 4, rw, MemoryUsage::DeviceLocal),
      "irradiance");
  depth =
      orFail(vk::Buffer::create(*ctx, bytes(field.depth), rw, MemoryUsage::DeviceLocal), "depth");
  occlusion = orFail(vk::Buffer::create(*ctx, bytes(field.occlusion), rw, MemoryUsage::DeviceLocal),
                     "occlusion");
  const std::size_t recordBytes = std::max<std::size_t>(field.probes.size(), 1) * sizeof(GpuProbeRecord);
  records = orFail(vk::Buffer::create(*ctx, recordBytes, rw, MemoryUsage::DeviceLocal), "records");
  recordsReadback = orFail(vk::Buffer::create(*ctx, recordBytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                              MemoryUsage::Readback),
                           "record readback");
  brickFlags =
      orFail(vk::Buffer::create(*ctx, bricks * 4, rw, MemoryUsage::DeviceLocal), "brick flags");
  const std::size_t listBytes = (PC_BRICK_LIST_HEADER + bricks) * 4;
  brickList = orFail(vk::Buffer::create(*ctx, listBytes, rw | VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT,
                                        MemoryUsage::DeviceLocal),
                     "brick list");
  brickListReadback = orFail(
      vk::Buffer::create(*ctx, listBytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT, MemoryUsage::Readback),
      "brick list readback");
  // Shaders write the packed tiles straight into host memory: only changed bricks cross.
  packed = orFail(vk::Buffer::create(*ctx, packedBytes, kStorage, MemoryUsage::Readback),
                  "packed bricks");
  layoutDesc = field.desc;
  haveField = true;
  syncedField = nullptr;
  descriptorsDirty = true;
  return true;
}

void VulkanTracer::Impl::ensureMirrors() {
  for (auto [host, device] : mirrors()) {
    if (device->get() && device->size() == host->size()) continue;
    *device =
        orFail(vk::Buffer::create(*ctx, host->size(), kStorage | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                  vk::MemoryUsage::DeviceLocal),
               "input copy");
    descriptorsDirty = true;
  }
}

void VulkanTracer::Impl::recordMirrorCopies() {
  for (auto [host, device] : mirrors()) {
    const VkBufferCopy copy{0, 0, host->size()};
    if (copy.size > 0) vkCmdCopyBuffer(cmd, host->get(), device->get(), 1, &copy);
  }
  vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT, kRayStage | kComputeStage,
                    VK_ACCESS_2_SHADER_STORAGE_READ_BIT);
}

void VulkanTracer::Impl::writeDescriptors() {
  ensureMirrors();
  if (!descriptorsDirty) return;
  std::array<VkDescriptorBufferInfo, PC_BINDING_COUNT> infos{};
  std::array<const vk::Buffer*, PC_BINDING_COUNT> buffers{};
  buffers[PC_BIND_PARAMS] = &paramsGpu;
  buffers[PC_BIND_FIELD] = &fieldDescGpu;
  buffers[PC_BIND_IRRADIANCE] = &irradiance;
  buffers[PC_BIND_DEPTH] = &depth;
  buffers[PC_BIND_OCCLUSION] = &occlusion;
  buffers[PC_BIND_PROBES] = &records;
  buffers[PC_BIND_REQUESTS] = &requestsGpu;
  buffers[PC_BIND_RAY_DIRS] = &rayDirsGpu;
  buffers[PC_BIND_RAYS] = &rays;
  buffers[PC_BIND_VERTICES] = &vertices;
  buffers[PC_BIND_INDICES] = &indices;
  buffers[PC_BIND_MESHES] = &meshes;
  buffers[PC_BIND_INSTANCES] = &instancesGpu;
  buffers[PC_BIND_MATERIALS] = &materialsGpu;
  buffers[PC_BIND_LIGHTS] = &lightsGpu;
  buffers[PC_BIND_EMISSIVE] = &emissiveGpu;
  buffers[PC_BIND_CHANGES] = &changes;
  buffers[PC_BIND_BRICK_FLAGS] = &brickFlags;
  buffers[PC_BIND_BRICK_LIST] = &brickList;
  buffers[PC_BIND_PACKED] = &packed;
  buffers[PC_BIND_COUNTERS] = &counters;
  buffers[PC_BIND_TAPS] = &taps;
  buffers[PC_BIND_HITS] = &hits;
  buffers[PC_BIND_SHADOW_MASK] = &shadowMask;
  buffers[PC_BIND_SHADOW_RAYS] = &shadowRays;
  buffers[PC_BIND_SHADOW_LIGHT] = &shadowLight;
  std::vector<VkDescriptorImageInfo> images;
  for (std::size_t i = 0; i < textures.size(); ++i)
    images.push_back(
        {textureSamplers[i], textures[i].view(), VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL});
  VkAccelerationStructureKHR tlas = accel.topLevel();
  VkWriteDescriptorSetAccelerationStructureKHR asw{
      VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET_ACCELERATION_STRUCTURE_KHR};
  asw.accelerationStructureCount = 1;
  asw.pAccelerationStructures = &tlas;
  auto writeSet = [&](VkDescriptorSet dst) {
    std::vector<VkWriteDescriptorSet> writes;
    for (int b = 0; b < PC_BINDING_COUNT; ++b) {
      if (!buffers[b] || !buffers[b]->get()) continue;
      infos[b] = buffers[b]->descriptor();
      VkWriteDescriptorSet w{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
      w.dstSet = dst;
      w.dstBinding = std::uint32_t(b);
      w.descriptorCount = 1;
      w.descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
      w.pBufferInfo = &infos[b];
      writes.push_back(w);
    }
    VkWriteDescriptorSet w{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
    w.pNext = &asw;
    w.dstSet = dst;
    w.dstBinding = PC_BIND_TLAS;
    w.descriptorCount = 1;
    w.descriptorType = VK_DESCRIPTOR_TYPE_ACCELERATION_STRUCTURE_KHR;
    writes.push_back(w);
    VkWriteDescriptorSet tw{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
    tw.dstSet = dst;
    tw.dstBinding = PC_BIND_TEXTURES;
    tw.descriptorCount = std::uint32_t(images.size());
    tw.descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
    tw.pImageInfo = images.data();
    writes.push_back(tw);
    vkUpdateDescriptorSets(ctx->device(), std::uint32_t(writes.size()), writes.data(), 0, nullptr);
  };
  writeSet(set);
  if (prevIrradiance.get()) {
    // The snapshot set: the field as the update found it, for the slices' trace and shading.
    buffers[PC_BIND_IRRADIANCE] = &prevIrradiance;
    buffers[PC_BIND_DEPTH] = &prevDepth;
    buffers[PC_BIND_OCCLUSION] = &prevOcclusion;
    buffers[PC_BIND_PROBES] = &prevRecords;
    writeSet(snapshotSet);
  }
  descriptorsDirty = false;
}

// Probes per slice of an update of `probes` probes at `rayCount` rays per probe: as few slices
// as the pass size allows, of even sizes (not full ones and a sliver).
std::size_t VulkanTracer::Impl::sliceProbes(std::size_t probes, int rayCount) const {
  const std::size_t rays =
      vulkanPassRays(maxPassRays, shadowSlots(), shadowMemoryBudget, maxBufferBytes);
  const std::size_t most = std::max<std::size_t>(1, rays / std::size_t(std::max(rayCount, 1)));
  const std::size_t slices = (probes + most - 1) / most;
  return slices <= 1 ? most : (probes + slices - 1) / slices;
}

// Snapshot buffers the size of the field's (made when an update first runs in slices).
void VulkanTracer::Impl::ensureSnapshot() {
  const VkBufferUsageFlags usage = kStorage | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
  for (auto [live, copy] : snapshots()) {
    if (copy->get() && copy->size() == live->size()) continue;
    *copy = orFail(vk::Buffer::create(*ctx, live->size(), usage, vk::MemoryUsage::DeviceLocal),
                   "field snapshot");
    descriptorsDirty = true;
  }
}

void VulkanTracer::Impl::recordSnapshot() {
  // After any upload of host edits into the field (recordFieldSync).
  vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT,
                    VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_READ_BIT);
  for (auto [live, copy] : snapshots()) {
    const VkBufferCopy region{0, 0, live->size()};
    vkCmdCopyBuffer(cmd, live->get(), copy->get(), 1, &region);
  }
  vk::memoryBarrier(cmd, VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT,
                    kRayStage | kComputeStage, kShaderRW);
}

void VulkanTracer::Impl::writeUpdateInputs(const Field& field, const UpdateRequest& request,
                                           std::size_t first, std::size_t count, bool blendTaps,
                                           bool sliced) {
  const int rayCount = field.settings.raysPerProbe;
  const std::size_t n = count;
  ensureRequestCapacity(n, rayCount, shadowSlots());
  ensureFieldBuffers(field);
  if (sliced) ensureSnapshot();
  writeDescriptors();
  traceSet = sliced ? snapshotSet : set;

  // The same directions as the Embree backend, computed once on the host.
  const std::vector<glm::vec3> dirs = probeRayDirections(rayCount, request.rotationSeed);
  auto* d = rayDirs.as<glm::vec4>();
  for (int i = 0; i < rayCount; ++i) d[i] = glm::vec4(dirs[i], 0.0f);
  if (blendTaps) {
    // The CPU's taps for these directions, laid out for the blend shader (gpu_trace.h); the
    // occlusion taps are the irradiance taps (same tile size, same lobe).
    const BlendTaps bt = BlendTaps::build(dirs.data(), rayCount, field.settings.distanceExponent);
    auto* out = tapsUpload.as<std::uint32_t>();
    std::uint32_t texel = 0, next = 2 * PC_TAP_TEXELS;
    for (const TexelTaps* tt : {&bt.irradiance, &bt.depth}) {
      const std::uint32_t texels = std::uint32_t(tt->begin.size() - 1);
      std::uint32_t most = 0;
      for (std::uint32_t t = 0; t < texels; ++t) most = std::max(most, tt->begin[t + 1] - tt->begin[t]);
      const std::uint32_t blocks = (most + 3) / 4;
      std::memset(out + next, 0, std::size_t(blocks) * 4 * texels * sizeof(std::uint32_t));
      for (std::uint32_t t = 0; t < texels; ++t) {
        const std::uint32_t first = tt->begin[t], count = tt->begin[t + 1] - first;
        out[2 * (texel + t)] = count;
        out[2 * (texel + t) + 1] = next + 4 * t;
        for (std::uint32_t j = 0; j < count; ++j) {
          // Exact: the CPU's weights are float16 values already.
          const std::uint32_t half = glm::packHalf1x16(tt->weight[first + j]);
          out[next + (j / 4) * 4 * texels + 4 * t + j % 4] = std::uint32_t(tt->ray[first + j]) | half << 16;
        }
      }
      texel += texels;
      next += blocks * 4 * texels;
    }
    tapBytes = std::size_t(next) * sizeof(std::uint32_t);
  }
  auto* r = requests.as<glm::ivec2>();
  for (std::size_t i = 0; i < n; ++i)
    r[i] = glm::ivec2(request.probes[first + i].cascade, request.probes[first + i].slot);

  UpdateParams p{};
  p.skyZenith = scene->sky.zenith;
  p.skyHorizon = scene->sky.horizon;
  p.skyGround = scene->sky.ground;
  p.rayCount = rayCount;
  p.probeCount = int(n);
  p.requestBase = int(first);
  p.shading = request.shading;
  p.lightCount = int(state.lights.size());
  p.emissiveCount = int(emissive.size() / sizeof(GpuEmissiveTriangle));
  p.emissiveSamples = options.emissiveSamples;
  p.seed = request.rotationSeed;
  p.hysteresis = field.settings.hysteresis;
  p.changeThreshold = request.changeThreshold;
  p.brickTotal = brickTotal;
  p.shadowSlots = shadowSlots();
  p.shadowRouletteShare = options.shadowRouletteShare;
  p.roundSlots = roundSlots;
  p.lightsResolved = pcShadowRounds(p.shadowSlots, roundSlots) > 1 ? 1 : 0;
  p.cascadeBrickOffset = glm::ivec4(brickOffset[0], brickOffset[1], brickOffset[2], brickOffset[3]);
  params.write(&p, sizeof p);

  // The blend reads the lobe exponent from the settings, as the CPU's blendProbe does.
  FieldDesc desc = field.desc;
  desc.distanceExponent = field.settings.distanceExponent;
  fieldDesc.write(&desc, sizeof desc);
}

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
  VkCommandBufferSubmitInfo cbi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_SUBMIT_INFO};
  cbi.commandBuffer = cmd;
  VkSubmitInfo2 si{VK_STRUCTURE_TYPE_SUBMIT_INFO_2};
  si.commandBufferInfoCount = 1;
  si.pCommandBufferInfos = &cbi;
  VkFence f = fence.get();
  checkCall(vkResetFences(ctx->device(), 1, &f), "vkResetFences");
  ++submissions;
  if (submissions == failSubmission) {
    // VulkanTracerOptions::failSubmission: what a device lost in this submission reports.
    fail(vk::vkErrorMessage("vkQueueSubmit2", VK_ERROR_DEVICE_LOST) + " (simulated)");
  }
  checkCall(vkQueueSubmit2(ctx->queue(), 1, &si, f), "vkQueueSubmit2");
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
                    kRayStage | kComputeStage, kShaderRW);
  timer.end(cmd);
}

// Invocations one launch may have: the compute limits and the ray-tracing invocation limit.
std::uint64_t VulkanTracer::Impl::maxLaunchWidth() const {
  const auto& limits = ctx->properties().limits;
  return std::min<std::uint64_t>(std::uint64_t(limits.maxComputeWorkGroupCount[0]) * limits.maxComputeWorkGroupSize[0],
                                 ctx->rayTracingProperties().maxRayDispatchInvocationCount);
}

void VulkanTracer::Impl::recordTrace(int probeCount, int rayCount) {
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_RAY_TRACING_KHR, tracePipeline.get());
  vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_RAY_TRACING_KHR, pipelineLayout.get(), 0, 1,
                          &traceSet, 0, nullptr);
  // One-dimensional launches (gpu_trace.h: PC_TRACE_TILE_PROBES); whole tiles per launch but
  // the last, so launch order runs on across launches.
  const std::uint64_t rays = std::uint64_t(std::max(rayCount, 1));
  const int maxProbes = std::max(PC_TRACE_TILE_PROBES, int(std::min<std::uint64_t>(maxLaunchWidth() / rays, 1u << 30)) /
                                                           PC_TRACE_TILE_PROBES * PC_TRACE_TILE_PROBES);
  for (int base = 0; base < probeCount; base += maxProbes) {
    const TracePush push{base, std::min(probeCount - base, maxProbes), 0, 0};
    vkCmdPushConstants(cmd, pipelineLayout.get(), VK_SHADER_STAGE_RAYGEN_BIT_KHR | VK_SHADER_STAGE_COMPUTE_BIT, 0,
                       sizeof push, &push);
    ctx->rt().cmdTraceRays(cmd, &traceTable.raygen, &traceTable.miss, &traceTable.hit, &traceTable.callable,
                           std::uint32_t(std::uint64_t(push.count) * rays), 1, 1);
  }
}

// A dispatch of `groups` workgroups, in rows of PC_DISPATCH_ROWS (the shaders flatten it).
void VulkanTracer::Impl::dispatchRows(std::uint64_t groups) {
  if (groups == 0) return;
  const std::uint64_t rows = (groups + PC_DISPATCH_ROWS - 1) / PC_DISPATCH_ROWS;
  vkCmdDispatch(cmd, std::uint32_t(std::min<std::uint64_t>(groups, PC_DISPATCH_ROWS)), std::uint32_t(rows), 1);
}

void VulkanTracer::Impl::recordShade(int probeCount, int rayCount, int slotBase) {
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, shadePipeline.get());
  vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipelineLayout.get(), 0, 1,
                          &traceSet, 0, nullptr);
  const TracePush push{0, 0, slotBase, 0};
  vkCmdPushConstants(cmd, pipelineLayout.get(),
                     VK_SHADER_STAGE_RAYGEN_BIT_KHR | VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof push,
                     &push);
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
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_RAY_TRACING_KHR, shadowPipeline.get());
  vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_RAY_TRACING_KHR, pipelineLayout.get(), 0, 1,
                          &traceSet, 0, nullptr);
  const std::uint64_t maxWidth = std::min<std::uint64_t>(maxLaunchWidth(), 1u << 30);
  // Per-slot timestamps (PC_SHADOW_SLOT_TIMES) in single rounds only: several rounds are one
  // timed span, which they would cut.
  const bool slotTimes = shadowSlotTimes && roundSlots >= shadowSlots();
  for (int slot = 0; slot < slots; ++slot) {
    const std::uint64_t listStart = std::uint64_t(slot) * rayCount;
    if (slotTimes) {
      timer.end(cmd);  // the previous slot's pair
      timer.begin(cmd, "shadow slot " + std::to_string(slotBase + slot));
    }
    if (ctx->rt().cmdTraceRaysIndirect && rayCount <= maxWidth && !boundedShadowLaunch) {
      const TracePush push{int(listStart), int(rayCount), slotBase, 0};
      vkCmdPushConstants(cmd, pipelineLayout.get(),
                         VK_SHADER_STAGE_RAYGEN_BIT_KHR | VK_SHADER_STAGE_COMPUTE_BIT, 0,
                         sizeof push, &push);
      ctx->rt().cmdTraceRaysIndirect(
          cmd, &shadowTable.raygen, &shadowTable.miss, &shadowTable.hit, &shadowTable.callable,
          counters.address() + VkDeviceAddress(slotBase + slot) * PC_COUNTER_WORDS * 4);
      continue;
    }
    for (std::uint64_t first = 0; first < rayCount; first += maxWidth) {
      const TracePush push{int(listStart + first), int(std::min(rayCount - first, maxWidth)),
                           slotBase, 0};
      vkCmdPushConstants(cmd, pipelineLayout.get(),
                         VK_SHADER_STAGE_RAYGEN_BIT_KHR | VK_SHADER_STAGE_COMPUTE_BIT, 0,
                         sizeof push, &push);
      ctx->rt().cmdTraceRays(cmd, &shadowTable.raygen, &shadowTable.miss, &shadowTable.hit,
                             &shadowTable.callable, std::uint32_t(push.count), 1, 1);
    }
  }
}

// The wavefront (gpu_trace.h): trace, shade, shadow rays, then the blend adds the visible light
// and blends; with more shadow slots than a round holds, shade and shadow rays once per round,
// each round's light added to the rays by the resolve pass.
void VulkanTracer::Impl::recordWavefront(int n, int rayCount, bool sliced) {
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
  const int groupProbes = blendGroupProbes(rayCount);
  auto recordBlend = [&] {
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, blendPipeline.get());
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipelineLayout.get(), 0, 1, &set,
                            0, nullptr);
    dispatchRows(std::uint64_t((n + groupProbes - 1) / groupProbes));
  };
  if (overlapVariant != 0 && rounds <= 1 && !sliced) {
    // Timing experiment (PC_OVERLAP_VARIANT): one span over the passes, some barriers left
    // out so that passes may run at once; fields are wrong. 8 every barrier, 1 trace with
    // shade, 4 shadow trace with blend, 5 both, 16 trace with blend, 17 trace, shade and blend.
    const int v = overlapVariant;
    auto rtToCs = [&] { vk::memoryBarrier(cmd, kRayStage, kShaderRW, kComputeStage, kShaderRW); };
    auto csToAll = [&] {
      vk::memoryBarrier(cmd, kComputeStage | kRayStage, kShaderRW,
                        kRayStage | kComputeStage | VK_PIPELINE_STAGE_2_DRAW_INDIRECT_BIT,
                        kShaderRW | VK_ACCESS_2_INDIRECT_COMMAND_READ_BIT);
    };
    timer.begin(cmd, "overlap span");
    recordTrace(n, rayCount);
    if (v & 16) recordBlend();
    if (!(v & 1)) rtToCs();
    recordShade(n, rayCount, 0);
    csToAll();
    if (slots > 0) recordShadowTrace(slots, std::uint64_t(n) * std::uint64_t(rayCount), 0);
    if (!(v & 4)) rtToCs();
    if (!(v & 16)) recordBlend();
    timer.end(cmd);
    vk::memoryBarrier(cmd, kComputeStage | kRayStage, kShaderRW, kComputeStage, kShaderRW);
    return;
  }
  timer.begin(cmd, "trace");
  recordTrace(n, rayCount);
  timer.end(cmd);
  vk::memoryBarrier(cmd, kRayStage, kShaderRW, kComputeStage, kShaderRW);

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
                      kRayStage | kComputeStage | VK_PIPELINE_STAGE_2_DRAW_INDIRECT_BIT,
                      kShaderRW | VK_ACCESS_2_INDIRECT_COMMAND_READ_BIT);

    if (slots > 0) {
      if (roundTimes) timer.begin(cmd, "shadow trace");
      recordShadowTrace(std::min(roundSlots, slots - slotBase),
                        std::uint64_t(n) * std::uint64_t(rayCount), slotBase);
      if (roundTimes) timer.end(cmd);
      vk::memoryBarrier(cmd, kRayStage, kShaderRW, kComputeStage, kShaderRW);
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
  recordBlend();
  timer.end(cmd);
  vk::memoryBarrier(cmd, kComputeStage, kShaderRW, kComputeStage, kShaderRW);
}

// ---------------------------------------------------------------------------------------------
// The tracer

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

Result<std::unique_ptr<VulkanTracer>> VulkanTracer::create(const Scene& scene, const TracerOptions& options,
                                                           const VulkanTracerOptions& vulkan) {
  auto impl = std::make_unique<Impl>();
  impl->scene = &scene;
  impl->options = options;
  if (Status s = impl->init(vulkan); !s) return s.error();
  std::unique_ptr<VulkanTracer> tracer(new VulkanTracer(std::move(impl)));
  try {
    tracer->setState(evaluateScene(scene, 0.0));
  } catch (const TracerFailure& e) {
    return Error{e.what()};
  }
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

std::string VulkanTracer::name() const { return "vulkan (" + impl_->ctx->deviceName() + ")"; }

const vk::Context& VulkanTracer::context() const { return *impl_->ctx; }

void VulkanTracer::setState(const SceneState& state) {
  impl_->guarded([&] { setStateOnce(state); });
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
    const glm::mat4 t = isStatic                                  ? glm::mat4(1.0f)
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
  m.accel.setInstances(top);
  m.tlasDirty = true;

  // Lights, and emissive triangles by the same rule as the CPU (EmissiveLights).
  std::vector<GpuLight> lights;
  for (const Light& l : state.lights) {
    GpuLight g{};
    g.position = l.position;
    g.type = l.type == LightType::Directional ? PC_LIGHT_DIRECTIONAL
             : l.type == LightType::Spot      ? PC_LIGHT_SPOT
                                              : PC_LIGHT_POINT;
    g.direction = glm::normalize(l.direction);
    g.range = l.range;
    g.power = l.color * l.intensity;
    g.cosOuter = std::cos(l.outerConeAngle);
    g.cosInner = std::cos(std::min(l.innerConeAngle, l.outerConeAngle));
    lights.push_back(g);
  }
  const EmissiveLights emissive = EmissiveLights::build(scene, state);
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
    const auto tex = [&](int t) { return t >= 0 && std::size_t(t) < scene.textures.size() ? t : -1; };
    GpuMaterial g{};
    g.baseColor = s.baseColor;
    g.baseColorTexture = tex(s.baseColorTexture);
    g.emissive = s.emissive;
    g.emissiveTexture = tex(s.emissiveTexture);
    g.sampled = emissive.sampled(int(i)) ? 1 : 0;
    g.alphaTexture = tex(s.alphaTexture);
    g.alphaChannel = std::clamp(s.alphaChannel, 0, 3);
    g.alphaCutoff = s.isCutOut() ? s.alphaCutoff : 0.0f;
    g.baseAlpha = s.baseAlpha;
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

UpdateStats VulkanTracer::update(Field& field, const UpdateRequest& request) {
  return impl_->guarded([&] { return updateOnce(field, request); });
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
  std::vector<vk::Buffer> staging;
  for (std::size_t first = 0; first < total; first += perSlice) {
    const int n = int(std::min(perSlice, total - first));
    const bool firstSlice = first == 0, lastSlice = first + std::size_t(n) == total;
    m.writeUpdateInputs(field, request, first, std::size_t(n), firstSlice, sliced);
    m.begin();
    VkCommandBuffer cmd = m.cmd;
    if (firstSlice) {
      m.recordFieldSync(field, staging);
      if (m.tlasDirty) {
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
                      kRayStage | kComputeStage | VK_PIPELINE_STAGE_2_DRAW_INDIRECT_BIT,
                      kShaderRW | VK_ACCESS_2_INDIRECT_COMMAND_READ_BIT);
    m.recordWavefront(n, rayCount, sliced);

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
  const std::size_t ri = std::size_t(PC_PROBES_PER_BRICK) * si * 3, rd = std::size_t(PC_PROBES_PER_BRICK) * sd * 2,
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
    for (int y = 0; y < si; ++y, src += ri) std::memcpy(field.irradiance.at(oi.x, oi.y + y), src, ri * 4);
    const glm::ivec2 od = pcAtlasTileOrigin(c, firstSlot, sd);
    for (int y = 0; y < sd; ++y, src += rd) std::memcpy(field.depth.at(od.x, od.y + y), src, rd * 4);
    const glm::ivec2 oo = pcAtlasTileOrigin(c, firstSlot, so);
    for (int y = 0; y < so; ++y, src += ro) std::memcpy(field.occlusion.at(oo.x, oo.y + y), src, ro * 4);
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

double VulkanTracer::traceOnly(Field& field, const UpdateRequest& request) {
  return impl_->guarded([&] { return traceOnlyOnce(field, request); });
}

double VulkanTracer::traceOnlyOnce(Field& field, const UpdateRequest& request) {
  Impl& m = *impl_;
  const std::size_t total = request.probes.size();
  const int rayCount = field.settings.raysPerProbe;
  const std::size_t perSlice = m.sliceProbes(total, rayCount);
  std::vector<vk::Buffer> staging;
  double ms = 0.0;
  // In the update's slices; the field stays as it is, so every slice reads it as it is.
  for (std::size_t first = 0; first < total; first += perSlice) {
    const std::size_t n = std::min(perSlice, total - first);
    m.writeUpdateInputs(field, request, first, n, false, false);
    m.begin();
    if (first == 0) {
      m.recordFieldSync(field, staging);
      if (m.tlasDirty) {
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
