// What every CPU render of a scene needs before its first ray: the camera (explicit or the
// scene's), the Embree scene moved to the frame's animation time, and the emissive lights of
// that state. Shared by the reference path tracer and the probe-lit render.
#pragma once

#include <memory>
#include <optional>

#include "../common/result.h"
#include "../common/scene.h"
#include "embree_scene.h"
#include "lighting.h"

namespace pc {

struct CpuRenderSetup {
  std::unique_ptr<EmbreeScene> embree;
  SceneState state;
  EmissiveLights emissive;
  Camera camera;
};

// `explicitCamera` when set, else the scene's camera `cameraIndex` (see sceneCamera).
Result<CpuRenderSetup> prepareCpuRender(const Scene& scene, int width, int height,
                                        const std::optional<Camera>& explicitCamera,
                                        int cameraIndex, double time);

}  // namespace pc
