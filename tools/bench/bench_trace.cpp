// trace: in one run, on the same scene and the same probe rays, (a) bare Embree closest-hit
// throughput for the probe rays alone and (b) the full field update (probe rays, shadow rays,
// shading with the previous field, blending). Prints both rates and their ratio. The field
// the measured updates leave can be written, or compared with one written before: a faster
// update must leave the same field.
#include <chrono>

#include "bench.h"
#include "common/field.h"
#include "common/volume_placement.h"
#include "protocol/baked_file.h"
#include "server/bake.h"
#include "server/embree_tracer.h"
#include "server/field_compare.h"

namespace pc::bench {

Benchmark addTrace(CLI::App& app) {
  auto* cmd = app.add_subcommand("trace", "Embree: raw probe-ray rate vs full field update rate");
  static std::string scenePath = "builtin", sidecar, writeField, compareField;
  static int updates = 6, warmup = 4, rays = 256;
  static std::vector<int> counts;
  static float roulette = pc::TracerOptions{}.shadowRouletteShare;
  cmd->add_option("--scene", scenePath, "scene file, or 'builtin'");
  cmd->add_option("--shadow-roulette", roulette,
                  "share of a hit's punctual light below which shadow rays are drawn at random (0: "
                  "all traced)")
      ->capture_default_str();
  cmd->add_option("--sidecar", sidecar, "scene.json sidecar");
  addSceneLoadOptions(*cmd, sceneLoadOptions());
  cmd->add_option("--updates", updates, "measured updates");
  cmd->add_option("--warmup", warmup, "updates before measuring (states, indirect light)");
  cmd->add_option("--rays", rays, "rays per probe");
  cmd->add_option("--counts", counts, "probes per axis of a single cascade over the scene (x y z)")
      ->expected(3);
  cmd->add_option("--write-field", writeField, "write the field the measured updates left here");
  cmd->add_option("--compare-field", compareField,
                  "compare the field the measured updates left with this one (--write-field of "
                  "the same command)");
  return {cmd, [] {
            auto scene = loadBenchScene(scenePath, sidecar);
            if (!scene) {
              std::fprintf(stderr, "trace: %s\n", scene.error().message.c_str());
              return 1;
            }
            std::vector<ProbeVolume> volumes = sceneVolumes(*scene);
            if (counts.size() == 3) {
              glm::vec3 extent = scene->boundsMax - scene->boundsMin;
              glm::ivec3 n(counts[0], counts[1], counts[2]);
              float spacing = std::max(extent.x / n.x, std::max(extent.y / n.y, extent.z / n.z));
              glm::vec3 origin =
                  0.5f * (scene->boundsMin + scene->boundsMax) - 0.5f * spacing * glm::vec3(n - 1);
              volumes = {ProbeVolume{origin, spacing, n}};
            }
            FieldSettings settings;
            settings.raysPerProbe = rays;
            Field field = Field::create(volumes, settings);
            TracerOptions options;
            options.shadowRouletteShare = roulette;
            auto tracer = EmbreeTracer::create(*scene, options);
            if (!tracer) {
              std::fprintf(stderr, "trace: %s\n", tracer.error().message.c_str());
              return 1;
            }
            BakeOptions warm;
            warm.updates = warmup;
            if (auto baked = bakeField(field, **tracer, warm); !baked) {
              std::fprintf(stderr, "trace: %s\n", baked.error().message.c_str());
              return 1;
            }

            UpdateRequest request;
            request.probes = allProbes(field);
            double rawMs = 0, fullMs = 0, shadeMs = 0, blendMs = 0;
            std::uint64_t probeRays = 0, shadowRays = 0, hits = 0;
            for (int i = 0; i < updates; ++i) {
              request.rotationSeed = 1000u + std::uint32_t(i);
              std::uint64_t h = 0;
              rawMs += (*tracer)->traceOnly(field, request, &h);
              hits += h;
              auto updated = (*tracer)->update(field, request);
              if (!updated) {
                std::fprintf(stderr, "trace: %s\n", updated.error().message.c_str());
                return 1;
              }
              const UpdateStats& s = *updated;
              fullMs += s.totalMs;
              shadeMs += s.traceMs;
              blendMs += s.blendMs;
              probeRays += s.probeRays;
              shadowRays += s.shadowRays;
            }
            const double raw = double(probeRays) / (rawMs * 1e3);
            const double full = double(probeRays + shadowRays) / (fullMs * 1e3);
            const double fullProbe = double(probeRays) / (fullMs * 1e3);
            std::printf("trace: %s (%zu triangles), %d probes x %d rays, %d measured updates\n",
                        scene->name.c_str(), scene->triangleCount(), int(request.probes.size()),
                        rays, updates);
            std::printf("machine: %s; Embree 3 on TBB\n", machineDescription().c_str());
            std::printf("%-34s %12s %12s %12s\n", "pass", "ms/update", "rays/update", "Mrays/s");
            std::printf("%-34s %12.2f %12llu %12.2f\n", "raw closest hit (probe rays)",
                        rawMs / updates, (unsigned long long)(probeRays / updates), raw);
            std::printf("%-34s %12.2f %12llu %12.2f\n", "full update (probe + shadow rays)",
                        fullMs / updates, (unsigned long long)((probeRays + shadowRays) / updates),
                        full);
            std::printf("%-34s %12s %12llu %12.2f\n", "full update (probe rays only)", "",
                        (unsigned long long)(probeRays / updates), fullProbe);
            std::printf(
                "  of which trace + shade %.2f ms, blend + borders + classify %.2f ms per update\n",
                shadeMs / updates, blendMs / updates);
            std::printf("hit fraction %.3f, shadow rays per probe ray %.2f\n",
                        double(hits) / probeRays, double(shadowRays) / probeRays);
            figure("raw_mrays", raw, "Mrays/s");
            figure("update_mrays", full, "Mrays/s");
            figure("update_probe_mrays", fullProbe, "Mrays/s");
            figure("trace_ratio", full / raw, "ratio");
            if (!writeField.empty()) {
              if (Status s = writeBakedField(writeField, field); !s) {
                std::fprintf(stderr, "trace: %s\n", s.error().message.c_str());
                return 1;
              }
            }
            if (!compareField.empty()) {
              auto reference = readBakedField(compareField, 0);
              if (!reference) {
                std::fprintf(stderr, "trace: %s\n", reference.error().message.c_str());
                return 1;
              }
              if (!sameLayout(field.desc, reference->desc)) {
                std::fprintf(stderr, "trace: %s holds another field layout\n",
                             compareField.c_str());
                return 1;
              }
              const FieldDifference d = compareFields(field, *reference);
              std::printf("against %s: %d probes active in both, %d states differ\n",
                          compareField.c_str(), d.probes, d.stateMismatches);
              figure("field_rel_diff_irradiance", d.irradiance, "ratio");
              figure("field_rel_diff_depth", d.depth, "ratio");
              figure("field_state_mismatches", d.stateMismatches, "probes");
            }
            return 0;
          }};
}

}  // namespace pc::bench
