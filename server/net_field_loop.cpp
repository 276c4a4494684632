#include "net_field_loop.h"

#include <chrono>
#include <thread>

#include "common/field_scroll.h"
#include "common/log.h"
#include "protocol/baked_file.h"

namespace pc {

void FieldLoop::sleepSeconds(double s) {
  if (s > 0) std::this_thread::sleep_for(std::chrono::duration<double>(s));
}

UpdateStats FieldLoop::update(const SceneState& state, std::uint64_t tick) {
  UpdateRequest request;
  request.rotationSeed = std::uint32_t(tick);
  std::vector<glm::vec3> viewers;
  std::vector<float> weights;
  hub_.weightedViewers(viewers, weights);
  request.probes = scheduler_.plan(field_, tick, viewers, weights, &rest_);
  request.changeThreshold = options_.changeThreshold;
  while (tracer_) {
    Result<UpdateStats> updated = moveAndUpdate(state, request);
    if (updated) {
      rest_.observe(field_, request.probes);
      return std::move(updated).value();
    }
    const std::string& why = updated.error().message;
    logError("field update " + std::to_string(tick) + " failed: " + why);
    {
      std::lock_guard lock(statsMutex_);
      ++stats_.tracerFailures;
      stats_.lastFailure = why;
    }
    if (!fallBack()) break;
  }
  return {};
}

Result<UpdateStats> FieldLoop::moveAndUpdate(const SceneState& state,
                                             const UpdateRequest& request) {
  if (Status s = tracer_->setState(state); !s) return s.error();
  return tracer_->update(field_, request);
}

bool FieldLoop::fallBack() {
  const bool used = fallbackTracer_ != nullptr;  // the fallback itself failed
  tracer_ = nullptr;
  if (!used && options_.fallback) {
    auto made = options_.fallback();
    if (made) {
      fallbackTracer_ = std::move(made).value();
      tracer_ = fallbackTracer_.get();
      logWarn("field updates go on with the " + tracer_->name() + " tracer, from field version " +
              std::to_string(field_.version));
    } else {
      logError("fallback tracer: " + made.error().message);
    }
  }
  if (!tracer_)
    logError("no tracer left: the field stays at version " + std::to_string(field_.version) +
             ", still published to clients");
  std::lock_guard lock(statsMutex_);
  stats_.tracer = tracer_ ? tracer_->name() : "";
  return tracer_ != nullptr;
}

SceneStateMsg FieldLoop::publishedState(const SceneState& state) const {
  SceneStateMsg m = sceneStateMessage(state);
  m.cascadePlaces = cascadePlaces(field_);
  return m;
}

void FieldLoop::followViewers() {
  bool follows = false;
  for (int k = 0; k < field_.cascadeCount(); ++k) follows |= field_.cascade(k).follows != 0;
  if (!follows) return;
  const std::vector<glm::vec3> viewers = hub_.viewers();
  if (viewers.empty()) return;  // no one to follow: the cascades stay where they are
  glm::vec3 lo = viewers.front(), hi = viewers.front();
  for (const glm::vec3& v : viewers) {
    lo = glm::min(lo, v);
    hi = glm::max(hi, v);
  }
  const glm::vec3 center = 0.5f * (lo + hi);
  std::uint64_t scrolls = 0, probes = 0;
  for (int k = 0; k < field_.cascadeCount(); ++k) {
    if (field_.cascade(k).follows == 0) continue;
    const glm::ivec3 shift = followShift(field_.cascade(k), center);
    if (shift == glm::ivec3(0)) continue;
    const std::vector<int> reset = scrollCascade(field_, k, shift);
    scheduler_.forget(field_, k, reset);
    const std::size_t first = std::size_t(field_.cascade(k).firstProbe);
    for (int s : reset) rest_.wake(first + std::size_t(s));
    ++scrolls;
    probes += reset.size();
  }
  if (scrolls == 0) return;
  std::lock_guard lock(statsMutex_);
  stats_.scrolls += scrolls;
  stats_.scrolledProbes += probes;
}

void FieldLoop::tickOnce(double elapsed, double now, std::uint64_t tick) {
  double t = options_.startTime + elapsed;
  const bool freezing = options_.freezeAt >= 0 && t >= options_.freezeAt;
  if (freezing) t = options_.freezeAt;
  std::vector<EditRegion> edited;
  const SceneState state =
      options_.editor ? options_.editor->evaluate(t, edited) : evaluateScene(scene_, t);
  if (!edited.empty()) {
    scheduler_.prioritize(field_, edited);
    // A new edit's state goes out before the update that traces it: clients light the scene
    // as edited one update sooner, and the field follows over the next updates anyway.
    if (Status early = hub_.publish(field_, publishedState(state), now); !early)
      logError("publish: " + early.error().message);
  }

  if (!edited.empty()) convergeLeft_ = options_.editConvergeUpdates;
  {
    // Any change of what the tracer sees (lights, instances, emission, edits) wakes every
    // probe; the clock alone does not.
    SceneStateMsg untimed = sceneStateMessage(state);
    untimed.animationTime = 0;
    std::vector<std::uint8_t> key = encodeMessage(untimed);
    if (key != restKey_) {
      rest_.wakeAll();
      restKey_ = std::move(key);
    }
  }
  if (!frozen_) followViewers();
  UpdateStats us;
  if (!frozen_ && tracer_) {
    if (convergeLeft_ > 0 && restoreHysteresis_.empty()) {
      for (int k = 0; k < field_.cascadeCount(); ++k) {
        restoreHysteresis_.push_back(field_.cascade(k).hysteresis);
        field_.desc.cascades[k].hysteresis =
            std::min(field_.desc.cascades[k].hysteresis, options_.editHysteresis);
      }
    }
    us = update(state, tick);
    if (convergeLeft_ > 0 && --convergeLeft_ == 0) {
      for (int k = 0; k < field_.cascadeCount(); ++k)
        field_.desc.cascades[k].hysteresis = restoreHysteresis_[std::size_t(k)];
      restoreHysteresis_.clear();
    }
  }
  // Published every tick, frozen or not: the scene state doubles as the clients' clock.
  const auto publishStart = std::chrono::steady_clock::now();
  Status published = hub_.publish(field_, publishedState(state), now);
  const double publishMs =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - publishStart)
          .count();
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
  stats_.editVersion = state.editVersion;
  if (us.totalMs > 0) stats_.lastUpdateMs = us.totalMs;
  stats_.lastBricksChanged = us.bricksChanged;
  stats_.frozen = frozen_;
  if (us.totalMs > 0) {
    stats_.lastUpdate = us;
    ++stats_.updates;
    stats_.updateSeconds += us.totalMs / 1e3;
  }
  stats_.lastPublishMs = publishMs;
  stats_.restingProbes = rest_.restingProbes();
  stats_.publishSeconds += publishMs / 1e3;
}

void appendFieldLoopFields(std::vector<LogField>& out, const FieldLoopStats& s) {
  out.insert(out.end(), {{"animation_time_s", s.animationTime},
                         {"field_updates_total", s.updates},
                         {"last_update_ms", s.lastUpdateMs},
                         {"last_bricks_changed", s.lastBricksChanged},
                         {"frozen", s.frozen ? 1 : 0},
                         {"tracer", s.tracer.empty() ? "none" : s.tracer}});
}

void appendFieldLoopMetrics(MetricsText& m, const FieldLoopStats& s) {
  m.counter("probecast_field_ticks_total", "Field thread ticks (each publishes).", double(s.ticks));
  m.counter("probecast_field_updates_total", "Field updates traced.", double(s.updates));
  m.counter("probecast_field_tracer_failures_total",
            "Tracer failures (a GPU lost or out of memory); each moves updates to the fallback.",
            double(s.tracerFailures));
  m.gauge("probecast_field_tracer_info", "The tracer updating the field (none: updates stopped).",
          1.0, {{"tracer", s.tracer.empty() ? "none" : s.tracer}});
  m.counter("probecast_field_update_seconds_total", "Time spent tracing and blending updates.",
            s.updateSeconds);
  m.counter("probecast_field_publish_seconds_total",
            "Time spent publishing updates (quantizing changed bricks).", s.publishSeconds);
  m.gauge("probecast_field_animation_time_seconds", "Animation time of the latest tick.",
          s.animationTime);
  m.gauge("probecast_field_frozen", "1 once the animation clock and the field stopped.",
          s.frozen ? 1.0 : 0.0);
  m.gauge("probecast_field_last_bricks_changed", "Bricks changed by the latest update.",
          double(s.lastUpdate.bricksChanged));
  m.gauge("probecast_field_last_probes_updated", "Probes traced by the latest update.",
          double(s.lastUpdate.probesUpdated));
  m.counter("probecast_field_scrolls_total",
            "Moves of cascades that follow the viewers (each re-traces the probes that came in).",
            double(s.scrolls));
  m.counter("probecast_field_scrolled_probes_total",
            "Probes that started over because their cascade moved to follow the viewers.",
            double(s.scrolledProbes));
  m.gauge("probecast_field_resting_probes",
          "Probes at rest in a still scene (updated every rest period only).",
          double(s.restingProbes));
  // Per pass, the latest update. The CPU tracer fuses trace and shade (shade reads 0); a GPU
  // tracer adds its timestamped passes. The update's whole duration is a metric of its own, not
  // a pass: sum(probecast_field_last_pass_seconds) would count it twice.
  const std::string help = "Duration of each pass of the latest field update.";
  const UpdateStats& u = s.lastUpdate;
  m.gauge("probecast_field_last_update_seconds",
          "Duration of the latest field update (trace, shade and blend; not publish).",
          u.totalMs / 1e3);
  m.gauge("probecast_field_last_pass_seconds", help, u.traceMs / 1e3, {{"pass", "trace"}});
  m.gauge("probecast_field_last_pass_seconds", help, u.shadeMs / 1e3, {{"pass", "shade"}});
  m.gauge("probecast_field_last_pass_seconds", help, u.blendMs / 1e3, {{"pass", "blend"}});
  m.gauge("probecast_field_last_pass_seconds", help, s.lastPublishMs / 1e3, {{"pass", "publish"}});
  // The GPU's timestamps of its passes measure the same work again, on the device: a family
  // of their own, so that each family sums to one update.
  for (const auto& [name, ms] : u.gpuPasses) {
    m.gauge("probecast_field_last_gpu_pass_seconds",
            "GPU duration of each pass of the latest field update (device timestamps).", ms / 1e3,
            {{"pass", name}});
  }
}

}  // namespace pc
