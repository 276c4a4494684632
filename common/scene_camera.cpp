#include <algorithm>
#include <cmath>
#include <string>

#include "scene.h"

namespace pc {

Result<Camera> sceneCamera(const Scene& scene, int index) {
  if (index >= 0 && std::size_t(index) < scene.cameras.size()) return scene.cameras[index];
  if (!scene.cameras.empty() || index != 0) {
    return Error{"camera " + std::to_string(index) + " not found; the scene has " +
                 std::to_string(scene.cameras.size())};
  }
  // No camera in the scene: look at the bounds' centre from in front (+z), far enough back
  // for the bounds to fill the default field of view.
  Camera camera;
  camera.name = "default";
  const glm::vec3 centre = 0.5f * (scene.boundsMin + scene.boundsMax);
  const float radius = 0.5f * glm::length(scene.boundsMax - scene.boundsMin);
  const float distance = std::max(radius, 1e-3f) / std::tan(0.5f * camera.yfov);
  camera.position = centre + glm::vec3(0.0f, 0.0f, distance);
  camera.forward = glm::vec3(0.0f, 0.0f, -1.0f);
  return camera;
}

}  // namespace pc
