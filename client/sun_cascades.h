// The sun's cascaded shadow maps fitted to the camera (shaders/interop/sun_cascades.h says how
// the shader picks them): the view is cut into slices by distance, and each slice gets an
// orthographic map around what of it lies inside the scene. Maps keep their size while the
// camera moves (sizes come in steps) and their texels on a fixed grid (corners snapped to
// whole texels from the light's fixed origin), so a moving camera does not make shadow edges
// crawl, and a still one redraws nothing (the shadow cache compares the matrices).
#pragma once

#include <array>
#include <glm/glm.hpp>
#include <vector>

#include "common/scene.h"
#include "shaders/interop/sun_cascades.h"

namespace pc::client {

// The views the cascades are fitted to.
struct ShadowFocus {
  std::vector<Camera> cameras;  // one per view (stereo: both eyes); none: the whole scene
  float aspect = 1.0f;          // width / height of the views
  float nearPlane = 0.0f;       // where the views begin (world units)
};

using SunCascadeMatrices = std::array<glm::mat4, gpu::PC_SUN_CASCADES>;

// Slice boundaries along the view direction, from `nearDistance` to `farDistance`
// (PC_SUN_CASCADES + 1 values, increasing).
std::array<float, gpu::PC_SUN_CASCADES + 1> sunCascadeSplits(float nearDistance, float farDistance);

// Each cascade's view-projection (Vulkan depth 0..1) of offsets from `origin`, the shadow
// origin: `lightView` (a rotation looking along the sun's direction) then an orthographic
// projection over the part of the scene box `lo..hi` (world) that the cascade's slice covers,
// with `mapSize` texels per side. Depth always spans the whole scene, so casters outside a
// slice still cast into it. Without cameras, or where a slice misses the scene, the cascade
// covers the whole scene as the light sees it.
SunCascadeMatrices fitSunCascades(const glm::mat4& lightView, glm::vec3 origin, glm::vec3 lo,
                                  glm::vec3 hi, const ShadowFocus& focus, int mapSize);

}  // namespace pc::client
