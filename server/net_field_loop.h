// The server's field thread: ticks at a fixed rate on the animation clock, moves the scene
// (evaluateScene, Tracer::setState), updates the probes the scheduler picks (nearest the
// clients' viewers first under a budget), and publishes each finished update to the hub.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "common/field.h"
#include "common/log.h"
#include "common/scene.h"
#include "net_hub.h"
#include "net_metrics.h"
#include "probe_scheduler.h"
#include "scene_editor.h"
#include "tracer.h"

namespace pc {

struct FieldLoopOptions {
  double rate = 30.0;      // ticks per second
  double startTime = 0.0;  // animation time of the first tick
  double freezeAt = -1.0;  // animation time where the clock and the field stop (< 0: never)
  std::filesystem::path dumpField;  // at the freeze, the exact field is written here
  SchedulerOptions scheduler;
  // Probes at rest in a still scene (probe_rest.h): updated every rest period only.
  RestOptions rest;
  float changeThreshold = 0.0f;
  // Where the tracer fails (an Error from setState or update: a GPU lost or out of memory),
  // the field thread makes this one and goes on with it from the field as the last completed
  // update left it, redoing the failed tick's update. Without one, or where it fails too, the
  // field stays as it is and is still published every tick: clients keep what they hold and
  // the scene keeps moving.
  std::function<Result<std::unique_ptr<Tracer>>()> fallback;
  // Runtime edits (scene_editor.h): each tick traces and publishes the scene with the edits in
  // force, and the probes near an edit are scheduled first. Null: the animation alone.
  SceneEditor* editor = nullptr;
  // After an edit, this many updates blend with at most this hysteresis (every cascade), as a
  // bake's first updates do: the probes drop most of their history of the scene before the
  // edit (0.5^8: 0.4% of it) instead of converging over seconds. 0: no such updates.
  int editConvergeUpdates = 8;
  float editHysteresis = 0.5f;
};

struct FieldLoopStats {
  std::uint64_t ticks = 0;
  std::uint64_t fieldVersion = 0;
  double animationTime = 0;
  double lastUpdateMs = 0;
  int lastBricksChanged = 0;
  bool frozen = false;
  UpdateStats lastUpdate;         // the tracer's figures of the latest update (per-pass times)
  std::uint64_t editVersion = 0;  // the runtime edits the latest state includes
  double lastPublishMs = 0;       // quantizing the changed bricks for the senders
  std::uint64_t updates = 0;      // ticks that traced (not frozen)
  double updateSeconds = 0, publishSeconds = 0;  // totals
  std::string tracer;                            // the tracer's name; empty once none is left
  std::uint64_t tracerFailures = 0;              // tracer calls that failed
  std::string lastFailure;                       // the latest one's message
  std::size_t restingProbes = 0;                 // probes at rest after the latest update
  std::uint64_t scrolls = 0;                     // cascade moves to follow the viewers
  std::uint64_t scrolledProbes = 0;              // probes that started over in them
};

// The field thread's metrics (probecast_field_*) for the server's /metrics endpoint.
void appendFieldLoopMetrics(MetricsText& out, const FieldLoopStats& stats);
// Its figures for the periodic statistics record (statisticsFields adds the network's).
void appendFieldLoopFields(std::vector<LogField>& out, const FieldLoopStats& stats);

class FieldLoop {
 public:
  FieldLoop(const Scene& scene, Tracer& tracer, Field& field, FieldHub& hub,
            FieldLoopOptions options)
      : scene_(scene),
        tracer_(&tracer),
        field_(field),
        hub_(hub),
        options_(std::move(options)),
        scheduler_(options_.scheduler),
        rest_(options_.rest) {
    stats_.tracer = tracer.name();
  }

  // Ticks until `stop` is set. `clock` gives seconds on the server's clock (the one the
  // senders use). The animation clock follows it, so an overlong tick is caught up, not
  // drifted from.
  template <typename Clock>
  void run(const std::atomic<bool>& stop, Clock clock) {
    const double start = clock();
    std::uint64_t tick = 0;
    while (!stop.load()) {
      const double now = clock();
      tickOnce(now - start, now, ++tick);
      const double next = start + double(tick) / options_.rate;
      while (!stop.load() && clock() < next) sleepSeconds(std::min(0.005, next - clock()));
    }
  }

  FieldLoopStats stats() const {
    std::lock_guard lock(statsMutex_);
    return stats_;
  }

 private:
  void tickOnce(double elapsed, double now, std::uint64_t tick);
  // Moves the cascades that follow the viewers (field_scroll.h) to the middle of the viewers'
  // bounds; the probes that scrolled in go first in the next plans.
  void followViewers();
  // The scene state as published: with the cascades' places when any follows.
  SceneStateMsg publishedState(const SceneState& state) const;
  // The tick's update on the current tracer, and on the fallback where that one fails.
  UpdateStats update(const SceneState& state, std::uint64_t tick);
  // The current tracer's setState, then its update.
  Result<UpdateStats> moveAndUpdate(const SceneState& state, const UpdateRequest& request);
  // Replaces the failed tracer with the fallback; false where there is none to go on with.
  bool fallBack();
  static void sleepSeconds(double s);

  const Scene& scene_;
  Tracer* tracer_;  // null once every tracer failed
  std::unique_ptr<Tracer> fallbackTracer_;
  Field& field_;
  FieldHub& hub_;
  FieldLoopOptions options_;
  ProbeScheduler scheduler_;
  ProbeRest rest_;
  std::vector<std::uint8_t> restKey_;  // the scene state the probes rest in (encoded, untimed)
  bool frozen_ = false;
  int convergeLeft_ = 0;                  // updates still at editHysteresis
  std::vector<float> restoreHysteresis_;  // each cascade's own, while they are
  mutable std::mutex statsMutex_;
  FieldLoopStats stats_;
};

}  // namespace pc
