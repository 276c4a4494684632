#include "net_field_loop.h"

#include <chrono>
#include <thread>

#include "common/log.h"
#include "protocol/baked_file.h"

namespace pc {

void FieldLoop::sleepSeconds(double s) {
  if (s > 0) std::this_thread::sleep_for(std::chrono::duration<double>(s));
}

void FieldLoop::tickOnce(double elapsed, double now, std::uint64_t tick) {
  double t = options_.startTime + elapsed;
  const bool freezing = options_.freezeAt >= 0 && t >= options_.freezeAt;
  if (freezing) t = options_.freezeAt;
  const SceneState state = evaluateScene(scene_, t);

  UpdateStats us;
  if (!frozen_) {
    tracer_.setState(state);
    UpdateRequest request;
    request.rotationSeed = std::uint32_t(tick);
    request.probes = scheduler_.plan(field_, tick, hub_.viewers());
    request.changeThreshold = options_.changeThreshold;
    us = tracer_.update(field_, request);
  }
  // Published every tick, frozen or not: the scene state doubles as the clients' clock.
  Status published = hub_.publish(field_, sceneStateMessage(state), now);
  if (!published) logError("publish: " + published.error().message);

  if (freezing && !frozen_) {
    // The last update was traced at the freeze time: from here on the field no longer changes,
    // so clients converge to exactly this field, which is what gets written.
    frozen_ = true;
    logInfo("animation frozen at t=" + std::to_string(t) + " s, field version " +
            std::to_string(field_.version));
    if (!options_.dumpField.empty()) {
      Status written = writeBakedField(options_.dumpField, field_);
      if (!written) logError("--dump-field: " + written.error().message);
    }
  }
  std::lock_guard lock(statsMutex_);
  stats_.ticks = tick;
  stats_.fieldVersion = field_.version;
  stats_.animationTime = t;
  if (us.totalMs > 0) stats_.lastUpdateMs = us.totalMs;
  stats_.lastBricksChanged = us.bricksChanged;
  stats_.frozen = frozen_;
}

}  // namespace pc
