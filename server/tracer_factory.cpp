#include "../common/log.h"
#include "tracer.h"
#include "vulkan_tracer.h"

namespace pc {

Result<std::unique_ptr<Tracer>> makeTracer(const Scene& scene, const std::string& backend,
                                           const TracerOptions& options,
                                           const VulkanTracerOptions* given) {
  if (backend == "embree") return makeEmbreeTracer(scene, options);
  if (backend == "vulkan" || backend == "auto" || backend.empty()) {
    VulkanTracerOptions vulkan = given ? *given : VulkanTracerOptions{};
    // A CPU implementation only when asked for by name: it is far slower than Embree.
    vulkan.allowCpuDevice = backend == "vulkan";
    auto gpu = VulkanTracer::create(scene, options, vulkan);
    if (gpu) return std::unique_ptr<Tracer>(std::move(gpu).value());
    if (backend == "vulkan") return gpu.error();
    logInfo("tracer: no GPU ray tracing (" + gpu.error().message + "); using Embree");
    return makeEmbreeTracer(scene, options);
  }
  return Error{"unknown tracer backend '" + backend + "' (embree, vulkan or auto)"};
}

}  // namespace pc
