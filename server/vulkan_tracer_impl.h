// Internals of the Vulkan tracer, shared by its source files and by nothing else:
// vulkan_tracer_setup.cpp (device, scene upload, pipelines), vulkan_tracer_buffers.cpp
// (buffers, descriptors, an update's inputs), vulkan_tracer_passes.cpp (recording the passes
// of an update) and vulkan_tracer.cpp (the Tracer calls).
#pragma once

#include <algorithm>
#include <array>
#include <chrono>
#include <cstring>
#include <optional>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "../common/log.h"
#include "../common/vulkan/texture_samplers.h"
#include "../cpu/lighting.h"
#include "../shaders/interop/gpu_trace.h"
#include "../shaders/interop/sdf_grid.h"
#include "probe_blend.h"
#include "vulkan_accel.h"
#include "vulkan_tracer.h"

namespace pc {
namespace vulkan_tracer_detail {

using namespace pc::gpu;

using Clock = std::chrono::steady_clock;
inline double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

inline constexpr VkBufferUsageFlags kStorage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
// Host-written inputs: mapped host memory, copied to a device-local mirror per submission.
inline constexpr VkBufferUsageFlags kHostInput = kStorage | VK_BUFFER_USAGE_TRANSFER_SRC_BIT;
// The ray-tracing passes' stage (the SDF backend traces in compute: Impl::traceStage).
inline constexpr VkPipelineStageFlags2 kRayStage = VK_PIPELINE_STAGE_2_RAY_TRACING_SHADER_BIT_KHR;
inline constexpr VkPipelineStageFlags2 kComputeStage = VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT;
inline constexpr VkAccessFlags2 kShaderRW =
    VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT;

// Failures deep in an update (a lost device, memory the GPU lacks) throw a Failure, never
// abort; the Tracer calls catch it and return it as their Error (Impl::guarded), so nothing
// outside these files sees the exception. A server whose GPU fails goes on with another
// backend, and its clients with it.
class Failure : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

[[noreturn]] inline void fail(const std::string& message) { throw Failure(message); }

// The buffer, or a Failure naming it: resources the update cannot do without.
template <typename T>
T orFail(Result<T> r, const char* what) {
  if (!r) fail(std::string(what) + ": " + r.error().message);
  return std::move(r).value();
}

// A call's VkResult, as a Failure naming the call where it failed (a lost device, memory).
inline void checkCall(VkResult result, const char* call) {
  if (result != VK_SUCCESS) fail(vk::vkErrorMessage(call, result));
}

// Fails, saying why: `what` needs a buffer of `bytes`, past the storage-buffer range `range`
// that a descriptor binding the whole buffer can cover. `fix` says what to ask for instead.
[[noreturn]] inline void failOverRange(const std::string& what, std::size_t bytes,
                                       std::size_t range, const char* fix) {
  auto size = [](std::size_t b) {
    return b >= (std::size_t(1) << 20) ? std::to_string(b >> 20) + " MiB"
                                       : std::to_string(b) + " bytes";
  };
  fail(what + " needs buffers of " + size(bytes) + ", over the device's storage-buffer range of " +
       size(range) + ": " + fix);
}

inline VkDeviceSize alignUp(VkDeviceSize v, VkDeviceSize a) { return (v + a - 1) / a * a; }

// A ray-tracing pipeline's shader binding table: one raygen record, the miss records, one hit
// group record, in one buffer.
struct BindingTable {
  vk::Buffer buffer;
  VkStridedDeviceAddressRegionKHR raygen{}, miss{}, hit{}, callable{};
};

inline GpuProbeRecord toGpu(const ProbeRecord& r) {
  GpuProbeRecord g{};
  g.offset = r.offset;
  g.state = r.state;
  g.updates = r.updates;
  return g;
}

inline bool sameRecord(const ProbeRecord& a, const ProbeRecord& b) {
  return a.offset == b.offset && a.state == b.state && a.updates == b.updates;
}

}  // namespace vulkan_tracer_detail

// The tracer's files are written against these helpers and the interop types unqualified.
using namespace vulkan_tracer_detail;

struct VulkanTracer::Impl {
  // The SDF backend (VulkanTracing::DistanceField): no ray-tracing extensions, the probe and
  // shadow rays sphere-traced through a distance field in compute (vulkan_tracer_sdf.cpp).
  bool sdf = false;
  // The stage of the trace and shadow passes and the stages the descriptors and push constants
  // serve: ray tracing, or compute alone for the SDF backend.
  VkPipelineStageFlags2 traceStage = kRayStage;
  VkShaderStageFlags shaderStages = VK_SHADER_STAGE_RAYGEN_BIT_KHR | VK_SHADER_STAGE_COMPUTE_BIT;
  const Scene* scene = nullptr;
  std::optional<EmissiveSurfaces> surfaces;  // found once: each state only places them
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
  bool shadowSlotTimes = false;      // VulkanTracerOptions::shadowSlotTimes
  bool boundedShadowLaunch = false;  // VulkanTracerOptions::boundedShadowLaunch
  // Submissions made, and the one that fails as a lost device would (VulkanTracerOptions).
  int submissions = 0, failSubmission = 0;
  // The first failure's message: once set, every call fails with it (a lost device stays lost).
  std::string failure;
  // Runs `f`, the body of the Tracer call `call`, unless an earlier call failed: its value (a
  // Status where it returns nothing), or the Failure it throws as an Error naming the call,
  // remembered for every later call.
  template <typename F>
  auto guarded(const char* call, F&& f) {
    using Value = decltype(f());
    using Out = std::conditional_t<std::is_void_v<Value>, Status, Result<Value>>;
    const std::string prefix = std::string("vulkan tracer: ") + call + ": ";
    if (!failure.empty())
      return Out(Error{prefix + "refused, the tracer is unusable since an earlier call failed (" +
                       failure + ")"});
    try {
      if constexpr (std::is_void_v<Value>) {
        f();
        return Out(Status::success());
      } else {
        return Out(f());
      }
    } catch (const Failure& e) {
      failure = prefix + e.what();
      return Out(Error{failure});
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

  // ---- the SDF backend's distance field (vulkan_tracer_sdf.cpp) ----
  int sdfVoxels = 128;                        // VulkanTracerOptions::sdfVoxels
  SdfHeader sdfHeader{};                      // the grid's layout, fixed at the first build
  vk::Buffer sdfTrianglesHost, sdfTriangles;  // SdfTriangle[]: host-written, device copy
  vk::Buffer sdfGrid, sdfBricks, sdfHeaderReadback;
  vk::Buffer sdfOutside;  // uint[]: the triangles reaching outside the grid (host-written)
  vk::Buffer sdfLists;    // uint[]: each brick's cell's triangles (sdf_grid.h)
  vk::UniquePipeline sdfCellsPipeline, sdfBricksPipeline;
  bool sdfDirty = true;                       // the instances moved since the last build
  std::vector<glm::mat4> sdfTransforms;       // the animated records' transforms it was built for
  std::vector<SdfTriangle> sdfLastTriangles;  // the triangles it was built for
  std::uint32_t sdfAllocated = 0;             // bricks allocated (SdfHeader::brickCount)
  std::uint32_t sdfListed = 0;                // list references written (SdfHeader::listCount)
  std::size_t sdfLastOutside = 0;             // triangles outside the grid, last reported
  SdfBuildStats sdfBuild;
  std::vector<std::pair<std::string, double>> sdfPasses;  // the last build's, for the update
  // World-space triangles of every shading record in the current state.
  std::vector<SdfTriangle> sdfSceneTriangles() const;
  Status createSdfPipelines(bool cutOuts);
  // Builds the field where the instances moved (sdfDirty): its own submission.
  void ensureSdf();
  void recordSdfTrace(int probeCount, int rayCount);
  void recordSdfShadows(int slots, std::uint64_t rayCount, int slotBase);

  // ---- occlusion from layered depth maps (VulkanTracerOptions::ldmOcclusion,
  // vulkan_tracer_ldm.cpp) ----
  std::unique_ptr<LdmOcclusion> ldm;
  glm::vec3 ldmLo{0.0f}, ldmHi{0.0f};
  bool ldmBuilt = false;
  std::vector<glm::mat4> ldmTransforms;  // the state's instance transforms they were built for
  // Replaces the occlusion tiles of the request's probes (host and GPU) by their LDM occlusion,
  // after the update; marks the bricks whose tiles changed. Its own submissions.
  void applyLdmOcclusion(Field& field, const UpdateRequest& request, UpdateStats& stats);
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
  int loggedRounds = 1;            // the rounds last reported in the log
  vk::Buffer tapsUpload, taps;     // blend taps: host-written, copied to device memory per update
  std::size_t tapBytes = 0;        // of this update's taps
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
  vk::Buffer paramsGpu, rayDirsGpu, requestsGpu, fieldDescGpu, materialsGpu, instancesGpu,
      lightsGpu, emissiveGpu;
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
  Status createComputePasses();
  // A compute pipeline of `name` with its specialization constants (none when empty).
  using SpecConstant = vk::SpecConstant;
  Result<vk::UniquePipeline> computePipeline(const char* name,
                                             const std::vector<SpecConstant>& constants);
  // The compiler's statistics of a pipeline, logged where the context captures them.
  void logStatistics(const char* name, VkPipeline pipeline) const;
  // The blend pipeline for `rayCount` rays per probe: its shared scratch is sized for the
  // group (pcBlendProbes) at that ray count, rebuilt when the count changes.
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
  void recordWavefront(int probeCount, int rayCount);
  bool loggedSlices = false;  // the first update in slices is reported in the log
};

}  // namespace pc
