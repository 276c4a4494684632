// Runtime edits of a scene: a light moved, recoloured, dimmed, added or removed, an instance
// moved, an emitter's emission switched. They come from the network (an editor's Edit message,
// PROTOCOL.md "Runtime edits"), so every field is checked against the scene and bounded before
// anything changes; an edit that fails changes nothing. The edits in force lie on top of the
// animation: evaluate(time) is evaluateScene(scene, time) with them applied.
#pragma once

#include <cstdint>
#include <glm/glm.hpp>
#include <optional>
#include <string>
#include <vector>

#include "common/result.h"
#include "common/scene.h"

namespace pc {

enum class EditOp : std::uint8_t {
  SetLight = 1,      // change the given fields of light `target`
  AddLight = 2,      // a point light at `position` (and the other given fields)
  RemoveLight = 3,   // light `target` gives no light from here on
  MoveInstance = 4,  // instance `target` takes `transform` (object to world)
  SetEmission = 5,   // material `target` emits `emission` times its own emission
};
inline constexpr std::uint8_t kLastEditOp = std::uint8_t(EditOp::SetEmission);
const char* editOpName(EditOp op);  // "set_light", ...

// Which fields of a SetLight or AddLight are given (SceneEdit::fields).
inline constexpr std::uint32_t kEditPosition = 1, kEditDirection = 2, kEditColor = 4,
                               kEditIntensity = 8, kEditRange = 16;
inline constexpr std::uint32_t kEditLightFields = 31;

struct SceneEdit {
  EditOp op = EditOp::SetLight;
  std::uint32_t target = 0;  // a light (the scene's, then added ones), an instance, a material
  std::uint32_t fields = 0;  // kEdit* bits, for SetLight and AddLight
  glm::vec3 position{0.0f}, direction{0.0f, -1.0f, 0.0f}, color{1.0f};
  float intensity = 1.0f, range = 0.0f;
  glm::mat4 transform{1.0f};  // MoveInstance
  float emission = 1.0f;      // SetEmission
};

// Bounds on what an edit may state. Coordinates are world units: no scene probecast serves is
// 100 km across, and larger values only serve to overflow what the tracers compute from them.
inline constexpr float kMaxEditCoordinate = 1e5f;
inline constexpr float kMaxEditColor = 1e3f;
inline constexpr float kMaxEditIntensity = 1e7f;
inline constexpr float kMaxEditRange = 1e5f;
inline constexpr float kMaxEditEmission = 1e3f;
// Lights edits may add: each one costs every probe ray a light evaluation and a shadow ray.
inline constexpr std::uint32_t kMaxAddedLights = 64;
// Irradiance below which a light without a range no longer counts as reaching a point, for the
// region an edit of it changes (EditRegion).
inline constexpr float kLightReachIrradiance = 0.01f;

// Where an edit changed the light: a sphere (radius infinite: everywhere, a directional light).
struct EditRegion {
  glm::vec3 center{0.0f};
  float radius = 0.0f;
};

struct EditOutcome {
  std::uint64_t version = 0;        // SceneEdits::version() after it
  std::uint32_t target = 0;         // the light an AddLight made; else the edit's target
  std::vector<EditRegion> regions;  // before and after the edit
};

class SceneEdits {
 public:
  explicit SceneEdits(const Scene& scene);

  // Checks `edit` against the scene, the edits so far and the bounds above; applies it, or
  // returns an Error naming the field, its value and the bound, and changes nothing. `time`:
  // the animation time, for the regions of animated lights and instances.
  Result<EditOutcome> apply(const SceneEdit& edit, double time);
  // The scene at `time` with the edits in force (evaluateScene when there are none).
  SceneState evaluate(double time) const;
  // Edits applied so far (0: none; the state is the animation's).
  std::uint64_t version() const { return version_; }

 private:
  struct LightEdit {
    std::uint32_t fields = 0;
    glm::vec3 position{0.0f}, direction{0.0f}, color{0.0f};
    float intensity = 0, range = 0;
    bool removed = false;
  };
  Status check(const SceneEdit& edit) const;
  Status checkLightFields(const SceneEdit& edit) const;
  std::vector<EditRegion> regionsOf(const SceneEdit& edit, std::uint32_t target,
                                    const SceneState& state) const;

  const Scene& scene_;
  std::vector<LightEdit> lights_;  // the scene's lights, then the added ones
  std::vector<Light> added_;
  std::vector<std::optional<glm::mat4>> instances_;
  std::vector<float> emission_;  // per material; empty until an emission edit
  std::uint64_t version_ = 0;
};

// The region a light lights: its range, or where its irradiance falls below
// kLightReachIrradiance; everywhere for a directional light.
EditRegion lightRegion(const Light& light);
// The sphere around instance `index`'s mesh placed by `transform`, doubled: shadows and
// bounces reach past the surface.
EditRegion instanceRegion(const Scene& scene, std::size_t index, const glm::mat4& transform);

}  // namespace pc
