// client: the client renderer's quality and speed. Quality at the render setup's size: the
// client's image against the CPU probe-lit render of the same baked field and camera, and
// against the path-traced reference; the stereo left eye against a mono render of the same
// pose. Speed at --speed-width x --speed-height (1920x1080): GPU time per frame and per pass
// from timestamp queries, median over the measured frames. The field is sampled in the
// lighting pass (compute), together with the direct light and the surface rebuild:
// probe_pass_ms is that pass's time minus its time with the field switched off (ambient),
// lighting_pass_ms the whole pass.
#include <algorithm>
#include <chrono>
#include <filesystem>

#include "bench.h"
#include "bench_common.h"
#include "client/camera.h"
#include "client/renderer.h"
#include "cpu/path_tracer.h"
#include "cpu/probe_lit_render.h"

namespace pc::bench {

namespace {

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

}  // namespace

Benchmark addClient(CLI::App& app) {
  auto* cmd = app.add_subcommand("client", "client renderer: PSNR vs CPU and reference, GPU ms");
  static std::string scenePath = "builtin", sidecar, outDir;
  static RenderSetup setup;
  static int speedWidth = 1920, speedHeight = 1080, frames = 5, areaLights = 16;
  static bool validation = false, speedOnly = false, noPrepass = false, stereo = false;
  static std::string raster = "auto";
  static int cascades = 0;
  static double dt = 0.0;
  static int msaa = 4;
  static float fovea = 0.5f;
  cmd->add_option("--scene", scenePath, "scene file, or 'builtin'");
  cmd->add_option("--sidecar", sidecar, "scene.json sidecar");
  addSceneLoadOptions(*cmd, sceneLoadOptions());
  cmd->add_option("--out", outDir, "write the images here");
  cmd->add_option("--speed-width", speedWidth, "width of the timed frames");
  cmd->add_option("--speed-height", speedHeight, "height of the timed frames");
  cmd->add_option("--frames", frames,
                  "timed frames (after a warm-up of 1 s or 100 frames, whichever comes first)");
  cmd->add_option("--fovea", fovea,
                  "also time foveated field sampling with this radius (the client's --fovea) and "
                  "compare its image with full-rate sampling; 0: not measured")
      ->capture_default_str();
  cmd->add_flag("--stereo", stereo,
                "time stereo frames instead (both eyes in one multiview pass) at --width x "
                "--height per eye, 2064x2208 (a current headset's panel) unless given; skips "
                "the quality comparisons");
  cmd->add_option("--cascades", cascades,
                  "cascades: the scene's first volume and coarser ones around it (0: the scene's)");
  cmd->add_option("--area-lights", areaLights, "virtual point lights standing in for emitters");
  cmd->add_flag("--validation", validation, "Vulkan validation layer on");
  cmd->add_flag("--speed-only", speedOnly, "skip the quality comparisons (no CPU renders)");
  cmd->add_option("--dt", dt,
                  "animation seconds between timed frames (0: a still scene, shadow maps cached)");
  cmd->add_flag("--no-prepass", noPrepass, "main pass without the depth pre-pass");
  cmd->add_option("--raster", raster, "visibility buffer: auto, fixed or compute");
  cmd->add_option("--msaa", msaa, "main pass samples per pixel (2, 4, 8)");
  addRenderOptions(*cmd, setup);
  return {
      cmd, [cmd] {
        namespace fs = std::filesystem;
        if (stereo) speedOnly = true;
        auto scene = loadBenchScene(scenePath, sidecar);
        if (!scene) {
          std::printf("client: %s\n", scene.error().message.c_str());
          return 1;
        }
        auto camera = sceneCamera(*scene, setup.camera);
        if (!camera) {
          std::printf("client: %s\n", camera.error().message.c_str());
          return 1;
        }
        vk::ContextOptions co;
        co.validation = validation;
        co.allowCpuDevice = true;
        co.multiview = true;
        auto ctx = vk::Context::create(co);
        if (!ctx) {
          std::printf("client: no usable Vulkan device: %s\n", ctx.error().message.c_str());
          return 2;
        }
        double bakeSeconds = 0;
        auto field = bakeSceneField(*scene, setup.updates, &bakeSeconds, cascades);
        if (!field) {
          std::printf("client: %s\n", field.error().message.c_str());
          return 1;
        }
        client::FieldMirror mirror;
        mirror.reset(*field, 0.0);
        client::RendererOptions ro;
        ro.shadows.areaLights = areaLights;
        ro.msaa = msaa;
        ro.aoRadius = setup.aoRadius;
        ro.depthPrepass = !noPrepass;
        if (auto r = client::parseRasterizer(raster)) {
          ro.rasterizer = *r;
        } else {
          std::printf("client: --raster: expected auto, fixed or compute\n");
          return 1;
        }
        double vsCpu = 0, vsRef = 0, cpuVsRef = 0, stereoDb = 0;
        int areaLightCount = 0;
        client::FrameInput input;
        input.cameras[0] = *camera;
        const float ipd = 0.064f;  // m between the eyes
        if (!speedOnly) {
          // ---- quality ----
          ro.width = setup.width;
          ro.height = setup.height;
          auto small = client::Renderer::create(**ctx, *scene, mirror, ro);
          if (!small) {
            std::printf("client: renderer: %s\n", small.error().message.c_str());
            return 1;
          }
          auto mono = (*small)->renderOffscreen(input);
          areaLightCount = (*small)->areaLightCount();
          small->reset();
          ro.views = 2;
          client::FrameInput stereoInput;
          stereoInput.cameras[0] = *camera;
          stereoInput.cameras[1] = client::offsetCamera(*camera, ipd);
          auto stereoRenderer = client::Renderer::create(**ctx, *scene, mirror, ro);
          if (!stereoRenderer) {
            std::printf("client: renderer: %s\n", stereoRenderer.error().message.c_str());
            return 1;
          }
          auto stereo = (*stereoRenderer)->renderOffscreen(stereoInput);
          stereoRenderer->reset();
          if (!mono || !stereo) {
            std::printf("client: frame failed: %s\n",
                        (!mono ? mono : stereo).error().message.c_str());
            return 1;
          }
          ProbeLitOptions lit;
          lit.width = setup.width;
          lit.height = setup.height;
          lit.primarySamples = std::max(setup.primarySamples, 8);
          lit.emissiveSamples = setup.emissiveSamples;
          lit.explicitCamera = *camera;
          lit.aoRadius = setup.aoRadius;
          auto cpu = renderProbeLit(*scene, *field, lit);
          auto reference = cachedReference(*scene, *camera, setup);
          if (!cpu || !reference) {
            std::printf("client: %s\n", (!cpu ? cpu.error() : reference.error()).message.c_str());
            return 1;
          }
          const Image8 cpu8 = tonemap(*cpu, scene->exposure);
          const Image8 ref8 = tonemap(reference->image, scene->exposure);
          vsCpu = psnr8(mono->display[0], cpu8);
          vsRef = psnr8(mono->display[0], ref8);
          cpuVsRef = psnr8(cpu8, ref8);
          stereoDb = psnr8(stereo->display[0], mono->display[0]);
          if (!outDir.empty()) {
            fs::create_directories(outDir);
            writePng(fs::path(outDir) / "client.png", mono->display[0]);
            writePng(fs::path(outDir) / "cpu_probe_lit.png", cpu8);
            writePng(fs::path(outDir) / "reference.png", ref8);
            writePng(fs::path(outDir) / "diff_client_cpu.png",
                     differenceImage(mono->display[0], cpu8));
            writePng(fs::path(outDir) / "stereo_right.png", stereo->display[1]);
          }
        }  // quality

        // ---- speed ----
        ro.views = 1;
        ro.width = speedWidth;
        ro.height = speedHeight;
        if (stereo) {
          // Per eye: the headset's panel unless --width/--height say otherwise.
          ro.width = cmd->get_option("--width")->count() > 0 ? setup.width : 2064;
          ro.height = cmd->get_option("--height")->count() > 0 ? setup.height : 2208;
          speedWidth = ro.width;
          speedHeight = ro.height;
        }
        struct Timed {
          std::vector<double> frameMs, probeMs, shadowMs, mainMs, uploadMs, tonemapMs, redrawn;
          client::FrameStats stats;
          client::Rasterizer rasterizer = client::Rasterizer::Auto;
          int areaLights = 0;
          double wallMsPerFrame = 0;
          int warmupFrames = 0;
        };
        // Frames are pipelined (no wait, no readback), as in a window: a GPU left idle between
        // frames lowers its clocks and inflates every timing. A frame's timings arrive when
        // its slot comes round again, client::kFrameSlots frames later.
        // Warm-up before the clock starts: 1 s or 100 frames, whichever comes first (and at
        // least until the first frame's timings are back), so that the GPU's clocks have risen
        // and the caches and uploads are done.
        auto timeFrames = [&](const client::RendererOptions& options,
                              client::FrameInput frameInput) -> Result<Timed> {
          auto big = client::Renderer::create(**ctx, *scene, mirror, options);
          if (!big) return Error{"renderer: " + big.error().message};
          Timed out;
          out.areaLights = (*big)->areaLightCount();
          out.rasterizer = (*big)->options().rasterizer;
          using Clock = std::chrono::steady_clock;
          const auto warmStart = Clock::now();
          int warmFrames = 0;
          for (;; ++warmFrames) {
            const bool enough =
                warmFrames >= 2 + client::kFrameSlots &&
                (warmFrames >= 100 || Clock::now() - warmStart >= std::chrono::seconds(1));
            if (enough) break;
            frameInput.time = warmFrames * dt;
            if (Status r = (*big)->renderFrame(frameInput); !r)
              return Error{"frame failed: " + r.error().message};
          }
          out.warmupFrames = warmFrames;
          const auto wallStart = Clock::now();
          const int timedFrames = frames + client::kFrameSlots;
          for (int f = 0; f < timedFrames; ++f) {
            frameInput.time = (warmFrames + f) * dt;
            Status r = (*big)->renderFrame(frameInput);
            out.stats = (*big)->lastStats();
            if (!r) return Error{"frame failed: " + r.error().message};
            const client::FrameTimings& t = (*big)->lastTimings();
            // A frame's timings come back kFrameSlots frames later: the first ones are the
            // warm-up's.
            if (f < client::kFrameSlots || !t.valid) continue;
            out.frameMs.push_back(t.frameMs());
            out.probeMs.push_back(t.probeMs);
            out.shadowMs.push_back(t.shadowMs);
            out.mainMs.push_back(t.mainMs);
            out.uploadMs.push_back(t.uploadMs);
            out.tonemapMs.push_back(t.tonemapMs);
            out.redrawn.push_back(out.stats.shadowViewsDrawn);
          }
          (*big)->waitIdle();
          out.wallMsPerFrame = std::chrono::duration<double, std::milli>(
                                   std::chrono::steady_clock::now() - wallStart)
                                   .count() /
                               timedFrames;
          return out;
        };
        client::FrameInput timedInput = input;
        if (stereo) {
          ro.views = 2;
          timedInput.cameras[1] = client::offsetCamera(*camera, ipd);
        }
        auto timed = timeFrames(ro, timedInput);
        if (!timed) {
          std::printf("client: %s\n", timed.error().message.c_str());
          return 1;
        }
        // The probe sampling runs inside the lighting pass (with direct light and the surface
        // rebuild); its cost is the lighting pass's time with the field minus without it.
        client::RendererOptions noField = ro;
        noField.sampleField = false;
        auto timedNoField = timeFrames(noField, timedInput);
        if (!timedNoField) {
          std::printf("client: %s\n", timedNoField.error().message.c_str());
          return 1;
        }
        // Stereo: one eye alone at the same size, for what rendering both in one pass saves.
        Result<Timed> timedMonoEye = Error{"not measured"};
        if (stereo) {
          client::RendererOptions mono = ro;
          mono.views = 1;
          timedMonoEye = timeFrames(mono, input);
          if (!timedMonoEye) {
            std::printf("client: %s\n", timedMonoEye.error().message.c_str());
            return 1;
          }
        }
        // Foveated field sampling against full rate: the same frames timed, and one image of
        // each (tone-mapped, the first view) compared.
        Result<Timed> timedFovea = Error{"not measured"};
        double foveaDb = 0;
        if (fovea > 0.0f) {
          client::RendererOptions foveated = ro;
          foveated.foveaRadius = fovea;
          timedFovea = timeFrames(foveated, timedInput);
          if (!timedFovea) {
            std::printf("client: %s\n", timedFovea.error().message.c_str());
            return 1;
          }
          Image8 images[2];
          for (int k = 0; k < 2; ++k) {
            auto r = client::Renderer::create(**ctx, *scene, mirror, k == 0 ? ro : foveated);
            if (!r) {
              std::printf("client: renderer: %s\n", r.error().message.c_str());
              return 1;
            }
            auto frame = (*r)->renderOffscreen(timedInput);
            if (!frame) {
              std::printf("client: frame failed: %s\n", frame.error().message.c_str());
              return 1;
            }
            images[k] = frame->display[0];
          }
          foveaDb = psnr8(images[1], images[0]);
        }
        const std::vector<double>& frameMs = timed->frameMs;
        const std::vector<double>& probeMs = timed->probeMs;
        const std::vector<double>& shadowMs = timed->shadowMs;
        const std::vector<double>& mainMs = timed->mainMs;
        const std::vector<double>& uploadMs = timed->uploadMs;
        const std::vector<double>& tonemapMs = timed->tonemapMs;
        const std::vector<double>& redrawn = timed->redrawn;
        const client::FrameStats& stats = timed->stats;
        areaLightCount = timed->areaLights;
        const double samplingMs = median(probeMs) - median(timedNoField->probeMs);

        std::printf("device: %s\nmachine: %s\n", (*ctx)->deviceName().c_str(),
                    machineDescription().c_str());
        std::printf("scene %s, %d cascade(s), %d probes, %d emitter lights (area-light VPLs)\n",
                    sceneSlug(*scene).c_str(), field->cascadeCount(), field->probeCount(),
                    areaLightCount);
        if (!speedOnly) {
          std::printf(
              "%-34s %10s\n",
              ("quality (" + std::to_string(setup.width) + "x" + std::to_string(setup.height) + ")")
                  .c_str(),
              "PSNR dB");
          std::printf("%-34s %10.2f\n", "client vs CPU probe-lit", vsCpu);
          std::printf("%-34s %10.2f\n", "client vs path-traced reference", vsRef);
          std::printf("%-34s %10.2f\n", "CPU probe-lit vs reference", cpuVsRef);
          std::printf("%-34s %10.2f\n", "stereo left eye vs mono", stereoDb);
        }
        std::printf("%-34s %10s\n",
                    ("GPU ms at " + std::to_string(speedWidth) + "x" + std::to_string(speedHeight) +
                     (stereo ? " per eye, both eyes" : "") + " (median of " +
                     std::to_string(frameMs.size()) + " after " +
                     std::to_string(timed->warmupFrames) + " warm-up)")
                        .c_str(),
                    "ms");
        std::printf("%-34s %10.3f\n", "frame", median(frameMs));
        std::printf("%-34s %10.3f\n", "  shadow maps", median(shadowMs));
        std::printf("%-34s %10.3f\n", "  main pass (visibility buffer)", median(mainMs));
        std::printf("%-34s %10.3f\n", "  lighting pass (direct + field)", median(probeMs));
        std::printf("%-34s %10.3f\n", "    without the field (ambient)",
                    median(timedNoField->probeMs));
        std::printf("%-34s %10.3f\n", "    probe sampling (difference)", samplingMs);
        std::printf("%-34s %10.3f\n", "  field uploads", median(uploadMs));
        std::printf("%-34s %10.3f\n", "  tone mapping", median(tonemapMs));
        std::printf("%-34s %10.3f\n", "wall clock per frame (CPU + GPU)", timed->wallMsPerFrame);
        std::printf("%-34s %10s\n", "rasterizer", client::rasterizerName(timed->rasterizer));
        const double foveaSamplingMs =
            fovea > 0.0f ? median(timedFovea->probeMs) - median(timedNoField->probeMs) : 0.0;
        if (fovea > 0.0f) {
          char label[64];
          std::snprintf(label, sizeof label, "frame, fovea %.2g", double(fovea));
          std::printf("%-34s %10.3f\n", label, median(timedFovea->frameMs));
          std::printf("%-34s %10.3f\n", "  its probe sampling", foveaSamplingMs);
          std::printf("%-34s %10.2f\n", "  its image vs full rate, dB", foveaDb);
        }
        if (stereo) {
          std::printf("%-34s %10.3f\n", "stereo frame, per eye", median(frameMs) / 2);
          std::printf("%-34s %10.3f\n", "one eye alone (mono, same size)",
                      median(timedMonoEye->frameMs));
          std::printf("%-34s %10.3f\n", "  its lighting pass", median(timedMonoEye->probeMs));
        }
        std::printf(
            "per frame (%s): %d draw calls, %llu triangles (all passes), %d lights per "
            "fragment, %d shadow layers (%g redrawn, median), %dx MSAA\n",
            dt > 0 ? "animated" : "still", stats.drawCalls, (unsigned long long)stats.triangles,
            stats.lights, stats.shadowViews, median(redrawn), stats.msaa);
        if ((*ctx)->validationErrorCount() > 0)
          std::printf("validation errors: %u\n", (*ctx)->validationErrorCount());
        if (!speedOnly) {
          figure("psnr_client_vs_reference", vsRef, "dB");
          figure("psnr_client_vs_cpu", vsCpu, "dB");
          figure("psnr_stereo_left_vs_mono", stereoDb, "dB");
        }
        if (fovea > 0.0f) {
          figure(stereo ? "stereo_frame_ms_fovea" : "frame_ms_fovea", median(timedFovea->frameMs),
                 "ms");
          figure(stereo ? "stereo_probe_pass_ms_fovea" : "probe_pass_ms_fovea", foveaSamplingMs,
                 "ms");
          figure("psnr_fovea_vs_full", foveaDb, "dB");
        }
        if (stereo) {
          // The figures of a stereo frame: both eyes, every pass.
          figure("stereo_frame_ms", median(frameMs), "ms");
          figure("stereo_eye_ms", median(frameMs) / 2, "ms");
          figure("stereo_probe_pass_ms", samplingMs, "ms");
          figure("stereo_lighting_pass_ms", median(probeMs), "ms");
          // Below 2: one multiview pass costs less than two mono frames.
          figure("stereo_vs_mono_eye", median(frameMs) / median(timedMonoEye->frameMs), "ratio");
          return 0;
        }
        figure("frame_ms", median(frameMs), "ms");
        figure("probe_pass_ms", samplingMs, "ms");
        figure("lighting_pass_ms", median(probeMs), "ms");
        return 0;
      }};
}

}  // namespace pc::bench
