#include "client_setup.h"

#include <chrono>

#include "camera.h"
#include "common/log.h"
#include "protocol/baked_file.h"

namespace pc::client {

double secondsNow() {
  using namespace std::chrono;
  return duration<double>(steady_clock::now().time_since_epoch()).count();
}

Result<Scene> loadClientScene(const ClientConfig& config) {
  if (config.scene.empty() || config.scene == "builtin") return builtinScene();
  Result<Scene> scene = loadScene(config.scene, config.sidecar, config.sceneLoad);
  if (scene) logInfo(sidecarReport(*scene));
  return scene;
}

Result<Camera> clientCamera(const Scene& scene, const ClientConfig& config) {
  auto chosen = sceneCamera(scene, config.camera);
  if (!chosen) return chosen.error();
  Camera c = chosen.value();
  if (config.fovDegrees) c.yfov = glm::radians(*config.fovDegrees);
  if (config.position) c.position = *config.position;
  if (config.target) {
    if (glm::length(*config.target - c.position) <= 0.0f)
      return Error{"--target must differ from the camera position"};
    c = lookAtCamera(c.position, *config.target, c.yfov);
  } else if (config.direction) {
    if (glm::length(*config.direction) <= 0.0f) return Error{"--dir must not be zero"};
    c = lookAtCamera(c.position, c.position + glm::normalize(*config.direction), c.yfov);
  }
  return c;
}

Status loadFallbackField(const Scene& scene, const ClientConfig& config, FieldMirror& mirror) {
  if (config.probes.empty()) {
    logWarn("no baked field given (--probes): indirect light is a plain ambient term");
    return Status::success();
  }
  auto field = readBakedField(config.probes, scene.hash);
  if (!field) {
    Error e{"cannot use the baked field: " + field.error().message};
    logError(e.message);
    return e;
  }
  mirror.reset(std::move(field).value(), secondsNow());
  return Status::success();
}

Result<std::unique_ptr<vk::Context>> createClientContext(
    const ClientConfig& config, const std::vector<std::string>& instanceExtensions) {
  vk::ContextOptions o;
  o.validation = config.validation;
  o.presentation = config.windowed;
  o.instanceExtensions = instanceExtensions;
  o.allowCpuDevice = true;  // lavapipe renders correctly, only slower: better than nothing
  o.multiview = true;
  auto ctx = vk::Context::create(o);
  if (!ctx) {
    return Error{"no usable Vulkan device: " + ctx.error().message +
                 " (install mesa-vulkan-drivers from bookworm-backports for lavapipe, or your "
                 "GPU's Vulkan driver)"};
  }
  return ctx;
}

}  // namespace pc::client
