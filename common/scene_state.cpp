// Animation: the lights and instance transforms of a scene at a given time.
#include <cmath>
#include <glm/gtc/matrix_transform.hpp>
#include <numbers>

#include "common/scene.h"

namespace pc {

namespace {

// Position on a closed polyline, each segment taking period / n seconds. Time is reduced in
// double so long-running servers keep sub-millisecond precision.
glm::vec3 pathPosition(const Animation& a, double time) {
  const std::size_t n = a.points.size();
  if (n == 0) return glm::vec3(0.0f);
  if (n == 1 || !(a.period > 0.0f)) return a.points[0];
  double phase = std::fmod(time, double(a.period)) / double(a.period);
  if (phase < 0.0) phase += 1.0;
  double s = phase * double(n);
  std::size_t i = std::size_t(s) % n;
  float f = float(s - std::floor(s));
  return glm::mix(a.points[i], a.points[(i + 1) % n], f);
}

// Rotation about the animation's axis through its pivot, at time t.
glm::mat4 rotation(const Animation& a, double time) {
  double turns = std::fmod(double(a.radiansPerSecond) * time, 2.0 * std::numbers::pi);
  glm::vec3 axis = glm::length(a.axis) > 0.0f ? glm::normalize(a.axis) : glm::vec3(0, 1, 0);
  glm::mat4 m = glm::translate(glm::mat4(1.0f), a.pivot);
  m = glm::rotate(m, float(turns), axis);
  return glm::translate(m, -a.pivot);
}

const Animation* animationOf(const Scene& scene, int index) {
  if (index < 0 || std::size_t(index) >= scene.animations.size()) return nullptr;
  return &scene.animations[index];
}

}  // namespace

SceneState evaluateScene(const Scene& scene, double time) {
  SceneState state;
  state.time = time;
  state.lights = scene.lights;
  for (Light& l : state.lights) {
    const Animation* a = animationOf(scene, l.animation);
    if (!a) continue;
    if (a->kind == Animation::Kind::Path) {
      l.position = pathPosition(*a, time);
    } else if (a->kind == Animation::Kind::Keyframes) {
      const glm::mat4 m = keyframedTransform(*a, time);
      l.position = glm::vec3(m[3]);
      l.direction = glm::normalize(glm::vec3(m * glm::vec4(0.0f, 0.0f, -1.0f, 0.0f)));
    } else {
      glm::mat4 r = rotation(*a, time);
      l.position = glm::vec3(r * glm::vec4(l.position, 1.0f));
      l.direction = glm::normalize(glm::vec3(r * glm::vec4(l.direction, 0.0f)));
    }
  }
  state.instanceTransforms.reserve(scene.instances.size());
  for (const Instance& inst : scene.instances) {
    glm::mat4 m = inst.transform;
    if (const Animation* a = animationOf(scene, inst.animation)) {
      if (a->kind == Animation::Kind::Path) {
        glm::vec3 offset =
            pathPosition(*a, time) - (a->points.empty() ? glm::vec3(0.0f) : a->points[0]);
        m = glm::translate(glm::mat4(1.0f), offset) * m;
      } else if (a->kind == Animation::Kind::Keyframes) {
        m = keyframedTransform(*a, time);
      } else {
        m = rotation(*a, time) * m;
      }
    }
    state.instanceTransforms.push_back(m);
  }
  return state;
}

}  // namespace pc
