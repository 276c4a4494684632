#include "camera.h"

#include <algorithm>
#include <cmath>

namespace pc::client {

ViewMatrices viewMatrices(const Camera& camera, int width, int height, float nearPlane) {
  // Same basis as PinholeCamera, so the two renders agree to the pixel.
  const glm::vec3 f = glm::normalize(camera.forward);
  const glm::vec3 r = glm::normalize(glm::cross(f, camera.up));
  const glm::vec3 u = glm::cross(r, f);
  ViewMatrices m;
  m.position = camera.position;
  // Rows are the camera axes (x = right, y = up, z = -forward); GLM is column-major.
  m.view = glm::mat4(1.0f);
  for (int c = 0; c < 3; ++c) {
    m.view[c][0] = r[c];
    m.view[c][1] = u[c];
    m.view[c][2] = -f[c];
  }
  m.view[3][0] = -glm::dot(r, camera.position);
  m.view[3][1] = -glm::dot(u, camera.position);
  m.view[3][2] = glm::dot(f, camera.position);

  const float tanHalf = std::tan(0.5f * camera.yfov);
  const float aspect = float(width) / float(height);
  m.proj = glm::mat4(0.0f);
  m.proj[0][0] = 1.0f / (tanHalf * aspect);
  m.proj[1][1] = -1.0f / tanHalf;  // Vulkan's y points down the screen
  m.proj[2][3] = -1.0f;            // w = -z_view
  m.proj[3][2] = nearPlane;        // z = near, so depth = near / -z_view
  m.viewProj = m.proj * m.view;
  glm::mat4 rotation = m.view;
  rotation[3] = glm::vec4(0.0f, 0.0f, 0.0f, 1.0f);
  m.invViewProjFromEye = glm::inverse(m.proj * rotation);
  return m;
}

Camera offsetCamera(const Camera& camera, float offset) {
  Camera c = camera;
  const glm::vec3 f = glm::normalize(camera.forward);
  const glm::vec3 r = glm::normalize(glm::cross(f, camera.up));
  c.position += r * offset;
  return c;
}

Camera lookAtCamera(glm::vec3 position, glm::vec3 target, float yfovRadians) {
  Camera c;
  c.position = position;
  c.forward = glm::normalize(target - position);
  glm::vec3 up(0.0f, 1.0f, 0.0f);
  // Looking straight up or down: any horizontal up will do.
  if (std::abs(glm::dot(c.forward, up)) > 0.999f) up = glm::vec3(0.0f, 0.0f, -1.0f);
  const glm::vec3 r = glm::normalize(glm::cross(c.forward, up));
  c.up = glm::cross(r, c.forward);
  c.yfov = yfovRadians;
  return c;
}

FlyCamera::FlyCamera(const Camera& start) : position_(start.position), yfov_(start.yfov) {
  const glm::vec3 f = glm::normalize(start.forward);
  yaw_ = std::atan2(f.x, -f.z);
  pitch_ = std::asin(std::clamp(f.y, -1.0f, 1.0f));
}

void FlyCamera::rotate(float dx, float dy, float radiansPerPixel) {
  yaw_ += dx * radiansPerPixel;
  pitch_ = std::clamp(pitch_ - dy * radiansPerPixel, -1.55f, 1.55f);
}

void FlyCamera::move(float forward, float right, float up) {
  const Camera c = camera();
  const glm::vec3 r = glm::normalize(glm::cross(c.forward, glm::vec3(0.0f, 1.0f, 0.0f)));
  position_ += c.forward * forward + r * right + glm::vec3(0.0f, up, 0.0f);
}

Camera FlyCamera::camera() const {
  Camera c;
  c.position = position_;
  c.forward = glm::vec3(std::sin(yaw_) * std::cos(pitch_), std::sin(pitch_),
                        -std::cos(yaw_) * std::cos(pitch_));
  const glm::vec3 r = glm::normalize(glm::cross(c.forward, glm::vec3(0.0f, 1.0f, 0.0f)));
  c.up = glm::cross(r, c.forward);
  c.yfov = yfov_;
  return c;
}

}  // namespace pc::client
