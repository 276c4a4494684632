// Tracer calls for tests: each returns what the call gives, and a failed call fails the test
// with the tracer's message (then the stats are empty), so that a test reads as the calls it
// makes.
#pragma once

#include <gtest/gtest.h>

#include "server/bake.h"
#include "server/field_compare.h"
#include "server/tracer.h"

namespace pc {

inline UpdateStats updateOrFail(Tracer& tracer, Field& field, const UpdateRequest& request) {
  Result<UpdateStats> updated = tracer.update(field, request);
  if (!updated) {
    ADD_FAILURE() << "update failed: " << updated.error().message;
    return {};
  }
  return std::move(updated).value();
}

inline void setStateOrFail(Tracer& tracer, const SceneState& state) {
  const Status moved = tracer.setState(state);
  if (!moved) ADD_FAILURE() << "setState failed: " << moved.error().message;
}

inline BakeStats bakeOrFail(Field& field, Tracer& tracer, const BakeOptions& options) {
  Result<BakeStats> baked = bakeField(field, tracer, options);
  if (!baked) {
    ADD_FAILURE() << "bake failed: " << baked.error().message;
    return {};
  }
  return std::move(baked).value();
}

// A 4x4x4 probe volume at the scene's centre spaced a fifth of its height (inside the McGuire
// Cornell box), baked `updates` times on each tracer from fresh fields: the first against the
// second (the reference).
inline FieldDifference bakeBothAndCompare(const Scene& scene, Tracer& tracer, Tracer& reference,
                                          int updates) {
  const glm::vec3 lo = scene.boundsMin, hi = scene.boundsMax;
  const float spacing = (hi.y - lo.y) / 5.0f;
  const std::vector<ProbeVolume> volumes = {
      {0.5f * (lo + hi) - 1.5f * spacing * glm::vec3(1.0f), spacing, glm::ivec3(4)}};
  Field a = Field::create(volumes, FieldSettings{});
  Field b = Field::create(volumes, FieldSettings{});
  BakeOptions bake;
  bake.updates = updates;
  bakeOrFail(a, tracer, bake);
  bakeOrFail(b, reference, bake);
  return compareFields(a, b);
}

}  // namespace pc
