// ldm: the occlusion field from layered depth maps (server/ldm_occlusion.h, docs/LDM.md)
// against the ray-traced one, per scene:
//   - reference: an Embree bake of --updates updates of --rays rays, every update in the
//     running mean (no converging phase), so each probe's occlusion is the mean of
//     updates x rays rays under different rotations;
//   - LDM: --directions LDMs of --resolution^2 pixels over the field's bounds, built and traced
//     for every probe the reference left outside geometry, at the reference's (relocated)
//     positions;
//   - occlusion_mae: the mean absolute difference of the occlusion tiles' texels, per probe,
//     averaged over the probes; the same figure for one Embree update of --rays rays (another
//     rotation) says what a single ray-traced update's noise costs against the same reference;
//   - ldm_ms: build + trace, wall clock (submission, readback included), after a warm-up run.
#include <tbb/parallel_for.h>

#include <chrono>
#include <filesystem>
#include <limits>

#include "bench.h"
#include "bench_common.h"
#include "common/field.h"
#include "common/volume_placement.h"
#include "server/bake.h"
#include "server/embree_tracer.h"
#include "server/ldm_occlusion.h"
#include "shaders/interop/probe_math.h"
#include "shaders/interop/probe_update.h"

namespace pc::bench {

namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

// Mean over `probes` (those outside geometry in `a`) of the mean absolute difference of their
// occlusion tiles' interior texels.
double occlusionMae(const Field& a, const Field& b, const std::vector<ProbeRef>& probes,
                    int* counted) {
  constexpr int n = gpu::PC_OCCLUSION_TEXELS;
  double sum = 0;
  *counted = 0;
  for (const ProbeRef& p : probes) {
    if (a.probe(p.cascade, p.slot).state == gpu::PC_PROBE_INSIDE) continue;
    const glm::ivec2 o = gpu::pcAtlasTileOrigin(a.cascade(p.cascade), p.slot, n + 2);
    double e = 0;
    for (int y = 1; y <= n; ++y)
      for (int x = 1; x <= n; ++x)
        e += std::abs(a.occlusion.at(o.x + x, o.y + y)[0] - b.occlusion.at(o.x + x, o.y + y)[0]);
    sum += e / (n * n);
    ++*counted;
  }
  return *counted > 0 ? sum / *counted : 0.0;
}

struct SceneResult {
  double mae = 0, maeOneUpdate = 0, maeSameDirections = 0, ms = 0;
};

// The LDMs' estimator with Embree rays instead of LDM lookups: from each probe, a ray along
// each LDM direction both ways, open where its first hit lies beyond d_max and is no backface
// (as the tracers count it), weighed per texel as ldm_occlusion.comp does. Its difference to
// the reference is what the finite direction set costs; the LDMs' own difference beyond it is
// what the pixels cost.
std::vector<float> embreeAlongDirections(const Scene& scene, const EmbreeScene& embree,
                                         const Field& field, const std::vector<ProbeRef>& probes,
                                         const LdmOcclusion& ldm) {
  constexpr int n = gpu::PC_OCCLUSION_TEXELS;
  const int dirs = ldm.stats().directions;
  const float dmax = field.desc.occlusionDistance;
  std::vector<float> tiles(probes.size() * n * n, 1.0f);
  tbb::parallel_for(std::size_t(0), probes.size(), [&](std::size_t i) {
    const ProbeRef& p = probes[i];
    const glm::vec3 origin = field.probePosition(p.cascade, p.slot);
    const float near = gpu::pcProbeRayNear(field.cascade(p.cascade));
    auto open = [&](glm::vec3 d) {
      Hit hit;
      if (!embree.intersect(origin, d, near, std::numeric_limits<float>::infinity(), hit))
        return true;
      const SurfacePoint sp = embree.surface(hit, origin, d);
      const bool backSurface =
          sp.material >= 0 && std::size_t(sp.material) < scene.materials.size() &&
          gpu::pcBackfaceIsSurface(scene.materials[std::size_t(sp.material)].alphaCutoff);
      return hit.t > dmax && (!sp.backface || backSurface);
    };
    std::vector<char> isOpen(std::size_t(2 * dirs));
    for (int j = 0; j < dirs; ++j) {
      isOpen[std::size_t(2 * j)] = open(ldm.direction(j));
      isOpen[std::size_t(2 * j + 1)] = open(-ldm.direction(j));
    }
    for (int t = 0; t < n * n; ++t) {
      const glm::vec3 w = gpu::pcTexelDirection(t % n, t / n, n);
      float o = 0, total = 0;
      for (int j = 0; j < dirs; ++j) {
        const float c = glm::dot(w, ldm.direction(j));
        total += std::abs(c);
        if (isOpen[std::size_t(c >= 0.0f ? 2 * j : 2 * j + 1)]) o += std::abs(c);
      }
      tiles[i * n * n + std::size_t(t)] = total > 0 ? o / total : 1.0f;
    }
  });
  return tiles;
}

}  // namespace

Benchmark addLdm(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "ldm",
      "occlusion field from layered depth maps against Embree's: mean absolute error per probe "
      "and build + trace time");
  static std::vector<std::string> scenePaths;
  static std::string device;
  static int directions = LdmOptions{}.directions, resolution = LdmOptions{}.resolution;
  static int rays = 256, updates = 16, repeats = 3;
  static bool gpuOnly = false;
  cmd->add_option("--scene", scenePaths,
                  "scene files (default: godot-living-room and sauer-pandora of the shared "
                  "scenes)");
  addSceneLoadOptions(*cmd, sceneLoadOptions());
  cmd->add_option("--directions", directions, "LDMs (each traced both ways)")
      ->capture_default_str();
  cmd->add_option("--resolution", resolution, "pixels a side of each LDM")->capture_default_str();
  cmd->add_option("--rays", rays, "reference: rays per probe per Embree update")
      ->capture_default_str();
  cmd->add_option("--updates", updates, "reference: Embree updates, all in the running mean")
      ->capture_default_str();
  cmd->add_option("--repeats", repeats, "timed LDM runs after the warm-up")->capture_default_str();
  cmd->add_option("--device", device, "substring of the Vulkan device name");
  cmd->add_flag("--gpu-only", gpuOnly, "refuse CPU Vulkan implementations (lavapipe)");
  return {cmd, [] {
            std::vector<std::string> paths = scenePaths;
            if (paths.empty()) {
              for (const char* name : {"godot-living-room", "sauer-pandora"}) {
                auto files = sceneFilesIn(std::string(PC_SCENES_DIR) + "/" + name);
                if (!files || files->empty()) {
                  std::printf("ldm: skipping %s: no scene under %s/%s\n", name, PC_SCENES_DIR,
                              name);
                  continue;
                }
                paths.push_back(files->front());
              }
              if (paths.empty()) {
                std::printf("ldm: no shared scenes (%s absent); pass --scene\n", PC_SCENES_DIR);
                return 0;
              }
            }
            vk::ContextOptions co;
            co.allowCpuDevice = !gpuOnly;
            co.deviceNameFilter = device;
            auto ctx = vk::Context::create(co);
            if (!ctx) {
              std::fprintf(stderr, "ldm: %s\n", ctx.error().message.c_str());
              return 1;
            }
            auto ldm = LdmOcclusion::create(**ctx, LdmOptions{directions, resolution});
            if (!ldm) {
              std::fprintf(stderr, "ldm: %s\n", ldm.error().message.c_str());
              return 1;
            }
            auto failed = [](const std::string& what) {
              std::fprintf(stderr, "ldm: %s\n", what.c_str());
              return 1;
            };
            std::printf(
                "ldm: %d directions (%d both ways), %d^2 pixels; reference Embree %d x %d "
                "rays per probe\n",
                directions, 2 * directions,
                (*ldm)->stats().resolution > 0 ? (*ldm)->stats().resolution : resolution, updates,
                rays);
            std::printf("device: %s; host: %s\n", (*ctx)->deviceName().c_str(),
                        machineDescription().c_str());
            std::vector<SceneResult> results;
            for (const std::string& path : paths) {
              auto scene = loadBenchScene(path, "");
              if (!scene) return failed(scene.error().message);
              FieldSettings settings;
              settings.raysPerProbe = rays;
              const std::vector<ProbeVolume> volumes = sceneVolumes(*scene);
              Field reference = Field::create(volumes, settings);
              auto embree = EmbreeTracer::create(*scene, TracerOptions{});
              if (!embree) return failed(embree.error().message);
              BakeOptions bake;
              bake.updates = updates;
              bake.convergeFraction = 0.0f;
              const auto bakeStart = Clock::now();
              auto baked = bakeField(reference, **embree, bake);
              if (!baked) return failed(baked.error().message);
              const double bakeMs = msSince(bakeStart);
              // One update of the same rays under another rotation, from the reference's
              // positions: a single ray-traced update's occlusion.
              Field oneUpdate = reference;
              UpdateRequest one;
              one.probes = allProbes(reference);
              one.rotationSeed = 7777777u;
              for (auto& r : oneUpdate.probes) r.updates = 0;
              if (auto u = (*embree)->update(oneUpdate, one); !u) return failed(u.error().message);

              const std::vector<ProbeRef> probes = allProbes(reference);
              const std::vector<glm::vec3> positions = ldmProbePositions(reference, probes);
              glm::vec3 lo, hi;
              ldmFieldBounds(reference, lo, hi);
              const std::vector<gpu::LdmTriangle> triangles =
                  ldmSceneTriangles(*scene, SceneState{}, lo, hi);
              Result<std::vector<float>> tiles = std::vector<float>{};
              double buildMs = 0, traceMs = 0;
              for (int run = 0; run <= repeats; ++run) {  // run 0 warms up
                const auto t0 = Clock::now();
                if (Status built = (*ldm)->build(triangles, lo, hi); !built)
                  return failed(built.error().message);
                const double b = msSince(t0);
                const auto t1 = Clock::now();
                tiles = (*ldm)->occlusion(positions, reference.desc.occlusionDistance);
                if (!tiles) return failed(tiles.error().message);
                if (run > 0) buildMs += b, traceMs += msSince(t1);
              }
              buildMs /= std::max(repeats, 1);
              traceMs /= std::max(repeats, 1);
              Field fromLdm = reference;
              writeLdmOcclusion(fromLdm, probes, *tiles);
              Field sameDirections = reference;
              writeLdmOcclusion(
                  sameDirections, probes,
                  embreeAlongDirections(*scene, (*embree)->embree(), reference, probes, **ldm));
              SceneResult r;
              int counted = 0;
              r.maeSameDirections = occlusionMae(reference, sameDirections, probes, &counted);
              r.mae = occlusionMae(reference, fromLdm, probes, &counted);
              r.maeOneUpdate = occlusionMae(reference, oneUpdate, probes, &counted);
              r.ms = buildMs + traceMs;
              results.push_back(r);
              const LdmBuildStats& s = (*ldm)->stats();
              std::printf(
                  "%s: %zu triangles (%d within the field's bounds), %d probes outside geometry "
                  "of %zu, d_max %.3g m, pixel %.3g m\n",
                  scene->name.c_str(), scene->triangleCount(), s.triangles, counted, probes.size(),
                  double(reference.desc.occlusionDistance), double(s.pixel));
              std::printf(
                  "  layers %llu (at most %d a pixel, %d lists sorted in place), %.1f MiB, "
                  "%d rasterization(s)\n",
                  (unsigned long long)s.layers, s.maxLayers, s.longLists,
                  double(s.bytes) / double(1 << 20), s.attempts);
              std::printf("  LDM build %.2f ms + trace %.2f ms; Embree reference bake %.1f s\n",
                          buildMs, traceMs, bakeMs / 1e3);
              std::printf(
                  "  occlusion MAE per probe: LDM %.4f, Embree along the LDM directions %.4f, one "
                  "Embree update of %d rays %.4f\n",
                  r.mae, r.maeSameDirections, rays, r.maeOneUpdate);
              const std::string slug = sceneSlug(*scene);
              figure("occlusion_mae_" + slug, r.mae, "share");
              figure("occlusion_mae_one_update_" + slug, r.maeOneUpdate, "share");
              figure("occlusion_mae_ldm_directions_" + slug, r.maeSameDirections, "share");
              figure("ldm_ms_" + slug, r.ms, "ms");
            }
            double mae = 0, ms = 0;
            for (const SceneResult& r : results) mae += r.mae, ms += r.ms;
            figure("ldm_directions", directions, "count");
            figure("ldm_resolution", (*ldm)->stats().resolution, "pixels");
            figure("occlusion_mae", mae / double(results.size()), "share");
            figure("ldm_ms", ms / double(results.size()), "ms");
            return 0;
          }};
}

}  // namespace pc::bench
