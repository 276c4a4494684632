#include "scene_editor.h"

namespace pc {

Result<EditOutcome> SceneEditor::submit(const SceneEdit& edit) {
  std::lock_guard lock(mutex_);
  auto outcome = edits_.apply(edit, time_);
  if (outcome) pending_.insert(pending_.end(), outcome->regions.begin(), outcome->regions.end());
  return outcome;
}

SceneState SceneEditor::evaluate(double time, std::vector<EditRegion>& changed) {
  std::lock_guard lock(mutex_);
  time_ = time;
  changed.insert(changed.end(), pending_.begin(), pending_.end());
  pending_.clear();
  return edits_.evaluate(time);
}

std::uint64_t SceneEditor::version() const {
  std::lock_guard lock(mutex_);
  return edits_.version();
}

}  // namespace pc
