// gpu-trace: a Vulkan backend (ray tracing, or with --backend sdf the distance field traced in
// compute) on one scene, in one run:
//   - speed: GPU milliseconds per pass, per update, probe rays per second end to end (trace,
//     shade, shadow trace, blend: probe_grays) and all rays (with shadow rays), against the raw
//     rate of the same probe rays through the update's trace pass alone (closest hits only: the
//     ceiling); and per whole update, which adds packing changed bricks for the host
//     (update_grays);
//   - agreement: the GPU and Embree fields after the same updates (same seeds and settings);
//   - quality: the probe-lit render from each field against the path-traced reference.
// The Embree backend runs the same updates on this machine's cores for comparison.
#include <chrono>
#include <map>

#include "bench.h"
#include "bench_common.h"
#include "common/field.h"
#include "common/volume_placement.h"
#include "cpu/path_tracer.h"
#include "cpu/probe_lit_render.h"
#include "server/bake.h"
#include "server/embree_tracer.h"
#include "server/field_compare.h"
#include "server/vulkan_tracer.h"

namespace pc::bench {

namespace {

// One cascade of n probes per axis spread over the scene's bounds (as bench trace does).
std::vector<ProbeVolume> volumesFor(const Scene& scene, const std::vector<int>& counts) {
  if (counts.size() != 3) return sceneVolumes(scene);
  const glm::vec3 extent = scene.boundsMax - scene.boundsMin;
  const glm::ivec3 n(counts[0], counts[1], counts[2]);
  const float spacing = std::max(extent.x / n.x, std::max(extent.y / n.y, extent.z / n.z));
  const glm::vec3 origin =
      0.5f * (scene.boundsMin + scene.boundsMax) - 0.5f * spacing * glm::vec3(n - 1);
  return {ProbeVolume{origin, spacing, n}};
}

double grays(std::uint64_t rays, double ms) { return ms > 0 ? double(rays) / (ms * 1e6) : 0.0; }

}  // namespace

Benchmark addGpuTrace(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "gpu-trace",
      "Vulkan ray tracing or SDF tracing: speed per pass, raw ceiling, agreement with Embree, "
      "quality");
  static std::string scenePath = "builtin", sidecar, device, backend = "vulkan";
  static int updates = 8, rays = 256, worst = 0, sdfVoxels = VulkanTracerOptions{}.sdfVoxels;
  static std::size_t shadowMemoryMiB = 0, passRays = 0;
  static std::vector<int> counts;
  static bool gpuOnly = false, skipEmbree = false, skipQuality = false, boundedShadowLaunch = false,
              singleBounce = false, pipelineStatistics = false, shadowSlotTimes = false,
              ldmOcclusion = false;
  static float roulette = pc::TracerOptions{}.shadowRouletteShare;
  static RenderSetup setup;
  cmd->add_option("--scene", scenePath, "scene file, or 'builtin'");
  cmd->add_option("--sidecar", sidecar, "scene.json sidecar");
  addSceneLoadOptions(*cmd, sceneLoadOptions());
  cmd->add_option("--measured", updates,
                  "measured updates (after --updates bake updates of both backends)");
  cmd->add_option("--rays", rays, "rays per probe");
  cmd->add_option("--shadow-roulette", roulette,
                  "share of a hit's punctual light below which shadow rays are drawn at random (0: "
                  "all traced)")
      ->capture_default_str();
  cmd->add_option("--counts", counts, "probes per axis of a single cascade over the scene (x y z)")
      ->expected(3);
  cmd->add_option("--device", device, "substring of the Vulkan device name");
  cmd->add_option("--backend", backend,
                  "vulkan (ray-tracing pipelines) or sdf (a distance field sphere-traced in "
                  "compute)")
      ->check(CLI::IsMember({"vulkan", "sdf"}))
      ->capture_default_str();
  cmd->add_option("--sdf-voxels", sdfVoxels,
                  "sdf backend: distance-field voxels along the scene's longest side")
      ->capture_default_str();
  cmd->add_flag("--ldm-occlusion", ldmOcclusion,
                "the GPU backend's occlusion tiles from layered depth maps (docs/LDM.md)");
  cmd->add_flag("--gpu-only", gpuOnly, "refuse CPU Vulkan implementations (lavapipe)");
  cmd->add_flag("--no-embree", skipEmbree, "skip the Embree run (and the field comparison)");
  cmd->add_flag("--no-quality", skipQuality, "skip the probe-lit renders and the reference");
  cmd->add_flag("--single-bounce", singleBounce,
                "both backends skip the previous field at hits (direct light only), to tell where "
                "they part");
  cmd->add_option("--worst", worst,
                  "list the N probes whose irradiance, and the N whose depth, differ most between "
                  "the backends, and those whose state differs");
  cmd->add_flag(
      "--bounded-shadow-launch", boundedShadowLaunch,
      "launch shadow rays over the most the list can hold, not from the list's length on the GPU");
  cmd->add_option(
      "--shadow-memory", shadowMemoryMiB,
      "MiB the shadow slots' records may take; more slots run in rounds (0: a quarter of the "
      "device-local heap, at most 8 GiB)");
  cmd->add_option(
      "--pass-rays", passRays,
      "the most probe rays one pass of a GPU update holds; larger updates run in slices "
      "of their probes (0: as many as the device's buffers and memory allow)");
  cmd->add_flag("--pipeline-statistics", pipelineStatistics,
                "log each GPU pipeline's compiler statistics (registers, shared memory), where "
                "the driver reports them");
  cmd->add_flag("--shadow-slot-times", shadowSlotTimes,
                "time each shadow slot's launch apart (serializes them) and log its shadow rays");
  addRenderOptions(*cmd, setup);
  return {
      cmd, [] {
        auto scene = loadBenchScene(scenePath, sidecar);
        if (!scene) {
          std::fprintf(stderr, "gpu-trace: %s\n", scene.error().message.c_str());
          return 1;
        }
        FieldSettings settings;
        settings.raysPerProbe = rays;
        const std::vector<ProbeVolume> volumes = volumesFor(*scene, counts);
        VulkanTracerOptions vo;
        vo.allowCpuDevice = !gpuOnly;
        vo.deviceNameFilter = device;
        vo.boundedShadowLaunch = boundedShadowLaunch;
        vo.shadowMemoryBudget = shadowMemoryMiB << 20;
        vo.maxPassRays = passRays;
        vo.pipelineStatistics = pipelineStatistics;
        vo.shadowSlotTimes = shadowSlotTimes;
        vo.tracing = backend == "sdf" ? VulkanTracing::DistanceField : VulkanTracing::RayPipelines;
        vo.sdfVoxels = sdfVoxels;
        vo.ldmOcclusion = ldmOcclusion;
        TracerOptions options;
        options.shadowRouletteShare = roulette;
        auto gpu = VulkanTracer::create(*scene, options, vo);
        if (!gpu) {
          std::fprintf(stderr, "gpu-trace: %s\n", gpu.error().message.c_str());
          return 1;
        }
        std::unique_ptr<EmbreeTracer> cpu;
        if (!skipEmbree) {
          auto e = EmbreeTracer::create(*scene, options);
          if (!e) {
            std::fprintf(stderr, "gpu-trace: %s\n", e.error().message.c_str());
            return 1;
          }
          cpu = std::move(e).value();
        }

        // ---- the same bake on both backends, then the fields compared ----
        Field fg = Field::create(volumes, settings);
        Field fc = Field::create(volumes, settings);
        BakeOptions bake;
        bake.updates = setup.updates;
        if (singleBounce) bake.shading = kShadeNoIndirect;
        auto failed = [](const Error& e) {
          std::fprintf(stderr, "gpu-trace: %s\n", e.message.c_str());
          return 1;
        };
        auto gpuBaked = bakeField(fg, **gpu, bake);
        if (!gpuBaked) return failed(gpuBaked.error());
        const BakeStats gpuBake = *gpuBaked;
        BakeStats cpuBake;
        if (cpu) {
          auto cpuBaked = bakeField(fc, *cpu, bake);
          if (!cpuBaked) return failed(cpuBaked.error());
          cpuBake = *cpuBaked;
        }

        // ---- speed: raw ceiling and full updates on the same rays ----
        UpdateRequest request;
        request.probes = allProbes(fg);
        request.shading = bake.shading;
        const std::uint64_t probeRaysPerUpdate = std::uint64_t(request.probes.size()) * rays;
        double rawMs = 0, gpuMs = 0, wallMs = 0, embreeMs = 0, embreeRawMs = 0;
        std::uint64_t shadowRays = 0, embreeShadowRays = 0, readback = 0;
        std::vector<std::string> passOrder;
        std::map<std::string, double> passMs;
        // The GPU's updates run back to back after about a second of trace-only launches
        // (which leave the field as it is): a GPU left idle (here, while Embree worked
        // between updates) drops its clocks, and on an H100 that slowed every pass about
        // 5x. Embree's updates run after the GPU's.
        {
          const auto start = std::chrono::steady_clock::now();
          for (int i = 0; std::chrono::steady_clock::now() - start < std::chrono::seconds(1); ++i) {
            request.rotationSeed = 900000u + std::uint32_t(i);
            auto traced = (*gpu)->traceOnly(fg, request);
            if (!traced) return failed(traced.error());
          }
        }
        for (int i = 0; i < updates; ++i) {
          request.rotationSeed = 100000u + std::uint32_t(i);
          auto traced = (*gpu)->traceOnly(fg, request);
          if (!traced) return failed(traced.error());
          rawMs += *traced;
          auto updated = (*gpu)->update(fg, request);
          if (!updated) return failed(updated.error());
          const UpdateStats& s = *updated;
          gpuMs += s.gpuMs;
          wallMs += s.totalMs;
          shadowRays += s.shadowRays;
          readback += s.readbackBytes;
          for (const auto& [name, ms] : s.gpuPasses) {
            if (!passMs.count(name)) passOrder.push_back(name);
            passMs[name] += ms;
          }
        }
        for (int i = 0; cpu && i < updates; ++i) {
          request.rotationSeed = 100000u + std::uint32_t(i);
          embreeRawMs += cpu->traceOnly(fc, request, nullptr);
          auto updated = cpu->update(fc, request);
          if (!updated) return failed(updated.error());
          const UpdateStats& e = *updated;
          embreeMs += e.totalMs;
          embreeShadowRays += e.shadowRays;
        }
        const std::uint64_t probeRays = probeRaysPerUpdate * std::uint64_t(updates);
        // End to end as the DDGI papers and the issue count it: trace, shade and blend (with
        // the acceleration-structure refit and the shadow rays). The whole update adds
        // packing the changed bricks for the host and the copies back.
        double traceShadeBlendMs = 0;
        for (const char* pass : {"tlas", "sdf cells", "sdf bricks", "trace", "shade",
                                 "shadow trace", "shadow rounds", "blend"})
          if (passMs.count(pass)) traceShadeBlendMs += passMs[pass];
        const double raw = grays(probeRays, rawMs);
        const double probe = grays(probeRays, traceShadeBlendMs);
        const double all = grays(probeRays + shadowRays, traceShadeBlendMs);
        const double whole = grays(probeRays, gpuMs);

        std::printf(
            "gpu-trace: %s (%zu triangles), %d probes x %d rays, %d measured updates after %d\n",
            scene->name.c_str(), scene->triangleCount(), int(request.probes.size()), rays, updates,
            setup.updates);
        std::printf("device: %s, backend %s\n", (*gpu)->context().deviceName().c_str(),
                    (*gpu)->name().c_str());
        if (vo.tracing == VulkanTracing::DistanceField) {
          // The field was built once, before the bake; a moved instance builds it again at
          // the same cost.
          const SdfBuildStats& b = (*gpu)->sdfBuildStats();
          std::printf(
              "distance field: %d triangles, %d cells, %d bricks, voxel %.4g m, %.1f MiB, build "
              "%.2f ms GPU (cells %.2f, bricks %.2f)\n",
              b.triangles, b.cells, b.bricks, b.voxel, double(b.bytes) / double(1 << 20), b.gpuMs,
              b.cellsMs, b.bricksMs);
          figure("sdf_build_ms", b.gpuMs, "ms");
        }
        std::printf("host: %s\n", machineDescription().c_str());
        std::printf("%-36s %12s\n", "GPU pass (timestamps)", "ms/update");
        for (const std::string& name : passOrder)
          std::printf("%-36s %12.3f\n", name.c_str(), passMs[name] / updates);
        std::printf("%-36s %12.3f\n", "update, GPU passes", gpuMs / updates);
        std::printf("%-36s %12.3f\n", "update, wall clock (submit..unpack)", wallMs / updates);
        std::printf("%-36s %12.3f\n", "raw closest hit (trace pass alone)", rawMs / updates);
        std::printf("%-36s %12.1f\n", "readback KiB/update", double(readback) / 1024.0 / updates);
        std::printf("%-36s %12s %14s\n", "rate", "Grays/s", "rays/update");
        std::printf("%-36s %12.4f %14llu\n", "raw probe rays", raw,
                    (unsigned long long)probeRaysPerUpdate);
        std::printf("%-36s %12.4f %14llu\n", "probe rays, trace+shade+blend", probe,
                    (unsigned long long)probeRaysPerUpdate);
        std::printf("%-36s %12.4f %14llu\n", "all rays incl. shadow, same passes", all,
                    (unsigned long long)((probeRays + shadowRays) / updates));
        std::printf("%-36s %12.4f\n", "probe rays, whole update (GPU)", whole);
        std::printf("%-36s %12.4f\n", "probe rays, wall clock", grays(probeRays, wallMs));
        if (cpu) {
          std::printf("%-36s %12.4f %14s (%.2f ms/update)\n", "Embree raw probe rays",
                      grays(probeRays, embreeRawMs), "", embreeRawMs / updates);
          std::printf("%-36s %12.4f %14s (%.2f ms/update)\n", "Embree probe rays, full update",
                      grays(probeRays, embreeMs), "", embreeMs / updates);
          std::printf("%-36s %12.4f\n", "Embree all rays, full update",
                      grays(probeRays + embreeShadowRays, embreeMs));
        }
        std::printf("bake of %d updates: %s %.1f s, embree %.1f s\n", setup.updates,
                    backend.c_str(), gpuBake.ms / 1e3, cpuBake.ms / 1e3);

        if (cpu) {
          const FieldDifference d = compareFields(fg, fc);
          std::printf(
              "fields after identical updates: %d probes active in both, %d state mismatches\n",
              d.probes, d.stateMismatches);
          if (worst > 0) {
            std::printf(
                "probes apart, GPU | Embree: the %d largest irradiance differences, "
                "the %d largest depth differences, then the state mismatches\n"
                "(irradiance and depth: tile means; differences: summed over the tile)\n",
                worst, worst);
            for (const ProbeDifference& p : largestProbeDifferences(fg, fc, worst))
              std::printf(
                  "  cascade %d slot %d: state %d | %d, at (%.3f %.3f %.3f) | (%.3f %.3f %.3f), "
                  "irradiance %.4g | %.4g, depth %.4g | %.4g, differences %.3g, %.3g\n",
                  p.cascade, p.slot, p.stateA, p.stateB, p.positionA.x, p.positionA.y,
                  p.positionA.z, p.positionB.x, p.positionB.y, p.positionB.z, p.irradianceA,
                  p.irradianceB, p.depthA, p.depthB, p.irradianceError, p.depthError);
          }
          figure("field_rel_diff_irradiance", d.irradiance, "ratio");
          figure("field_rel_diff_depth", d.depth, "ratio");
        }
        if (cpu && !skipQuality) {
          auto camera = sceneCamera(*scene, setup.camera);
          if (!camera) {
            std::fprintf(stderr, "gpu-trace: %s\n", camera.error().message.c_str());
            return 1;
          }
          auto reference = cachedReference(*scene, *camera, setup);
          if (!reference) {
            std::fprintf(stderr, "gpu-trace: %s\n", reference.error().message.c_str());
            return 1;
          }
          // The two fields compared alike, without the contact occlusion, as its figures in
          // docs/BENCHMARKS.md were measured.
          ProbeLitOptions lit = probeLitOptions(setup, *camera);
          lit.aoRadius = 0.0f;
          const Image8 ref8 = tonemap(reference->image, scene->exposure);
          double psnr[2] = {0, 0};
          const Field* fields[2] = {&fg, &fc};
          for (int i = 0; i < 2; ++i) {
            auto image = renderProbeLit(*scene, *fields[i], lit);
            if (!image) {
              std::fprintf(stderr, "gpu-trace: %s\n", image.error().message.c_str());
              return 1;
            }
            psnr[i] = psnr8(tonemap(*image, scene->exposure), ref8);
          }
          std::printf(
              "probe-lit vs reference: GPU field %.2f dB, Embree field %.2f dB (reference noise "
              "%.1f dB)\n",
              psnr[0], psnr[1], reference->noisePsnr);
          figure("psnr_gpu_minus_cpu", psnr[0] - psnr[1], "dB");
        }
        figure("raw_grays", raw, "Grays/s");
        figure("probe_grays", probe, "Grays/s");
        figure("all_grays", all, "Grays/s");
        figure("update_grays", whole, "Grays/s");
        figure("raw_fraction", raw > 0 ? probe / raw : 0.0, "ratio");
        if (cpu) figure("embree_probe_grays", grays(probeRays, embreeMs), "Grays/s");
        return 0;
      }};
}

}  // namespace pc::bench
