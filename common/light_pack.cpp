#include "light_pack.h"

#include <algorithm>
#include <cmath>

namespace pc {

gpu::GpuLight packLight(const Light& light) {
  gpu::GpuLight g{};
  g.position = light.position;
  g.type = light.type == LightType::Directional ? gpu::PC_LIGHT_DIRECTIONAL
           : light.type == LightType::Spot      ? gpu::PC_LIGHT_SPOT
                                                : gpu::PC_LIGHT_POINT;
  const float length = glm::length(light.direction);
  // A zero direction (a point light never reads it) stays zero rather than becoming NaN.
  g.direction = length > 0.0f ? light.direction / length : glm::vec3(0.0f);
  g.range = light.range;
  g.power = light.color * light.intensity;
  g.cosOuter = std::cos(light.outerConeAngle);
  g.cosInner = std::cos(std::min(light.innerConeAngle, light.outerConeAngle));
  g.shadowLayer = -1;
  return g;
}

std::vector<gpu::GpuLight> packLights(const SceneState& state) {
  std::vector<gpu::GpuLight> lights;
  lights.reserve(state.lights.size());
  for (const Light& l : state.lights) lights.push_back(packLight(l));
  return lights;
}

}  // namespace pc
