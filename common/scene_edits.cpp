// Runtime edits: checks, the edits in force, and the regions they change.
#include "common/scene_edits.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

namespace pc {

namespace {

std::string show(float v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

std::string show(glm::vec3 v) {
  return "(" + show(v.x) + ", " + show(v.y) + ", " + show(v.z) + ")";
}

// An Error when `v` is not finite or outside [lo, hi], naming the field.
Status within(const char* field, float v, float lo, float hi) {
  if (!std::isfinite(v)) return Error{std::string(field) + " is not finite: " + show(v)};
  if (v < lo || v > hi)
    return Error{std::string(field) + " " + show(v) + " is outside [" + show(lo) + ", " + show(hi) +
                 "]"};
  return Status::success();
}

Status within(const char* field, glm::vec3 v, float lo, float hi) {
  for (int i = 0; i < 3; ++i) {
    if (!std::isfinite(v[i]) || v[i] < lo || v[i] > hi)
      return Error{std::string(field) + " " + show(v) + " is not finite or outside [" + show(lo) +
                   ", " + show(hi) + "]"};
  }
  return Status::success();
}

Status checkTransform(const glm::mat4& m, const glm::mat4& original) {
  for (int c = 0; c < 4; ++c) {
    for (int r = 0; r < 4; ++r) {
      const float v = m[c][r];
      if (!std::isfinite(v) || std::abs(v) > kMaxEditCoordinate)
        return Error{"transform element [" + std::to_string(c) + "][" + std::to_string(r) + "] " +
                     show(v) + " is not finite or beyond " + show(kMaxEditCoordinate)};
    }
  }
  if (m[0][3] != 0.0f || m[1][3] != 0.0f || m[2][3] != 0.0f || m[3][3] != 1.0f)
    return Error{"transform is not affine: its last row must be (0, 0, 0, 1)"};
  const float det = glm::determinant(glm::mat3(m));
  if (!(std::abs(det) >= 1e-6f) || std::abs(det) > 1e6f)
    return Error{"transform's determinant " + show(det) + " is outside 1e-6..1e6 in magnitude"};
  // The tracers fix each instance's winding from its first transform.
  if ((det < 0.0f) != (glm::determinant(glm::mat3(original)) < 0.0f))
    return Error{"transform mirrors the instance (its determinant changes sign)"};
  return Status::success();
}

}  // namespace

const char* editOpName(EditOp op) {
  switch (op) {
    case EditOp::SetLight:
      return "set_light";
    case EditOp::AddLight:
      return "add_light";
    case EditOp::RemoveLight:
      return "remove_light";
    case EditOp::MoveInstance:
      return "move_instance";
    case EditOp::SetEmission:
      return "set_emission";
  }
  return "unknown";
}

EditRegion lightRegion(const Light& light) {
  if (light.type == LightType::Directional)
    return {light.position, std::numeric_limits<float>::infinity()};
  float reach = light.range;
  if (!(reach > 0.0f)) {
    const float peak = light.intensity * std::max({light.color.r, light.color.g, light.color.b});
    reach = std::sqrt(std::max(0.0f, peak) / kLightReachIrradiance);
  }
  return {light.position, std::min(reach, kMaxEditCoordinate)};
}

EditRegion instanceRegion(const Scene& scene, std::size_t index, const glm::mat4& transform) {
  const Instance& inst = scene.instances[index];
  if (inst.mesh < 0 || std::size_t(inst.mesh) >= scene.meshes.size()) return {};
  const Mesh& mesh = scene.meshes[std::size_t(inst.mesh)];
  if (mesh.positions.empty()) return {};
  glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
  for (const glm::vec3& p : mesh.positions) {
    const glm::vec3 w = glm::vec3(transform * glm::vec4(p, 1.0f));
    lo = glm::min(lo, w);
    hi = glm::max(hi, w);
  }
  return {0.5f * (lo + hi), glm::length(hi - lo)};  // twice the half-diagonal
}

SceneEdits::SceneEdits(const Scene& scene)
    : scene_(scene), lights_(scene.lights.size()), instances_(scene.instances.size()) {}

Status SceneEdits::checkLightFields(const SceneEdit& edit) const {
  if (edit.fields == 0 || (edit.fields & ~kEditLightFields) != 0)
    return Error{"light fields " + std::to_string(edit.fields) +
                 ": name at least one of position, direction, colour, intensity, range"};
  if (edit.fields & kEditPosition) {
    if (Status s = within("position", edit.position, -kMaxEditCoordinate, kMaxEditCoordinate); !s)
      return s;
  }
  if (edit.fields & kEditDirection) {
    if (Status s = within("direction", edit.direction, -kMaxEditCoordinate, kMaxEditCoordinate); !s)
      return s;
    if (!(glm::length(edit.direction) > 1e-6f)) return Error{"direction has no length"};
  }
  if (edit.fields & kEditColor) {
    if (Status s = within("colour", edit.color, 0.0f, kMaxEditColor); !s) return s;
  }
  if (edit.fields & kEditIntensity) {
    if (Status s = within("intensity", edit.intensity, 0.0f, kMaxEditIntensity); !s) return s;
  }
  if (edit.fields & kEditRange) {
    if (Status s = within("range", edit.range, 0.0f, kMaxEditRange); !s) return s;
  }
  return Status::success();
}

Status SceneEdits::check(const SceneEdit& edit) const {
  switch (edit.op) {
    case EditOp::SetLight:
    case EditOp::RemoveLight:
      if (edit.target >= lights_.size())
        return Error{"light " + std::to_string(edit.target) + " does not exist (the scene has " +
                     std::to_string(lights_.size()) + ")"};
      if (lights_[edit.target].removed)
        return Error{"light " + std::to_string(edit.target) + " was removed"};
      return edit.op == EditOp::SetLight ? checkLightFields(edit) : Status::success();
    case EditOp::AddLight:
      if (added_.size() >= kMaxAddedLights)
        return Error{"already " + std::to_string(kMaxAddedLights) + " added lights, the most"};
      if (!(edit.fields & kEditPosition)) return Error{"an added light needs a position"};
      return checkLightFields(edit);
    case EditOp::MoveInstance: {
      if (edit.target >= scene_.instances.size())
        return Error{"instance " + std::to_string(edit.target) + " does not exist (the scene has " +
                     std::to_string(scene_.instances.size()) + ")"};
      const Instance& inst = scene_.instances[edit.target];
      // The tracers build static instances into their acceleration structures once.
      if (inst.animation < 0)
        return Error{"instance " + std::to_string(edit.target) +
                     " is static; only animated instances move"};
      return checkTransform(edit.transform, inst.transform);
    }
    case EditOp::SetEmission:
      if (edit.target >= scene_.materials.size())
        return Error{"material " + std::to_string(edit.target) + " does not exist (the scene has " +
                     std::to_string(scene_.materials.size()) + ")"};
      if (!scene_.materials[edit.target].isEmissive())
        return Error{"material " + std::to_string(edit.target) + " emits nothing"};
      return within("emission", edit.emission, 0.0f, kMaxEditEmission);
  }
  return Error{"unknown edit operation " + std::to_string(int(edit.op))};
}

std::vector<EditRegion> SceneEdits::regionsOf(const SceneEdit& edit, std::uint32_t target,
                                              const SceneState& state) const {
  switch (edit.op) {
    case EditOp::SetLight:
    case EditOp::AddLight:
    case EditOp::RemoveLight:
      return {lightRegion(state.lights[target])};
    case EditOp::MoveInstance:
      return {instanceRegion(scene_, target, state.instanceTransforms[target])};
    case EditOp::SetEmission: {
      std::vector<EditRegion> out;
      for (std::size_t i = 0; i < scene_.instances.size(); ++i) {
        const Material* m = scene_.materialOf(scene_.instances[i]);
        if (m != &scene_.materials[target]) continue;
        EditRegion r = instanceRegion(scene_, i, state.instanceTransforms[i]);
        r.radius *= 2.0f;  // an emitter lights its surroundings
        out.push_back(r);
      }
      return out;
    }
  }
  return {};
}

Result<EditOutcome> SceneEdits::apply(const SceneEdit& edit, double time) {
  if (Status s = check(edit); !s) return s.error();
  const SceneState before = evaluate(time);
  EditOutcome outcome;
  outcome.target = edit.target;
  if (edit.op != EditOp::AddLight) outcome.regions = regionsOf(edit, edit.target, before);
  switch (edit.op) {
    case EditOp::AddLight: {
      Light light;
      light.name = "edit " + std::to_string(added_.size());
      light.type = LightType::Point;
      added_.push_back(light);
      outcome.target = std::uint32_t(lights_.size());
      lights_.push_back(LightEdit{});
      [[fallthrough]];
    }
    case EditOp::SetLight: {
      LightEdit& l = lights_[outcome.target];
      l.fields |= edit.fields;
      if (edit.fields & kEditPosition) l.position = edit.position;
      if (edit.fields & kEditDirection) l.direction = glm::normalize(edit.direction);
      if (edit.fields & kEditColor) l.color = edit.color;
      if (edit.fields & kEditIntensity) l.intensity = edit.intensity;
      if (edit.fields & kEditRange) l.range = edit.range;
      break;
    }
    case EditOp::RemoveLight:
      lights_[edit.target].removed = true;
      break;
    case EditOp::MoveInstance:
      instances_[edit.target] = edit.transform;
      break;
    case EditOp::SetEmission:
      if (emission_.empty()) emission_.assign(scene_.materials.size(), 1.0f);
      emission_[edit.target] = edit.emission;
      break;
  }
  ++version_;
  outcome.version = version_;
  const std::vector<EditRegion> after = regionsOf(edit, outcome.target, evaluate(time));
  outcome.regions.insert(outcome.regions.end(), after.begin(), after.end());
  return outcome;
}

SceneState SceneEdits::evaluate(double time) const {
  SceneState state = evaluateScene(scene_, time);
  if (version_ == 0) return state;
  state.editVersion = version_;
  state.lights.insert(state.lights.end(), added_.begin(), added_.end());
  state.addedLights = std::uint32_t(added_.size());
  for (std::size_t i = 0; i < lights_.size() && i < state.lights.size(); ++i) {
    const LightEdit& e = lights_[i];
    Light& l = state.lights[i];
    if (e.fields & kEditPosition) l.position = e.position;
    if (e.fields & kEditDirection) l.direction = e.direction;
    if (e.fields & kEditColor) l.color = e.color;
    if (e.fields & kEditIntensity) l.intensity = e.intensity;
    if (e.fields & kEditRange) l.range = e.range;
    if (e.removed) l.intensity = 0.0f;  // kept in place: every later light keeps its index
  }
  for (std::size_t i = 0; i < instances_.size() && i < state.instanceTransforms.size(); ++i) {
    if (instances_[i]) state.instanceTransforms[i] = *instances_[i];
  }
  state.emissionScale = emission_;
  return state;
}

}  // namespace pc
