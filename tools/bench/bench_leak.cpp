// leak: light leaking through walls. On a scene with a sealed room (rtxgi-two-rooms: sun
// only, the closed room has no opening), the mean radiance the closed room's camera sees,
// relative to the open room's, with the field's visibility weighting and without it (the
// naive trilinear baseline). A sealed room should stay dark: direct light cannot reach it and
// neither should indirect light.
#include <algorithm>
#include <cctype>
#include <filesystem>

#include "bench.h"
#include "bench_common.h"
#include "cpu/path_tracer.h"
#include "cpu/probe_lit_render.h"

namespace pc::bench {

namespace {

int findCamera(const Scene& scene, const std::string& word) {
  for (std::size_t i = 0; i < scene.cameras.size(); ++i) {
    std::string name = scene.cameras[i].name;
    std::transform(name.begin(), name.end(), name.begin(),
                   [](unsigned char c) { return std::tolower(c); });
    if (name.find(word) != std::string::npos) return int(i);
  }
  return -1;
}

double meanLuminance(const Image& image) {
  double sum = 0;
  for (const glm::vec3& p : image.pixels) sum += 0.2126 * p.x + 0.7152 * p.y + 0.0722 * p.z;
  return image.pixels.empty() ? 0.0 : sum / double(image.pixels.size());
}

}  // namespace

Benchmark addLeak(CLI::App& app) {
  auto* cmd = app.add_subcommand("leak", "sealed-room light leak: closed vs open room radiance");
  static std::string scenePath = std::string(PC_SCENES_DIR) + "/rtxgi-two-rooms/two-rooms.glb",
                     sidecar, outDir;
  static int closedCamera = -1, openCamera = -1;
  static RenderSetup setup;
  cmd->add_option("--scene", scenePath, "scene with a sealed room");
  cmd->add_option("--sidecar", sidecar, "scene.json sidecar");
  addSceneLoadOptions(*cmd, sceneLoadOptions());
  cmd->add_option("--closed-camera", closedCamera,
                  "camera inside the sealed room (default: name has 'closed')");
  cmd->add_option("--open-camera", openCamera,
                  "camera inside the open room (default: name has 'open')");
  cmd->add_option("--out", outDir, "write the images here");
  addRenderOptions(*cmd, setup);
  addBakeBackendOption(*cmd, setup);
  return {
      cmd, [] {
        if (!std::filesystem::exists(scenePath)) {
          std::printf("leak: scene %s is absent: nothing to measure\n", scenePath.c_str());
          return 0;
        }
        auto scene = loadBenchScene(scenePath, sidecar);
        if (!scene) {
          std::fprintf(stderr, "leak: %s\n", scene.error().message.c_str());
          return 1;
        }
        int closed = closedCamera >= 0 ? closedCamera : findCamera(*scene, "closed");
        int open = openCamera >= 0 ? openCamera : findCamera(*scene, "open");
        if (closed < 0 || open < 0 || closed >= int(scene->cameras.size()) ||
            open >= int(scene->cameras.size())) {
          std::fprintf(stderr,
                       "leak: the scene needs a closed-room and an open-room camera "
                       "(--closed-camera, --open-camera)\n");
          return 1;
        }
        double bakeSeconds = 0;
        auto field = bakeSceneField(*scene, setup.updates, &bakeSeconds, 0, false, std::nullopt,
                                    setup.backend);
        if (!field) {
          std::fprintf(stderr, "leak: %s\n", field.error().message.c_str());
          return 1;
        }
        double mean[2][2];  // [visibility on/off][closed/open]
        for (int naive = 0; naive < 2; ++naive) {
          for (int which = 0; which < 2; ++which) {
            ProbeLitOptions lit;
            lit.width = setup.width;
            lit.height = setup.height;
            lit.primarySamples = setup.primarySamples;
            lit.camera = which == 0 ? closed : open;
            lit.sampleFlags = naive ? gpu::PC_SAMPLE_NO_VISIBILITY : gpu::PC_SAMPLE_DEFAULT;
            auto image = renderProbeLit(*scene, *field, lit);
            if (!image) {
              std::fprintf(stderr, "leak: %s\n", image.error().message.c_str());
              return 1;
            }
            mean[naive][which] = meanLuminance(*image);
            if (!outDir.empty()) {
              std::filesystem::create_directories(outDir);
              std::string name =
                  std::string(which == 0 ? "closed" : "open") + (naive ? "_naive" : "") + ".png";
              writePng(std::filesystem::path(outDir) / name, *image, scene->exposure);
            }
          }
        }
        const double ratio = mean[0][0] / std::max(mean[0][1], 1e-30);
        const double naiveRatio = mean[1][0] / std::max(mean[1][1], 1e-30);
        std::printf(
            "leak: %s, %d probes, bake %.1f s (%s), cameras '%s' (closed) and '%s' (open)\n",
            scene->name.c_str(), field->probeCount(), bakeSeconds, setup.backend.c_str(),
            scene->cameras[closed].name.c_str(), scene->cameras[open].name.c_str());
        std::printf("%-24s %16s %16s %12s\n", "sampling", "closed mean L", "open mean L", "ratio");
        std::printf("%-24s %16.6g %16.6g %11.4f%%\n", "visibility-weighted", mean[0][0], mean[0][1],
                    100 * ratio);
        std::printf("%-24s %16.6g %16.6g %11.4f%%\n", "naive trilinear", mean[1][0], mean[1][1],
                    100 * naiveRatio);
        figure("leak_ratio", ratio, "ratio");
        figure("leak_ratio_naive", naiveRatio, "ratio");
        return 0;
      }};
}

}  // namespace pc::bench
