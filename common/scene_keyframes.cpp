// glTF keyframe animation: sampling a node's translation, rotation and scale at a time, and
// the transform of a chain of such nodes (glTF 2.0 spec, 3.11 Animations, and its appendix C
// on interpolation).
#include <algorithm>
#include <cmath>
#include <glm/gtc/matrix_transform.hpp>

#include "common/scene.h"

namespace pc {

namespace {

// The key interval [i, i + 1] holding local time t, and the fraction of it at t; a time before
// the first key or after the last holds the end key (fraction 0 at i = first, or i = last).
struct KeySpan {
  std::size_t i = 0;
  float f = 0.0f;
  float dt = 0.0f;
  bool single = true;  // t is outside the keys or there is one key: the value of key i
};

KeySpan findSpan(const std::vector<float>& times, float t) {
  KeySpan s;
  if (times.empty() || t <= times.front()) return s;
  if (t >= times.back()) {
    s.i = times.size() - 1;
    return s;
  }
  const auto upper = std::upper_bound(times.begin(), times.end(), t);
  s.i = std::size_t(upper - times.begin()) - 1;
  s.dt = times[s.i + 1] - times[s.i];
  s.f = s.dt > 0.0f ? (t - times[s.i]) / s.dt : 0.0f;
  s.single = false;
  return s;
}

glm::vec4 cubicSpline(const KeyframeTrack& k, const KeySpan& s) {
  // Each key holds (in-tangent, value, out-tangent); tangents are per second, so scaled by the
  // interval's length.
  const glm::vec4 p0 = k.values[3 * s.i + 1], m0 = k.values[3 * s.i + 2] * s.dt;
  const glm::vec4 p1 = k.values[3 * (s.i + 1) + 1], m1 = k.values[3 * (s.i + 1)] * s.dt;
  const float t = s.f, t2 = t * t, t3 = t2 * t;
  return (2 * t3 - 3 * t2 + 1) * p0 + (t3 - 2 * t2 + t) * m0 + (-2 * t3 + 3 * t2) * p1 +
         (t3 - t2) * m1;
}

glm::quat toQuat(glm::vec4 v) { return glm::quat(v.w, v.x, v.y, v.z); }

// The track's value at time t (seconds since the scene's time 0, looped on its period).
glm::vec4 sample(const KeyframeTrack& k, double time) {
  double local = time;
  if (k.period > 0.0f) {
    local = std::fmod(time, double(k.period));
    if (local < 0.0) local += k.period;
  }
  const KeySpan s = findSpan(k.times, float(local));
  const bool cubic = k.interpolation == KeyframeTrack::Interpolation::CubicSpline;
  const auto value = [&](std::size_t i) { return cubic ? k.values[3 * i + 1] : k.values[i]; };
  if (s.single || k.interpolation == KeyframeTrack::Interpolation::Step) return value(s.i);
  if (k.property == KeyframeTrack::Property::Rotation) {
    if (cubic) {
      const glm::quat q = glm::normalize(toQuat(cubicSpline(k, s)));
      return {q.x, q.y, q.z, q.w};
    }
    const glm::quat q =
        glm::slerp(glm::normalize(toQuat(value(s.i))), glm::normalize(toQuat(value(s.i + 1))), s.f);
    return {q.x, q.y, q.z, q.w};
  }
  return cubic ? cubicSpline(k, s) : glm::mix(value(s.i), value(s.i + 1), s.f);
}

glm::mat4 localTransform(const KeyframedNode& node, const std::vector<KeyframeTrack>& tracks,
                         double time) {
  if (node.hasMatrix) return node.matrix;
  glm::vec3 t = node.translation, sc = node.scale;
  glm::quat r = node.rotation;
  for (int index : node.tracks) {
    const KeyframeTrack& k = tracks[std::size_t(index)];
    const glm::vec4 v = sample(k, time);
    switch (k.property) {
      case KeyframeTrack::Property::Translation:
        t = glm::vec3(v);
        break;
      case KeyframeTrack::Property::Rotation:
        r = glm::normalize(toQuat(v));
        break;
      case KeyframeTrack::Property::Scale:
        sc = glm::vec3(v);
        break;
    }
  }
  return glm::translate(glm::mat4(1.0f), t) * glm::mat4_cast(r) * glm::scale(glm::mat4(1.0f), sc);
}

}  // namespace

glm::mat4 keyframedTransform(const Animation& a, double time) {
  glm::mat4 m = a.base;
  static const std::vector<KeyframeTrack> kNone;
  const std::vector<KeyframeTrack>& tracks = a.tracks ? *a.tracks : kNone;
  for (const KeyframedNode& node : a.chain) m = m * localTransform(node, tracks, time);
  return m;
}

}  // namespace pc
