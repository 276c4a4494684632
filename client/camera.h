// Camera math of the client: view and projection matrices that put pixel (x, y) exactly where
// the CPU renders' PinholeCamera (cpu/camera.h) sends its ray, a stereo eye offset, and the
// fly camera the windowed client steers.
#pragma once

#include <glm/glm.hpp>

#include "common/scene.h"

namespace pc::client {

struct ViewMatrices {
  glm::mat4 view{1.0f};
  glm::mat4 proj{1.0f};
  glm::mat4 viewProj{1.0f};
  // Clip -> the world-space offset from the camera: the inverse of proj x view without the
  // view's translation. A pixel's ray comes straight out of it. Subtracting the eye from a
  // point the full inverse gives would cancel: that point lies a near distance from the eye,
  // and far from the origin (1e4) a float's step (1e-3) is a large share of it.
  glm::mat4 invViewProjFromEye{1.0f};
  glm::vec3 position{0.0f};
};

// Right-handed view looking down -z; Vulkan clip space (y down) with reversed, infinite depth:
// depth 1 at `nearPlane`, tending to 0 far away (even precision over large scenes).
ViewMatrices viewMatrices(const Camera& camera, int width, int height, float nearPlane);

// The camera moved sideways by `offset` along its right vector (stereo eyes: -ipd/2, +ipd/2).
Camera offsetCamera(const Camera& camera, float offset);

// A camera pointing from `position` at `target`, with world up made orthogonal.
Camera lookAtCamera(glm::vec3 position, glm::vec3 target, float yfovRadians);

// Mouse-and-keyboard camera: yaw about world up, pitch clamped short of the poles.
class FlyCamera {
 public:
  explicit FlyCamera(const Camera& start);
  // Mouse motion in pixels; `radiansPerPixel` scales it.
  void rotate(float dx, float dy, float radiansPerPixel = 0.003f);
  // Movement along the camera's forward, right and world up, in world units.
  void move(float forward, float right, float up);
  Camera camera() const;

 private:
  glm::vec3 position_;
  float yaw_ = 0.0f, pitch_ = 0.0f, yfov_ = 0.785f;
};

}  // namespace pc::client
