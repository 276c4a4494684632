// What both front ends set up before rendering: the scene, the camera, the baked fallback
// field in a FieldMirror (or none, with a clear message), and the Vulkan context.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "client_app.h"
#include "common/result.h"
#include "common/scene.h"
#include "common/vulkan/context.h"
#include "field_mirror.h"

namespace pc::client {

Result<Scene> loadClientScene(const ClientConfig& config);
Result<Camera> clientCamera(const Scene& scene, const ClientConfig& config);
// Loads config.probes into `mirror`. None given: a warning that indirect light is a plain
// ambient term. A file that cannot be used (missing, corrupt, another scene's) is logged and
// returned as an error, which the front ends exit 1 with: the user asked for that field, and
// an image without it would pass for one lit by it.
Status loadFallbackField(const Scene& scene, const ClientConfig& config, FieldMirror& mirror);
// The context, or an error saying what to install when no Vulkan device is usable.
Result<std::unique_ptr<vk::Context>> createClientContext(
    const ClientConfig& config, const std::vector<std::string>& instanceExtensions);

double secondsNow();

}  // namespace pc::client
