#include "context.h"

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <optional>

#include "../log.h"

namespace pc::vk {

namespace {

constexpr const char* kValidationLayer = "VK_LAYER_KHRONOS_validation";
constexpr const char* kNoDriverHint =
    "install a Vulkan driver: mesa-vulkan-drivers from bookworm-backports (lavapipe, CPU) or "
    "your GPU's driver";

bool hasExtension(const std::vector<VkExtensionProperties>& list, const char* name) {
  return std::any_of(list.begin(), list.end(), [&](const VkExtensionProperties& e) {
    return std::strcmp(e.extensionName, name) == 0;
  });
}

std::vector<VkExtensionProperties> deviceExtensions(VkPhysicalDevice device) {
  std::uint32_t count = 0;
  vkEnumerateDeviceExtensionProperties(device, nullptr, &count, nullptr);
  std::vector<VkExtensionProperties> list(count);
  vkEnumerateDeviceExtensionProperties(device, nullptr, &count, list.data());
  return list;
}

// "1.2" for VK_API_VERSION_1_2.
std::string versionName(std::uint32_t version) {
  return std::to_string(VK_API_VERSION_MAJOR(version)) + "." +
         std::to_string(VK_API_VERSION_MINOR(version));
}

// Lower is better: discrete GPUs first, CPU implementations last.
int typeRank(VkPhysicalDeviceType type) {
  switch (type) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU:
      return 0;
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU:
      return 1;
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU:
      return 2;
    case VK_PHYSICAL_DEVICE_TYPE_CPU:
      return 4;
    default:
      return 3;
  }
}

std::vector<const char*> requiredDeviceExtensions(const ContextOptions& o) {
  std::vector<const char*> ext;
  if (o.rayTracing) {
    ext.push_back(VK_KHR_RAY_TRACING_PIPELINE_EXTENSION_NAME);
    ext.push_back(VK_KHR_ACCELERATION_STRUCTURE_EXTENSION_NAME);
    ext.push_back(VK_KHR_DEFERRED_HOST_OPERATIONS_EXTENSION_NAME);
  }
  if (o.presentation) ext.push_back(VK_KHR_SWAPCHAIN_EXTENSION_NAME);
  return ext;
}

// The feature structures the context enables, chained; filled either with what a device
// supports (query) or with what is requested (create).
struct FeatureChain {
  VkPhysicalDeviceFeatures2 base{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
  VkPhysicalDeviceVulkan11Features v11{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_1_FEATURES};
  VkPhysicalDeviceVulkan12Features v12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
  VkPhysicalDeviceVulkan13Features v13{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_3_FEATURES};
  VkPhysicalDeviceAccelerationStructureFeaturesKHR as{
      VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_ACCELERATION_STRUCTURE_FEATURES_KHR};
  VkPhysicalDeviceRayTracingPipelineFeaturesKHR rt{
      VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_RAY_TRACING_PIPELINE_FEATURES_KHR};

  // Not movable: the pNext pointers point into the object itself. The 1.3 structure is chained
  // only for a 1.3 context: a 1.2 device does not know it.
  FeatureChain(bool rayTracing, bool vulkan13) {
    base.pNext = &v11;
    v11.pNext = &v12;
    void** tail = &v12.pNext;
    if (vulkan13) {
      *tail = &v13;
      tail = &v13.pNext;
    }
    if (rayTracing) {
      *tail = &as;
      as.pNext = &rt;
    }
  }
  FeatureChain(const FeatureChain&) = delete;
};

// Empty when `device` supports everything `o` needs; else what is missing.
std::string missingSupport(VkPhysicalDevice device, const ContextOptions& o) {
  VkPhysicalDeviceProperties props;
  vkGetPhysicalDeviceProperties(device, &props);
  if (props.apiVersion < o.apiVersion) return "Vulkan " + versionName(o.apiVersion);
  const auto available = deviceExtensions(device);
  for (const char* e : requiredDeviceExtensions(o))
    if (!hasExtension(available, e)) return e;
  const bool vulkan13 = o.apiVersion >= VK_API_VERSION_1_3;
  FeatureChain f(o.rayTracing, vulkan13);
  vkGetPhysicalDeviceFeatures2(device, &f.base);
  if (vulkan13 && (!f.v13.dynamicRendering || !f.v13.synchronization2))
    return "dynamicRendering/synchronization2";
  if (!f.v12.timelineSemaphore || !f.v12.bufferDeviceAddress)
    return "timelineSemaphore/bufferDeviceAddress";
  if (o.multiview && !f.v11.multiview) return "multiview";
  if (o.rayTracing) {
    if (!f.as.accelerationStructure) return "accelerationStructure";
    if (!f.rt.rayTracingPipeline) return "rayTracingPipeline";
    if (!f.v12.runtimeDescriptorArray || !f.v12.descriptorBindingPartiallyBound ||
        !f.v12.shaderSampledImageArrayNonUniformIndexing ||
        !f.v12.descriptorBindingVariableDescriptorCount)
      return "descriptor indexing";
  }
  return {};
}

std::optional<std::uint32_t> pickQueueFamily(VkPhysicalDevice device) {
  std::uint32_t count = 0;
  vkGetPhysicalDeviceQueueFamilyProperties(device, &count, nullptr);
  std::vector<VkQueueFamilyProperties> families(count);
  vkGetPhysicalDeviceQueueFamilyProperties(device, &count, families.data());
  const VkQueueFlags want = VK_QUEUE_GRAPHICS_BIT | VK_QUEUE_COMPUTE_BIT;
  for (std::uint32_t i = 0; i < count; ++i)
    if ((families[i].queueFlags & want) == want) return i;
  return std::nullopt;
}

template <typename F>
F load(VkDevice device, const char* name) {
  return reinterpret_cast<F>(vkGetDeviceProcAddr(device, name));
}

}  // namespace

const char* resultName(VkResult r) {
  switch (r) {
#define PC_NAME(x) \
  case x:          \
    return #x;
    PC_NAME(VK_SUCCESS)
    PC_NAME(VK_NOT_READY)
    PC_NAME(VK_TIMEOUT)
    PC_NAME(VK_EVENT_SET)
    PC_NAME(VK_EVENT_RESET)
    PC_NAME(VK_INCOMPLETE)
    PC_NAME(VK_ERROR_OUT_OF_HOST_MEMORY)
    PC_NAME(VK_ERROR_OUT_OF_DEVICE_MEMORY)
    PC_NAME(VK_ERROR_INITIALIZATION_FAILED)
    PC_NAME(VK_ERROR_DEVICE_LOST)
    PC_NAME(VK_ERROR_MEMORY_MAP_FAILED)
    PC_NAME(VK_ERROR_LAYER_NOT_PRESENT)
    PC_NAME(VK_ERROR_EXTENSION_NOT_PRESENT)
    PC_NAME(VK_ERROR_FEATURE_NOT_PRESENT)
    PC_NAME(VK_ERROR_INCOMPATIBLE_DRIVER)
    PC_NAME(VK_ERROR_TOO_MANY_OBJECTS)
    PC_NAME(VK_ERROR_FORMAT_NOT_SUPPORTED)
    PC_NAME(VK_ERROR_FRAGMENTED_POOL)
    PC_NAME(VK_ERROR_UNKNOWN)
    PC_NAME(VK_ERROR_OUT_OF_POOL_MEMORY)
    PC_NAME(VK_ERROR_INVALID_EXTERNAL_HANDLE)
    PC_NAME(VK_ERROR_FRAGMENTATION)
    PC_NAME(VK_ERROR_INVALID_OPAQUE_CAPTURE_ADDRESS)
    PC_NAME(VK_PIPELINE_COMPILE_REQUIRED)
    PC_NAME(VK_ERROR_SURFACE_LOST_KHR)
    PC_NAME(VK_ERROR_NATIVE_WINDOW_IN_USE_KHR)
    PC_NAME(VK_SUBOPTIMAL_KHR)
    PC_NAME(VK_ERROR_OUT_OF_DATE_KHR)
    PC_NAME(VK_ERROR_INCOMPATIBLE_DISPLAY_KHR)
    PC_NAME(VK_ERROR_VALIDATION_FAILED_EXT)
    PC_NAME(VK_THREAD_IDLE_KHR)
    PC_NAME(VK_THREAD_DONE_KHR)
    PC_NAME(VK_OPERATION_DEFERRED_KHR)
    PC_NAME(VK_OPERATION_NOT_DEFERRED_KHR)
#undef PC_NAME
    default:
      return "VkResult(unnamed)";
  }
}

std::string vkErrorMessage(const char* call, VkResult result) {
  return std::string(call) + " failed: " + resultName(result);
}

VKAPI_ATTR VkBool32 VKAPI_CALL Context::onDebugMessage(
    VkDebugUtilsMessageSeverityFlagBitsEXT severity, VkDebugUtilsMessageTypeFlagsEXT,
    const VkDebugUtilsMessengerCallbackDataEXT* data, void* user) {
  auto* self = static_cast<Context*>(user);
  const std::string text = std::string("vulkan: ") + (data && data->pMessage ? data->pMessage : "");
  if (severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT) {
    self->validationErrors_.fetch_add(1);
    logError(text);
  } else if (severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT) {
    logWarn(text);
  }
  return VK_FALSE;  // never abort the call: the counter is what tests check
}

Result<std::unique_ptr<Context>> Context::create(const ContextOptions& options) {
  std::unique_ptr<Context> ctx(new Context());
  ctx->options_ = options;

  // ---- instance ----
  std::uint32_t loaderVersion = 0;
  if (options.apiVersion < VK_API_VERSION_1_2)
    return Error{"Vulkan " + versionName(options.apiVersion) + " asked for; 1.2 is the oldest"};
  if (vkEnumerateInstanceVersion(&loaderVersion) != VK_SUCCESS ||
      loaderVersion < options.apiVersion) {
    return Error{"the Vulkan loader is older than " + versionName(options.apiVersion) + "; " +
                 std::string(kNoDriverHint)};
  }
  std::vector<const char*> instanceExt;
  for (const std::string& e : options.instanceExtensions) instanceExt.push_back(e.c_str());
  std::vector<const char*> layers;
  bool syncValidation = false;
  if (options.validation) {
    std::uint32_t count = 0;
    vkEnumerateInstanceLayerProperties(&count, nullptr);
    std::vector<VkLayerProperties> available(count);
    vkEnumerateInstanceLayerProperties(&count, available.data());
    const bool found = std::any_of(
        available.begin(), available.end(),
        [](const VkLayerProperties& l) { return std::strcmp(l.layerName, kValidationLayer) == 0; });
    if (!found)
      return Error{
          "validation requested but VK_LAYER_KHRONOS_validation is not installed "
          "(vulkan-validationlayers)"};
    layers.push_back(kValidationLayer);
    instanceExt.push_back(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
    std::uint32_t extCount = 0;
    vkEnumerateInstanceExtensionProperties(kValidationLayer, &extCount, nullptr);
    std::vector<VkExtensionProperties> layerExt(extCount);
    vkEnumerateInstanceExtensionProperties(kValidationLayer, &extCount, layerExt.data());
    syncValidation =
        std::any_of(layerExt.begin(), layerExt.end(), [](const VkExtensionProperties& e) {
          return std::strcmp(e.extensionName, VK_EXT_VALIDATION_FEATURES_EXTENSION_NAME) == 0;
        });
    if (syncValidation) instanceExt.push_back(VK_EXT_VALIDATION_FEATURES_EXTENSION_NAME);
  }
  VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
  app.pApplicationName = "probecast";
  app.pEngineName = "probecast";
  app.apiVersion = options.apiVersion;
  VkInstanceCreateInfo ici{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
  ici.pApplicationInfo = &app;
  ici.enabledLayerCount = std::uint32_t(layers.size());
  ici.ppEnabledLayerNames = layers.data();
  ici.enabledExtensionCount = std::uint32_t(instanceExt.size());
  ici.ppEnabledExtensionNames = instanceExt.data();
  // The messenger also sees instance creation and destruction.
  VkDebugUtilsMessengerCreateInfoEXT dci{VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT};
  dci.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT |
                        VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
  dci.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT |
                    VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                    VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
  dci.pfnUserCallback = &Context::onDebugMessage;
  dci.pUserData = ctx.get();
  // Synchronization validation too, where the layer offers it: a missing barrier is a race on a
  // real GPU even where a CPU implementation happens to run the commands in order.
  const VkValidationFeatureEnableEXT syncFeature =
      VK_VALIDATION_FEATURE_ENABLE_SYNCHRONIZATION_VALIDATION_EXT;
  VkValidationFeaturesEXT features{VK_STRUCTURE_TYPE_VALIDATION_FEATURES_EXT};
  features.enabledValidationFeatureCount = 1;
  features.pEnabledValidationFeatures = &syncFeature;
  if (options.validation) {
    ici.pNext = &dci;
    if (syncValidation) {
      features.pNext = &dci;
      ici.pNext = &features;
    }
  }
  const VkResult ir = vkCreateInstance(&ici, nullptr, &ctx->instance_);
  if (ir == VK_ERROR_INCOMPATIBLE_DRIVER)
    return Error{"no Vulkan driver (ICD) found; " + std::string(kNoDriverHint)};
  PC_VK_TRY(ir);
  if (options.validation) {
    auto createMessenger = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(ctx->instance_, "vkCreateDebugUtilsMessengerEXT"));
    if (!createMessenger) return Error{"VK_EXT_debug_utils is not available"};
    PC_VK_TRY(createMessenger(ctx->instance_, &dci, nullptr, &ctx->messenger_));
  }

  // ---- physical device ----
  std::uint32_t count = 0;
  PC_VK_TRY(vkEnumeratePhysicalDevices(ctx->instance_, &count, nullptr));
  std::vector<VkPhysicalDevice> devices(count);
  PC_VK_TRY(vkEnumeratePhysicalDevices(ctx->instance_, &count, devices.data()));
  if (devices.empty()) return Error{"no Vulkan device found; " + std::string(kNoDriverHint)};
  std::vector<std::string> rejected;
  VkPhysicalDevice best = VK_NULL_HANDLE;
  int bestRank = 1 << 30;
  for (VkPhysicalDevice d : devices) {
    VkPhysicalDeviceProperties props;
    vkGetPhysicalDeviceProperties(d, &props);
    const std::string name = props.deviceName;
    if (!options.deviceNameFilter.empty() &&
        name.find(options.deviceNameFilter) == std::string::npos) {
      rejected.push_back(name + " (name does not match '" + options.deviceNameFilter + "')");
      continue;
    }
    if (props.deviceType == VK_PHYSICAL_DEVICE_TYPE_CPU && !options.allowCpuDevice) {
      rejected.push_back(name + " (CPU implementation; not allowed)");
      continue;
    }
    if (const std::string missing = missingSupport(d, options); !missing.empty()) {
      rejected.push_back(name + " (no " + missing + ")");
      continue;
    }
    if (!pickQueueFamily(d)) {
      rejected.push_back(name + " (no graphics+compute queue)");
      continue;
    }
    if (typeRank(props.deviceType) < bestRank) best = d, bestRank = typeRank(props.deviceType);
  }
  if (best == VK_NULL_HANDLE) {
    std::string msg = options.rayTracing
                          ? "no Vulkan device with ray tracing (VK_KHR_ray_tracing_pipeline)"
                          : "no suitable Vulkan device";
    msg += ":";
    for (const std::string& r : rejected) msg += " " + r + ";";
    return Error{msg};
  }
  ctx->physicalDevice_ = best;
  vkGetPhysicalDeviceProperties(best, &ctx->properties_);
  vkGetPhysicalDeviceMemoryProperties(best, &ctx->memory_);
  if (options.rayTracing) {
    ctx->rtProperties_ = {VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_RAY_TRACING_PIPELINE_PROPERTIES_KHR};
    VkPhysicalDeviceProperties2 p2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
    p2.pNext = &ctx->rtProperties_;
    vkGetPhysicalDeviceProperties2(best, &p2);
  }
  ctx->queueFamily_ = *pickQueueFamily(best);

  // ---- device ----
  const bool vulkan13 = options.apiVersion >= VK_API_VERSION_1_3;
  FeatureChain supported(options.rayTracing, vulkan13);
  vkGetPhysicalDeviceFeatures2(best, &supported.base);
  FeatureChain enable(options.rayTracing, vulkan13);
  enable.base.features.shaderInt64 = supported.base.features.shaderInt64;
  enable.base.features.samplerAnisotropy = supported.base.features.samplerAnisotropy;
  enable.base.features.fragmentStoresAndAtomics = supported.base.features.fragmentStoresAndAtomics;
  enable.base.features.multiDrawIndirect = supported.base.features.multiDrawIndirect;
  // gl_PrimitiveID in fragment shaders (the client's visibility buffer) needs it.
  enable.base.features.geometryShader = supported.base.features.geometryShader;
  enable.base.features.shaderStorageImageWriteWithoutFormat =
      supported.base.features.shaderStorageImageWriteWithoutFormat;
  enable.v11.multiview = options.multiview ? VK_TRUE : VK_FALSE;
  enable.v11.shaderDrawParameters = supported.v11.shaderDrawParameters;
  enable.v12.bufferDeviceAddress = VK_TRUE;
  enable.v12.timelineSemaphore = VK_TRUE;
  enable.v12.hostQueryReset = supported.v12.hostQueryReset;
  enable.v12.scalarBlockLayout = supported.v12.scalarBlockLayout;
  // The client's compute rasterizer: depth and id in one 64-bit atomic max.
  enable.v12.shaderBufferInt64Atomics = supported.v12.shaderBufferInt64Atomics;
  enable.v12.descriptorIndexing = supported.v12.descriptorIndexing;
  enable.v12.runtimeDescriptorArray = supported.v12.runtimeDescriptorArray;
  enable.v12.descriptorBindingPartiallyBound = supported.v12.descriptorBindingPartiallyBound;
  enable.v12.descriptorBindingVariableDescriptorCount =
      supported.v12.descriptorBindingVariableDescriptorCount;
  enable.v12.shaderSampledImageArrayNonUniformIndexing =
      supported.v12.shaderSampledImageArrayNonUniformIndexing;
  enable.v12.shaderStorageBufferArrayNonUniformIndexing =
      supported.v12.shaderStorageBufferArrayNonUniformIndexing;
  if (vulkan13) {
    enable.v13.dynamicRendering = VK_TRUE;
    enable.v13.synchronization2 = VK_TRUE;
    enable.v13.maintenance4 = supported.v13.maintenance4;
  }
  if (options.rayTracing) {
    enable.as.accelerationStructure = VK_TRUE;
    enable.rt.rayTracingPipeline = VK_TRUE;
    enable.rt.rayTracingPipelineTraceRaysIndirect =
        supported.rt.rayTracingPipelineTraceRaysIndirect;
  }
  std::vector<const char*> ext = requiredDeviceExtensions(options);
  VkPhysicalDevicePipelineExecutablePropertiesFeaturesKHR executableInfo{
      VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PIPELINE_EXECUTABLE_PROPERTIES_FEATURES_KHR};
  const bool statistics =
      options.pipelineStatistics &&
      hasExtension(deviceExtensions(best), VK_KHR_PIPELINE_EXECUTABLE_PROPERTIES_EXTENSION_NAME);
  if (statistics) {
    ext.push_back(VK_KHR_PIPELINE_EXECUTABLE_PROPERTIES_EXTENSION_NAME);
    executableInfo.pipelineExecutableInfo = VK_TRUE;
    executableInfo.pNext = enable.base.pNext;
    enable.base.pNext = &executableInfo;
  }
  const float priority = 1.0f;
  VkDeviceQueueCreateInfo qci{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
  qci.queueFamilyIndex = ctx->queueFamily_;
  qci.queueCount = 1;
  qci.pQueuePriorities = &priority;
  VkDeviceCreateInfo dci2{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
  dci2.pNext = &enable.base;
  dci2.queueCreateInfoCount = 1;
  dci2.pQueueCreateInfos = &qci;
  dci2.enabledExtensionCount = std::uint32_t(ext.size());
  dci2.ppEnabledExtensionNames = ext.data();
  PC_VK_TRY(vkCreateDevice(best, &dci2, nullptr, &ctx->device_));
  vkGetDeviceQueue(ctx->device_, ctx->queueFamily_, 0, &ctx->queue_);
  if (statistics) {
    ctx->getExecutableProperties_ = load<PFN_vkGetPipelineExecutablePropertiesKHR>(
        ctx->device_, "vkGetPipelineExecutablePropertiesKHR");
    ctx->getExecutableStatistics_ = load<PFN_vkGetPipelineExecutableStatisticsKHR>(
        ctx->device_, "vkGetPipelineExecutableStatisticsKHR");
    if (!ctx->getExecutableProperties_) ctx->getExecutableStatistics_ = nullptr;
  }

  if (options.rayTracing) {
    RayTracingFunctions& f = ctx->rt_;
    VkDevice d = ctx->device_;
    f.createAccelerationStructure =
        load<PFN_vkCreateAccelerationStructureKHR>(d, "vkCreateAccelerationStructureKHR");
    f.destroyAccelerationStructure =
        load<PFN_vkDestroyAccelerationStructureKHR>(d, "vkDestroyAccelerationStructureKHR");
    f.getAccelerationStructureBuildSizes = load<PFN_vkGetAccelerationStructureBuildSizesKHR>(
        d, "vkGetAccelerationStructureBuildSizesKHR");
    f.getAccelerationStructureDeviceAddress = load<PFN_vkGetAccelerationStructureDeviceAddressKHR>(
        d, "vkGetAccelerationStructureDeviceAddressKHR");
    f.cmdBuildAccelerationStructures =
        load<PFN_vkCmdBuildAccelerationStructuresKHR>(d, "vkCmdBuildAccelerationStructuresKHR");
    f.createRayTracingPipelines =
        load<PFN_vkCreateRayTracingPipelinesKHR>(d, "vkCreateRayTracingPipelinesKHR");
    f.getRayTracingShaderGroupHandles =
        load<PFN_vkGetRayTracingShaderGroupHandlesKHR>(d, "vkGetRayTracingShaderGroupHandlesKHR");
    f.cmdTraceRays = load<PFN_vkCmdTraceRaysKHR>(d, "vkCmdTraceRaysKHR");
    if (enable.rt.rayTracingPipelineTraceRaysIndirect)
      f.cmdTraceRaysIndirect = load<PFN_vkCmdTraceRaysIndirectKHR>(d, "vkCmdTraceRaysIndirectKHR");
    if (!f.createAccelerationStructure || !f.destroyAccelerationStructure ||
        !f.getAccelerationStructureBuildSizes || !f.getAccelerationStructureDeviceAddress ||
        !f.cmdBuildAccelerationStructures || !f.createRayTracingPipelines ||
        !f.getRayTracingShaderGroupHandles || !f.cmdTraceRays) {
      return Error{"the driver lacks ray-tracing entry points it advertises"};
    }
  }

  VkCommandPoolCreateInfo pci{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
  pci.flags =
      VK_COMMAND_POOL_CREATE_TRANSIENT_BIT | VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
  pci.queueFamilyIndex = ctx->queueFamily_;
  PC_VK_TRY(vkCreateCommandPool(ctx->device_, &pci, nullptr, &ctx->oneShotPool_));
  return ctx;
}

std::vector<std::string> Context::pipelineStatistics(VkPipeline pipeline) const {
  std::vector<std::string> lines;
  if (!getExecutableStatistics_) return lines;
  VkPipelineInfoKHR info{VK_STRUCTURE_TYPE_PIPELINE_INFO_KHR};
  info.pipeline = pipeline;
  std::uint32_t count = 0;
  if (getExecutableProperties_(device_, &info, &count, nullptr) != VK_SUCCESS) return lines;
  std::vector<VkPipelineExecutablePropertiesKHR> executables(
      count, {VK_STRUCTURE_TYPE_PIPELINE_EXECUTABLE_PROPERTIES_KHR});
  if (getExecutableProperties_(device_, &info, &count, executables.data()) != VK_SUCCESS)
    return lines;
  for (std::uint32_t e = 0; e < count; ++e) {
    VkPipelineExecutableInfoKHR ei{VK_STRUCTURE_TYPE_PIPELINE_EXECUTABLE_INFO_KHR};
    ei.pipeline = pipeline;
    ei.executableIndex = e;
    std::uint32_t n = 0;
    if (getExecutableStatistics_(device_, &ei, &n, nullptr) != VK_SUCCESS) continue;
    std::vector<VkPipelineExecutableStatisticKHR> stats(
        n, {VK_STRUCTURE_TYPE_PIPELINE_EXECUTABLE_STATISTIC_KHR});
    if (getExecutableStatistics_(device_, &ei, &n, stats.data()) != VK_SUCCESS) continue;
    std::string line = std::string(executables[e].name) + " (subgroup " +
                       std::to_string(executables[e].subgroupSize) + "):";
    for (std::uint32_t i = 0; i < n; ++i) {
      const VkPipelineExecutableStatisticKHR& st = stats[i];
      std::string value;
      switch (st.format) {
        case VK_PIPELINE_EXECUTABLE_STATISTIC_FORMAT_BOOL32_KHR:
          value = st.value.b32 ? "yes" : "no";
          break;
        case VK_PIPELINE_EXECUTABLE_STATISTIC_FORMAT_INT64_KHR:
          value = std::to_string(st.value.i64);
          break;
        case VK_PIPELINE_EXECUTABLE_STATISTIC_FORMAT_UINT64_KHR:
          value = std::to_string(st.value.u64);
          break;
        case VK_PIPELINE_EXECUTABLE_STATISTIC_FORMAT_FLOAT64_KHR:
          value = std::to_string(st.value.f64);
          break;
        default:
          value = "?";
      }
      line += std::string(i ? ", " : " ") + st.name + " " + value;
    }
    lines.push_back(line);
  }
  return lines;
}

Context::~Context() {
  if (device_) {
    vkDeviceWaitIdle(device_);
    if (oneShotPool_) vkDestroyCommandPool(device_, oneShotPool_, nullptr);
    vkDestroyDevice(device_, nullptr);
  }
  if (messenger_) {
    auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(instance_, "vkDestroyDebugUtilsMessengerEXT"));
    if (destroy) destroy(instance_, messenger_, nullptr);
  }
  if (instance_) vkDestroyInstance(instance_, nullptr);
}

int Context::findMemoryType(std::uint32_t typeBits, VkMemoryPropertyFlags required,
                            VkMemoryPropertyFlags preferred) const {
  int fallback = -1;
  for (std::uint32_t i = 0; i < memory_.memoryTypeCount; ++i) {
    if (!(typeBits & (1u << i))) continue;
    const VkMemoryPropertyFlags flags = memory_.memoryTypes[i].propertyFlags;
    if ((flags & required) != required) continue;
    if ((flags & preferred) == preferred) return int(i);
    if (fallback < 0) fallback = int(i);
  }
  return fallback;
}

Status Context::submitAndWait(const std::function<void(VkCommandBuffer)>& record) const {
  VkCommandBufferAllocateInfo ai{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
  ai.commandPool = oneShotPool_;
  ai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  ai.commandBufferCount = 1;
  VkCommandBuffer cmd = VK_NULL_HANDLE;
  PC_VK_TRY(vkAllocateCommandBuffers(device_, &ai, &cmd));
  struct Free {
    VkDevice d;
    VkCommandPool p;
    VkCommandBuffer c;
    ~Free() { vkFreeCommandBuffers(d, p, 1, &c); }
  } release{device_, oneShotPool_, cmd};
  VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  PC_VK_TRY(vkBeginCommandBuffer(cmd, &bi));
  record(cmd);
  PC_VK_TRY(vkEndCommandBuffer(cmd));
  VkFenceCreateInfo fci{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
  VkFence fenceHandle = VK_NULL_HANDLE;
  PC_VK_TRY(vkCreateFence(device_, &fci, nullptr, &fenceHandle));
  UniqueFence fence(device_, fenceHandle);
  PC_VK_TRY(submitOne(queue_, cmd, fence.get()));
  PC_VK_TRY(vkWaitForFences(device_, 1, &fenceHandle, VK_TRUE, UINT64_MAX));
  return Status::success();
}

VkResult Context::waitIdle() const { return vkDeviceWaitIdle(device_); }

}  // namespace pc::vk
