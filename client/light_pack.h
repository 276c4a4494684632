// Direct lights as the rasterizer sees them: the scene's punctual lights, plus virtual point
// lights standing in for the emissive surfaces that the CPU renders sample as area lights
// (EmissiveLights), each with the shadow views it needs.
//
// Emitters: every emissive triangle chosen for light sampling is split into k x k similar
// sub-triangles (k from its share of the emitted power), and each sub-triangle becomes one
// cosine-emitting point light at its centroid carrying its power, with a cube shadow map.
// Many small emitter triangles are instead sampled: `areaLights` triangles picked in
// proportion to power, each carrying an equal share. The soft shadow of the area is then the
// average of these hard (filtered) shadows.
#pragma once

#include <glm/glm.hpp>
#include <vector>

#include "common/emissive_lights.h"
#include "common/light_pack.h"
#include "common/scene.h"
#include "shaders/interop/client_frame.h"
#include "sun_cascades.h"

namespace pc::client {

struct ShadowSettings {
  int largeSize = 2048;  // spot light maps and each of the sun's cascades (texels per side)
  int smallSize = 512;   // the emitters' virtual point lights
  // Point lights' cube faces: a face spans 90 degrees, so 1024 texels give about the angular
  // resolution of a 1080p view with a 60-degree field of view, and a moving point light
  // redraws six faces a frame (a quarter of the texels of 2048^2 faces).
  int pointSize = 1024;
  int areaLights = 16;  // about this many virtual point lights for all emitters together
  // The sun's maps fitted to the views (sun_cascades.h); false: each covers the whole scene,
  // as one map did before cascades (to compare the two).
  bool sunCascades = true;
};

// Shadow map arrays: sun and spots, the emitters' virtual point lights, point-light cube faces.
inline constexpr int kLargeShadowArray = 0, kSmallShadowArray = 1, kPointShadowArray = 2;
inline constexpr int kShadowArrays = 3;

// One shadow map layer to render: the array (k*ShadowArray), its layer, the light's
// view-projection (Vulkan depth 0..1) in world space (for culling and the cache), and the same
// from the shadow origin (GpuLight::position): what the GPU uses, on positions minus the origin.
// Far from the world's origin (1e4) the translation of a world-space matrix cancels against
// the positions in float; offsets from the light do not.
struct ShadowView {
  int array = 0;
  int layer = 0;
  glm::mat4 viewProj{1.0f};
  glm::mat4 fromOrigin{1.0f};
  glm::vec3 origin{0.0f};
};

struct LightSet {
  std::vector<gpu::GpuLight> lights;
  // Indexed by GpuLight::shadowMatrix (+ cube face): view-projections from the light's shadow
  // origin, its GpuLight::position (ShadowView::fromOrigin).
  std::vector<glm::mat4> matrices;
  std::vector<ShadowView> views;          // the layers to render
  int layers[kShadowArrays] = {0, 0, 0};  // per shadow array
  int areaLightCount = 0;
};

// `focus`: the views the sun's cascades are fitted to (none: each covers the whole scene; the
// number of layers and matrices does not depend on it).
LightSet buildLights(const Scene& scene, const SceneState& state, const EmissiveLights& emitters,
                     const ShadowSettings& settings, const ShadowFocus& focus = {});

}  // namespace pc::client
