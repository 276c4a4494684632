// specular: the field's split-sum specular (shaders/interop/specular_probe.h) on glossy
// surfaces. McGuire's Cornell box with its floor a dielectric and both boxes metals
// (common/scene_glossy.h) at roughness 0.3, 0.6 and 1.0: the CPU probe-lit render and the
// client, each with and without the field's specular, against the path-traced reference
// (tone-mapped PSNR). psnr_specular_gain_db_rXX is the client's gain (with minus without; the
// probe-lit render's where there is no Vulkan device), psnr_specular_gain_cpu_db_rXX the
// probe-lit render's. specular_ms: the client's lighting pass at --speed-width x
// --speed-height with the specular minus without it (roughness 0.3), medians over the timed
// frames after warm-up frames.
#include <unistd.h>

#include <algorithm>
#include <filesystem>

#include "bench.h"
#include "bench_common.h"
#include "client/renderer.h"
#include "common/scene_glossy.h"
#include "cpu/probe_lit_render.h"

namespace pc::bench {

namespace {

namespace fs = std::filesystem;

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

// The lighting pass's median GPU ms over `frames` frames after warm-up (pipelined, no wait).
Result<double> lightingPassMs(vk::Context& ctx, const Scene& scene, client::FieldMirror& mirror,
                              const client::RendererOptions& options,
                              const client::FrameInput& input, int frames) {
  auto renderer = client::Renderer::create(ctx, scene, mirror, options);
  if (!renderer) return Error{"renderer: " + renderer.error().message};
  std::vector<double> ms;
  const int warmUp = 2 + client::kFrameSlots;
  for (int f = 0; f < warmUp + frames; ++f) {
    if (Status s = (*renderer)->renderFrame(input); !s) return s.error();
    const client::FrameTimings& t = (*renderer)->lastTimings();
    if (f >= warmUp && t.valid) ms.push_back(t.probeMs);
  }
  (*renderer)->waitIdle();
  return median(ms);
}

}  // namespace

Benchmark addSpecular(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "specular", "glossy Cornell box: PSNR with and without the field's split-sum specular");
  static std::string scenePath =
      std::string(PC_SCENES_DIR) + "/mcguire-cornellbox/CornellBox-Original.obj";
  static std::string sidecar = "data/sidecars/CornellBox-Original.json", outDir;
  static RenderSetup setup;
  static int speedWidth = 640, speedHeight = 360, frames = 5;
  static bool noClient = false;
  cmd->add_option("--scene", scenePath, "CornellBox-Original.obj")->capture_default_str();
  cmd->add_option("--sidecar", sidecar, "its sidecar, to which the glossy materials are added")
      ->capture_default_str();
  cmd->add_option("--out", outDir, "write the images and the variants' sidecars here");
  cmd->add_option("--speed-width", speedWidth, "width of the timed client frames");
  cmd->add_option("--speed-height", speedHeight, "height of the timed client frames");
  cmd->add_option("--frames", frames, "timed client frames (after warm-up frames)");
  cmd->add_flag("--no-client", noClient, "CPU probe-lit render only");
  addRenderOptions(*cmd, setup);
  return {
      cmd, [] {
        std::printf("machine: %s\n", machineDescription().c_str());
        const fs::path work =
            outDir.empty()
                ? fs::temp_directory_path() / ("probecast-specular-" + std::to_string(::getpid()))
                : fs::path(outDir);
        std::error_code ec;
        fs::create_directories(work, ec);
        std::unique_ptr<vk::Context> ctx;
        if (!noClient) {
          vk::ContextOptions co;
          co.allowCpuDevice = true;
          auto c = vk::Context::create(co);
          if (c)
            ctx = std::move(*c);
          else
            std::printf("specular: no Vulkan device (%s): CPU only\n", c.error().message.c_str());
        }
        if (ctx) std::printf("device: %s\n", ctx->deviceName().c_str());
        std::printf("%-9s %12s %12s %12s %12s %12s %12s %10s\n", "roughness", "cpu without",
                    "cpu with", "cpu gain", "client w/o", "client with", "client gain",
                    "ref noise");
        double specularMs = 0.0;
        bool timed = false;
        for (float roughness : {0.3f, 0.6f, 1.0f}) {
          char tag[8];
          std::snprintf(tag, sizeof tag, "r%02d", int(std::lround(roughness * 10.0f)));
          const fs::path variant = work / (std::string("glossy_") + tag + ".json");
          if (Status s = writeGlossyCornellSidecar(sidecar, roughness, variant); !s) {
            std::printf("specular: %s\n", s.error().message.c_str());
            return 1;
          }
          auto scene = loadBenchScene(scenePath, variant.string());
          if (!scene) {
            std::printf("specular: %s\n", scene.error().message.c_str());
            return 1;
          }
          auto camera = sceneCamera(*scene, setup.camera);
          auto field = camera ? bakeSceneField(*scene, setup.updates) : camera.error();
          auto reference = field ? cachedReference(*scene, *camera, setup) : field.error();
          if (!reference) {
            std::printf("specular: %s\n", reference.error().message.c_str());
            return 1;
          }
          const Image8 ref = tonemap(reference->image, scene->exposure);
          double cpuDb[2] = {0, 0}, clientDb[2] = {0, 0};
          for (int with = 0; with < 2; ++with) {
            ProbeLitOptions lit = probeLitOptions(setup, *camera);
            lit.indirectSpecular = with == 1;
            auto image = renderProbeLit(*scene, *field, lit);
            if (!image) {
              std::printf("specular: %s\n", image.error().message.c_str());
              return 1;
            }
            const Image8 img = tonemap(*image, scene->exposure);
            cpuDb[with] = psnr8(img, ref);
            const std::string name = std::string(tag) + (with ? "_with" : "_without");
            if (!outDir.empty()) writePng(work / ("probe_lit_" + name + ".png"), img);
            if (!ctx) continue;
            client::FieldMirror mirror;
            mirror.reset(*field, 0.0);
            client::RendererOptions ro;
            ro.width = setup.width;
            ro.height = setup.height;
            ro.aoRadius = setup.aoRadius;
            ro.indirectSpecular = with == 1;
            client::FrameInput input;
            input.cameras[0] = *camera;
            auto renderer = client::Renderer::create(*ctx, *scene, mirror, ro);
            auto frame = renderer ? (*renderer)->renderOffscreen(input) : renderer.error();
            if (!frame) {
              std::printf("specular: client: %s\n", frame.error().message.c_str());
              return 1;
            }
            clientDb[with] = psnr8(frame->display[0], ref);
            if (!outDir.empty()) writePng(work / ("client_" + name + ".png"), frame->display[0]);
          }
          if (!outDir.empty()) writePng(work / (std::string("reference_") + tag + ".png"), ref);
          std::printf("%-9.1f %12.2f %12.2f %12.2f %12.2f %12.2f %12.2f %10.2f\n", roughness,
                      cpuDb[0], cpuDb[1], cpuDb[1] - cpuDb[0], clientDb[0], clientDb[1],
                      clientDb[1] - clientDb[0], reference->noisePsnr);
          const std::string t(tag);
          figure("psnr_specular_gain_db_" + t,
                 ctx ? clientDb[1] - clientDb[0] : cpuDb[1] - cpuDb[0], "dB");
          figure("psnr_specular_gain_cpu_db_" + t, cpuDb[1] - cpuDb[0], "dB");
          figure("psnr_probe_vs_reference_specular_" + t, cpuDb[1], "dB");
          if (ctx) figure("psnr_client_vs_reference_specular_" + t, clientDb[1], "dB");
          if (ctx && !timed) {  // the pass's cost, on the roughest-to-see variant (0.3)
            client::FieldMirror mirror;
            mirror.reset(*field, 0.0);
            client::RendererOptions ro;
            ro.width = speedWidth;
            ro.height = speedHeight;
            ro.aoRadius = setup.aoRadius;
            client::FrameInput input;
            input.cameras[0] = *camera;
            auto with = lightingPassMs(*ctx, *scene, mirror, ro, input, frames);
            ro.indirectSpecular = false;
            auto without = lightingPassMs(*ctx, *scene, mirror, ro, input, frames);
            if (!with || !without) {
              std::printf("specular: %s\n", (!with ? with : without).error().message.c_str());
              return 1;
            }
            std::printf("lighting pass at %dx%d: %.3f ms with, %.3f ms without\n", speedWidth,
                        speedHeight, *with, *without);
            specularMs = *with - *without;
            timed = true;
          }
        }
        if (timed) figure("specular_ms", specularMs, "ms");
        if (outDir.empty()) fs::remove_all(work, ec);
        return 0;
      }};
}

}  // namespace pc::bench
