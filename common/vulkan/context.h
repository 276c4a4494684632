// The Vulkan context every GPU module works on: instance, one physical device, one logical
// device with one graphics+compute queue, and RAII helpers for the resources they all use
// (buffers, images, command pools, shader modules, timestamp queries).
//
// Ownership: every wrapper owns its handle and destroys it in its destructor; wrappers move,
// never copy. Wrappers keep a pointer to their Context, which must outlive them.
// Errors: creation returns pc::Result / pc::Status with the failing call and VkResult name;
// calls that a lost device can fail later (waitIdle, Buffer::invalidate) return their VkResult.
// Nothing here aborts: a GPU server falls back to the CPU, a client stops with a message.
#pragma once

#include <vulkan/vulkan.h>

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "../result.h"
#include "check.h"
#include "legacy_sync.h"

namespace pc::vk {

struct ContextOptions {
  bool validation = false;  // VK_LAYER_KHRONOS_validation + a debug messenger counting errors
  // Requires VK_KHR_ray_tracing_pipeline, VK_KHR_acceleration_structure,
  // VK_KHR_deferred_host_operations, buffer device address and descriptor indexing.
  bool rayTracing = false;
  bool presentation = false;                    // VK_KHR_swapchain on the device
  std::vector<std::string> instanceExtensions;  // e.g. glfwGetRequiredInstanceExtensions()
  // CPU implementations (lavapipe) are skipped unless allowed: they are correct but far too
  // slow to be picked by accident. Tests and CPU-only machines set this.
  bool allowCpuDevice = false;
  std::string deviceNameFilter;  // substring of the device name; empty: any
  bool multiview = false;        // VK_KHR_multiview (core 1.1 feature) for stereo rendering
  // VK_KHR_pipeline_executable_properties where the device has it (never required): the
  // compiler's statistics of a pipeline (registers, shared memory, ...), for diagnostics.
  bool pipelineStatistics = false;
  // The Vulkan version the context asks for and uses. 1.3 (the default) requires dynamic
  // rendering and synchronization2, which the client's renderer records. 1.2 is enough for
  // compute and ray tracing, so the server's tracers ask for it and run on devices that stop
  // at 1.2; such a context enables no 1.3 feature even where the device has them.
  std::uint32_t apiVersion = VK_API_VERSION_1_3;
};

// Extension entry points that the loader does not export; loaded per device.
struct RayTracingFunctions {
  PFN_vkCreateAccelerationStructureKHR createAccelerationStructure = nullptr;
  PFN_vkDestroyAccelerationStructureKHR destroyAccelerationStructure = nullptr;
  PFN_vkGetAccelerationStructureBuildSizesKHR getAccelerationStructureBuildSizes = nullptr;
  PFN_vkGetAccelerationStructureDeviceAddressKHR getAccelerationStructureDeviceAddress = nullptr;
  PFN_vkCmdBuildAccelerationStructuresKHR cmdBuildAccelerationStructures = nullptr;
  PFN_vkCreateRayTracingPipelinesKHR createRayTracingPipelines = nullptr;
  PFN_vkGetRayTracingShaderGroupHandlesKHR getRayTracingShaderGroupHandles = nullptr;
  PFN_vkCmdTraceRaysKHR cmdTraceRays = nullptr;
  // Null unless the device has rayTracingPipelineTraceRaysIndirect: launches whose size only
  // the GPU knows (the server's compacted shadow-ray list) read it from a buffer.
  PFN_vkCmdTraceRaysIndirectKHR cmdTraceRaysIndirect = nullptr;
};

class Context {
 public:
  static Result<std::unique_ptr<Context>> create(const ContextOptions& options);
  ~Context();
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;

  VkInstance instance() const { return instance_; }
  VkPhysicalDevice physicalDevice() const { return physicalDevice_; }
  VkDevice device() const { return device_; }
  VkQueue queue() const { return queue_; }
  std::uint32_t queueFamily() const { return queueFamily_; }
  const VkPhysicalDeviceProperties& properties() const { return properties_; }
  const VkPhysicalDeviceMemoryProperties& memoryProperties() const { return memory_; }
  // Valid when created with rayTracing.
  const VkPhysicalDeviceRayTracingPipelinePropertiesKHR& rayTracingProperties() const {
    return rtProperties_;
  }
  const RayTracingFunctions& rt() const { return rt_; }
  std::string deviceName() const { return properties_.deviceName; }
  bool isCpuDevice() const { return properties_.deviceType == VK_PHYSICAL_DEVICE_TYPE_CPU; }
  const ContextOptions& options() const { return options_; }

  // Errors the validation layer reported through the debug messenger (0 without validation).
  // Tests fail on any.
  std::uint32_t validationErrorCount() const { return validationErrors_.load(); }

  // With ContextOptions::pipelineStatistics on a device that has it: pipelines created with
  // VK_PIPELINE_CREATE_CAPTURE_STATISTICS_BIT_KHR (capturesStatistics()) report their
  // compiler statistics, one line per executable ("stage: name value, ..."). Empty otherwise.
  bool capturesStatistics() const { return getExecutableStatistics_ != nullptr; }
  std::vector<std::string> pipelineStatistics(VkPipeline pipeline) const;

  // Index of a memory type with `required` flags among `typeBits`, preferring one that also has
  // `preferred`; -1 when none.
  int findMemoryType(std::uint32_t typeBits, VkMemoryPropertyFlags required,
                     VkMemoryPropertyFlags preferred = 0) const;

  // Records `record` into a one-shot command buffer, submits it and waits for it to finish.
  Status submitAndWait(const std::function<void(VkCommandBuffer)>& record) const;

  // Waits for the device to finish its work. A lost device returns its error (it never
  // aborts): destroying resources afterwards is still allowed, so destructors may ignore it.
  VkResult waitIdle() const;

 private:
  Context() = default;
  static VKAPI_ATTR VkBool32 VKAPI_CALL onDebugMessage(
      VkDebugUtilsMessageSeverityFlagBitsEXT severity, VkDebugUtilsMessageTypeFlagsEXT types,
      const VkDebugUtilsMessengerCallbackDataEXT* data, void* user);

  ContextOptions options_;
  VkInstance instance_ = VK_NULL_HANDLE;
  VkDebugUtilsMessengerEXT messenger_ = VK_NULL_HANDLE;
  VkPhysicalDevice physicalDevice_ = VK_NULL_HANDLE;
  VkDevice device_ = VK_NULL_HANDLE;
  VkQueue queue_ = VK_NULL_HANDLE;
  std::uint32_t queueFamily_ = 0;
  VkCommandPool oneShotPool_ = VK_NULL_HANDLE;
  VkPhysicalDeviceProperties properties_{};
  VkPhysicalDeviceMemoryProperties memory_{};
  VkPhysicalDeviceRayTracingPipelinePropertiesKHR rtProperties_{};
  RayTracingFunctions rt_;
  PFN_vkGetPipelineExecutablePropertiesKHR getExecutableProperties_ = nullptr;
  PFN_vkGetPipelineExecutableStatisticsKHR getExecutableStatistics_ = nullptr;
  std::atomic<std::uint32_t> validationErrors_{0};
};

// ---- RAII for plain device-owned handles ------------------------------------------------------

// Owns one handle destroyed with vkDestroy<T>(device, handle, nullptr).
template <typename T, void (*Destroy)(VkDevice, T, const VkAllocationCallbacks*)>
class DeviceHandle {
 public:
  DeviceHandle() = default;
  DeviceHandle(VkDevice device, T handle) : device_(device), handle_(handle) {}
  ~DeviceHandle() { reset(); }
  DeviceHandle(DeviceHandle&& o) noexcept
      : device_(o.device_), handle_(std::exchange(o.handle_, VK_NULL_HANDLE)) {}
  DeviceHandle& operator=(DeviceHandle&& o) noexcept {
    if (this != &o) {
      reset();
      device_ = o.device_;
      handle_ = std::exchange(o.handle_, VK_NULL_HANDLE);
    }
    return *this;
  }
  DeviceHandle(const DeviceHandle&) = delete;
  DeviceHandle& operator=(const DeviceHandle&) = delete;
  void reset() {
    if (handle_ != VK_NULL_HANDLE) Destroy(device_, handle_, nullptr);
    handle_ = VK_NULL_HANDLE;
  }
  T get() const { return handle_; }
  explicit operator bool() const { return handle_ != VK_NULL_HANDLE; }

 private:
  VkDevice device_ = VK_NULL_HANDLE;
  T handle_ = VK_NULL_HANDLE;
};

using UniqueShaderModule = DeviceHandle<VkShaderModule, vkDestroyShaderModule>;
using UniquePipeline = DeviceHandle<VkPipeline, vkDestroyPipeline>;
using UniquePipelineLayout = DeviceHandle<VkPipelineLayout, vkDestroyPipelineLayout>;
using UniqueDescriptorSetLayout = DeviceHandle<VkDescriptorSetLayout, vkDestroyDescriptorSetLayout>;
using UniqueDescriptorPool = DeviceHandle<VkDescriptorPool, vkDestroyDescriptorPool>;
using UniqueSampler = DeviceHandle<VkSampler, vkDestroySampler>;
using UniqueFence = DeviceHandle<VkFence, vkDestroyFence>;
using UniqueSemaphore = DeviceHandle<VkSemaphore, vkDestroySemaphore>;
using UniqueImageView = DeviceHandle<VkImageView, vkDestroyImageView>;
using UniqueQueryPool = DeviceHandle<VkQueryPool, vkDestroyQueryPool>;

// ---- buffers ------------------------------------------------------------------------------------

enum class MemoryUsage {
  DeviceLocal,  // GPU only; filled by copies or shaders
  Upload,       // host-visible, coherent, persistently mapped: host writes, GPU reads
  Readback,     // host-visible, cached where possible, persistently mapped: GPU writes, host reads
};

class Buffer {
 public:
  // SHADER_DEVICE_ADDRESS is added to `usage` when the context has ray tracing (acceleration
  // structure inputs and shader binding tables need addresses).
  static Result<Buffer> create(const Context& ctx, VkDeviceSize size, VkBufferUsageFlags usage,
                               MemoryUsage memory);
  Buffer() = default;
  ~Buffer();
  Buffer(Buffer&& o) noexcept;
  Buffer& operator=(Buffer&& o) noexcept;
  Buffer(const Buffer&) = delete;
  Buffer& operator=(const Buffer&) = delete;

  VkBuffer get() const { return buffer_; }
  VkDeviceSize size() const { return size_; }
  VkDeviceAddress address() const { return address_; }  // 0 without device-address usage
  void* mapped() const { return mapped_; }              // null for DeviceLocal
  template <typename T>
  T* as() const {
    return static_cast<T*>(mapped_);
  }
  // Makes GPU writes visible to the host (no-op on coherent memory). Call after the GPU work
  // that wrote the buffer finished. A lost device can fail it: the caller decides what that
  // means (the tracer fails the call with an error, the client renderer stops).
  [[nodiscard]] VkResult invalidate() const;
  // Copies `bytes` to the start of a mapped buffer.
  void write(const void* data, std::size_t bytes, std::size_t offset = 0) const;
  VkDescriptorBufferInfo descriptor() const { return {buffer_, 0, VK_WHOLE_SIZE}; }

 private:
  void release();
  const Context* ctx_ = nullptr;
  VkBuffer buffer_ = VK_NULL_HANDLE;
  VkDeviceMemory memory_ = VK_NULL_HANDLE;
  VkDeviceSize size_ = 0;
  VkDeviceAddress address_ = 0;
  void* mapped_ = nullptr;
  bool coherent_ = true;
};

// Creates a DeviceLocal buffer holding `bytes` (through a staging buffer and a one-shot submit).
Result<Buffer> uploadBuffer(const Context& ctx, const void* data, std::size_t bytes,
                            VkBufferUsageFlags usage);

// ---- images -------------------------------------------------------------------------------------

struct ImageDesc {
  VkFormat format = VK_FORMAT_R8G8B8A8_UNORM;
  std::uint32_t width = 1, height = 1;
  std::uint32_t layers = 1;  // > 1: 2D array (or cube faces x6 when cube)
  std::uint32_t mipLevels = 1;
  bool cube = false;
  VkImageUsageFlags usage = VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT;
  VkSampleCountFlagBits samples = VK_SAMPLE_COUNT_1_BIT;
};

class Image {
 public:
  // Device-local image with a view over all layers and levels (2D, 2D array or cube).
  static Result<Image> create(const Context& ctx, const ImageDesc& desc);
  Image() = default;
  ~Image();
  Image(Image&& o) noexcept;
  Image& operator=(Image&& o) noexcept;
  Image(const Image&) = delete;
  Image& operator=(const Image&) = delete;

  VkImage get() const { return image_; }
  VkImageView view() const { return view_; }
  const ImageDesc& desc() const { return desc_; }
  VkImageLayout layout() const { return layout_; }
  VkImageAspectFlags aspect() const;
  VkImageSubresourceRange range() const;

  // Records a full-image layout transition and remembers the new layout. The masks are
  // synchronization2's; it is recorded with Vulkan 1.0's barrier (legacy_sync.h).
  // The stages/accesses default to "everything": correct, and fine outside hot paths.
  void transition(VkCommandBuffer cmd, VkImageLayout newLayout,
                  VkPipelineStageFlags2 srcStage = VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT,
                  VkAccessFlags2 srcAccess = VK_ACCESS_2_MEMORY_WRITE_BIT,
                  VkPipelineStageFlags2 dstStage = VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT,
                  VkAccessFlags2 dstAccess = VK_ACCESS_2_MEMORY_READ_BIT |
                                             VK_ACCESS_2_MEMORY_WRITE_BIT);
  // Uploads every level's tightly packed texels, level 0 first, each level's layers one after
  // another, and leaves the image in SHADER_READ_ONLY_OPTIMAL. `bytes` must be their exact sum.
  Status upload(const void* data, std::size_t bytes);

 private:
  void release();
  const Context* ctx_ = nullptr;
  VkImage image_ = VK_NULL_HANDLE;
  VkDeviceMemory memory_ = VK_NULL_HANDLE;
  VkImageView view_ = VK_NULL_HANDLE;
  ImageDesc desc_;
  VkImageLayout layout_ = VK_IMAGE_LAYOUT_UNDEFINED;
};

// Bytes per texel of the uncompressed formats the project uses (0 for others).
std::uint32_t formatTexelBytes(VkFormat format);

// ---- commands -----------------------------------------------------------------------------------

class CommandPool {
 public:
  // Pool on the context's queue family; buffers can be reset individually.
  static Result<CommandPool> create(const Context& ctx);
  CommandPool() = default;
  ~CommandPool();
  CommandPool(CommandPool&& o) noexcept;
  CommandPool& operator=(CommandPool&& o) noexcept;
  CommandPool(const CommandPool&) = delete;
  CommandPool& operator=(const CommandPool&) = delete;

  VkCommandPool get() const { return pool_; }
  Result<VkCommandBuffer> allocate() const;  // freed with the pool

  // Records into a fresh primary buffer, submits, waits, frees it.
  Status submitAndWait(const std::function<void(VkCommandBuffer)>& record) const;

 private:
  const Context* ctx_ = nullptr;
  VkCommandPool pool_ = VK_NULL_HANDLE;
};

// One memory barrier between two pipeline stages, in synchronization2's masks, recorded with
// Vulkan 1.0's barrier so that it runs on Vulkan 1.2 devices too (legacy_sync.h).
void memoryBarrier(VkCommandBuffer cmd, VkPipelineStageFlags2 srcStage, VkAccessFlags2 srcAccess,
                   VkPipelineStageFlags2 dstStage, VkAccessFlags2 dstAccess);

// ---- shaders ------------------------------------------------------------------------------------

// The SPIR-V file `name` in the first data folder's shaders/ that holds it
// (common/data_folders.h: beside the executable, where pc_compile_shaders puts it, then the
// install's share/probecast/shaders, then $PROBECAST_DATA/shaders); where none does, the path
// beside the executable. `name` is the source file name plus ".spv", e.g. "probe_trace.rgen.spv".
std::filesystem::path shaderPath(std::string_view name);
Result<UniqueShaderModule> loadShader(const Context& ctx, std::string_view name);
Result<UniqueShaderModule> createShaderModule(const Context& ctx,
                                              std::span<const std::uint32_t> spirv);
// One specialization constant of a compute shader: ints and bools (VkBool32) alike.
struct SpecConstant {
  std::uint32_t id;  // the shader's constant_id
  int value;
};
// The compute pipeline of the SPIR-V file `name` (loadShader) with `layout`, specialized by
// `constants`.
Result<UniquePipeline> createComputePipeline(const Context& ctx, std::string_view name,
                                             VkPipelineLayout layout,
                                             std::span<const SpecConstant> constants = {},
                                             VkPipelineCreateFlags flags = 0);
// A descriptor set layout of `bindings`; `flags`, where given, holds one
// VkDescriptorBindingFlags per binding (VK_EXT_descriptor_indexing's partially bound and
// variable-count arrays).
Result<UniqueDescriptorSetLayout> createDescriptorSetLayout(
    const Context& ctx, std::span<const VkDescriptorSetLayoutBinding> bindings,
    std::span<const VkDescriptorBindingFlags> flags = {});
// A pipeline layout of one descriptor set layout and, where pushBytes > 0, one push-constant
// range from offset 0 for `pushStages`.
Result<UniquePipelineLayout> createPipelineLayout(const Context& ctx,
                                                  VkDescriptorSetLayout setLayout,
                                                  VkShaderStageFlags pushStages = 0,
                                                  std::uint32_t pushBytes = 0);

// ---- timestamps ---------------------------------------------------------------------------------

// Named GPU passes timed with timestamp queries. Per frame/update:
//   timer.reset(cmd); timer.begin(cmd, "trace"); ...; timer.end(cmd); ...; submit, wait;
//   timer.results() -> {{"trace", 1.23}, ...} in milliseconds.
// Passes are sequential: begin() writes a timestamp after all prior work finished, end() after
// the pass's work finished.
class GpuTimer {
 public:
  static Result<GpuTimer> create(const Context& ctx, std::uint32_t maxPasses = 32);
  void reset(VkCommandBuffer cmd);
  void begin(VkCommandBuffer cmd, std::string name);
  void end(VkCommandBuffer cmd);
  // Fetches the timestamps of the last submitted frame (waits for them).
  std::vector<std::pair<std::string, double>> results() const;
  bool supported() const { return supported_; }

 private:
  const Context* ctx_ = nullptr;
  UniqueQueryPool pool_;
  std::uint32_t capacity_ = 0, used_ = 0;
  std::vector<std::string> names_;
  double periodNs_ = 1.0;
  bool supported_ = false;
};

}  // namespace pc::vk
