// quality: the probe-lit render (direct light + indirect from a baked field) against the
// path-traced reference of the same camera, as PSNR on tone-mapped 8-bit sRGB (and linear
// PSNR and SSIM). With --all, every scene under the shared scenes folder that has lights.
#include <filesystem>

#include "bench.h"
#include "bench_common.h"

namespace pc::bench {

namespace fs = std::filesystem;

Benchmark addQuality(CLI::App& app) {
  auto* cmd = app.add_subcommand("quality", "probe-lit render vs path-traced reference (PSNR)");
  static std::string scenePath = "builtin", sidecar, outDir;
  static bool all = false;
  static RenderSetup setup;
  cmd->add_option("--scene", scenePath, "scene file, or 'builtin'");
  cmd->add_option("--sidecar", sidecar, "scene.json sidecar");
  cmd->add_flag("--all", all, "every scene with lights under the shared scenes folder");
  cmd->add_option("--out", outDir, "write the images here");
  addRenderOptions(*cmd, setup);
  return {cmd, [] {
            std::vector<std::string> scenes;
            if (all) {
              scenes = sharedSceneFiles();
              if (scenes.empty()) {
                std::printf("quality: no shared scenes folder at %s: nothing to measure\n",
                            PC_SCENES_DIR);
                return 0;
              }
            } else {
              scenes = {scenePath};
            }
            std::printf("machine: %s\n", machineDescription().c_str());
            std::printf("%-28s %8s %8s %9s %8s %10s %10s %9s\n", "scene", "PSNR dB", "SSIM",
                        "linear dB", "ref noise", "bake s", "ref s", "probes");
            int failures = 0;
            for (const std::string& path : scenes) {
              auto scene = loadBenchScene(path, all ? std::string() : sidecar);
              if (!scene) {
                std::printf("%-28s error: %s\n", fs::path(path).filename().c_str(),
                            scene.error().message.c_str());
                ++failures;
                continue;
              }
              // A lit sky lights a scene as well as lights do (the white furnace has nothing else).
              if (!scene->hasLights() && scene->sky.isBlack()) {
                std::printf("%-28s skipped: no lights and a black sky\n", scene->name.c_str());
                continue;
              }
              auto r = compareWithReference(
                  *scene, setup,
                  outDir.empty() ? std::string() : (fs::path(outDir) / sceneSlug(*scene)).string());
              if (!r) {
                std::printf("%-28s error: %s\n", scene->name.c_str(), r.error().message.c_str());
                ++failures;
                continue;
              }
              std::printf("%-28s %8.2f %8.4f %9.2f %8.1f %10.1f %10.1f %9d\n",
                          sceneSlug(*scene).c_str(), r->psnr, r->ssim, r->psnrLinear,
                          r->referenceNoisePsnr, r->bakeSeconds, r->referenceSeconds, r->probes);
              if (!all)
                figure("psnr_probe_vs_reference", r->psnr, "dB");
              else
                figure("psnr_probe_vs_reference." + sceneSlug(*scene), r->psnr, "dB");
            }
            std::printf(
                "(ref noise: expected PSNR of the reference against its own noise-free limit, from "
                "two\n"
                " half-sample renders; it must sit well above the measured PSNR for the figure to "
                "hold)\n");
            return failures ? 1 : 0;
          }};
}

}  // namespace pc::bench
