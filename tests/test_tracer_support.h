// Tracer calls for tests: each returns what the call gives, and a failed call fails the test
// with the tracer's message (then the stats are empty), so that a test reads as the calls it
// makes.
#pragma once

#include <gtest/gtest.h>

#include "server/bake.h"
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

}  // namespace pc
