// Runtime edits on a running server: the network thread submits an editor's edits, the field
// thread takes the scene state with them at each tick, and the regions they changed for the
// probe scheduler. One mutex guards both sides; each holds it only for its own call.
#pragma once

#include <cstdint>
#include <mutex>
#include <vector>

#include "common/scene.h"
#include "common/scene_edits.h"

namespace pc {

class SceneEditor {
 public:
  explicit SceneEditor(const Scene& scene) : edits_(scene) {}

  // Network thread: checks and applies an edit at the field thread's latest animation time;
  // the next tick traces with it and publishes its state.
  Result<EditOutcome> submit(const SceneEdit& edit);
  // Field thread: the scene at `time` with the edits in force, and the regions of the edits
  // submitted since the previous call (appended to `changed`).
  SceneState evaluate(double time, std::vector<EditRegion>& changed);
  std::uint64_t version() const;

 private:
  mutable std::mutex mutex_;
  SceneEdits edits_;
  double time_ = 0;
  std::vector<EditRegion> pending_;
};

}  // namespace pc
