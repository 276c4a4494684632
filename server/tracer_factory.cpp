#include "../common/log.h"
#include "tracer.h"
#include "vulkan_tracer.h"

namespace pc {

namespace {

// The Vulkan tracer with `tracing`; a CPU implementation (lavapipe) only where the backend was
// asked for by name: it is far slower than Embree.
Result<std::unique_ptr<VulkanTracer>> makeVulkan(const Scene& scene, const TracerOptions& options,
                                                 const VulkanTracerOptions* given,
                                                 VulkanTracing tracing, bool byName) {
  VulkanTracerOptions vulkan = given ? *given : VulkanTracerOptions{};
  vulkan.allowCpuDevice = byName;
  vulkan.tracing = tracing;
  return VulkanTracer::create(scene, options, vulkan);
}

}  // namespace

Result<std::unique_ptr<Tracer>> makeTracer(const Scene& scene, const std::string& backend,
                                           const TracerOptions& options,
                                           const VulkanTracerOptions* given) {
  if (backend == "embree") return makeEmbreeTracer(scene, options);
  if (backend == "vulkan" || backend == "sdf") {
    const VulkanTracing tracing =
        backend == "sdf" ? VulkanTracing::DistanceField : VulkanTracing::RayPipelines;
    auto gpu = makeVulkan(scene, options, given, tracing, true);
    if (!gpu) return gpu.error();
    return std::unique_ptr<Tracer>(std::move(gpu).value());
  }
  if (backend == "auto" || backend.empty()) {
    // Ray tracing where the GPU has it, else the distance field on any GPU with compute, else
    // the CPU.
    auto rt = makeVulkan(scene, options, given, VulkanTracing::RayPipelines, false);
    if (rt) {
      logInfo("tracer: " + (*rt)->name() + ": the GPU has ray tracing");
      return std::unique_ptr<Tracer>(std::move(rt).value());
    }
    auto field = makeVulkan(scene, options, given, VulkanTracing::DistanceField, false);
    if (field) {
      logInfo("tracer: " + (*field)->name() + ": no GPU ray tracing (" + rt.error().message +
              "); sphere tracing a distance field in compute");
      return std::unique_ptr<Tracer>(std::move(field).value());
    }
    logInfo("tracer: no GPU ray tracing (" + rt.error().message + ") nor GPU compute (" +
            field.error().message + "); using Embree");
    return makeEmbreeTracer(scene, options);
  }
  return Error{"unknown tracer backend '" + backend + "' (embree, vulkan, sdf or auto)"};
}

}  // namespace pc
