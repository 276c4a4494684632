// probecast-reference: renders the ground-truth image of a scene with the CPU path tracer.
// Writes reference.exr (linear; reference.pfm with --pfm) and reference.png (tone-mapped with
// the scene's exposure) and reports the image's own noise, estimated from two independent
// half-sample renders, so measured errors of other renderers can be set against it.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>
#include <string>

#include "common/image.h"
#include "common/log.h"
#include "common/scene.h"
#include "cpu/path_tracer.h"
#include "tools/command_line.h"

namespace {

int fail(const std::string& message) {
  std::fprintf(stderr, "probecast-reference: error: %s\n", message.c_str());
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Render a scene's reference image with the CPU path tracer (Embree)."};
  std::string scenePath, sidecarPath, outDir = ".";
  pc::PathTraceOptions options;
  options.width = 640;
  options.height = 360;
  options.spp = 1024;
  bool pfm = false;
  app.add_option("--scene", scenePath, "glTF or OBJ scene (default: the built-in scene)");
  app.add_option("--sidecar", sidecarPath, "scene.json with lights, cameras and animation");
  app.add_option("--camera", options.camera, "camera index")->check(CLI::NonNegativeNumber);
  app.add_option("--width", options.width, "image width")->check(CLI::Range(1, 16384));
  app.add_option("--height", options.height, "image height")->check(CLI::Range(1, 16384));
  app.add_option("--spp", options.spp, "samples per pixel")->check(CLI::PositiveNumber);
  app.add_option("--time", options.time, "animation time in seconds")->check(pc::kFinite);
  app.add_option("--seed", options.seed, "random seed (same seed, same image)");
  app.add_option("--bounces", options.maxBounces, "maximum indirect bounces")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--out", outDir, "output folder");
  app.add_flag("--pfm", pfm, "write reference.pfm instead of reference.exr");
  pc::SceneLoadOptions sceneLoad;
  pc::addSceneLoadOptions(app, sceneLoad);
  if (auto code = pc::parseCommandLine(app, argc, argv)) return *code;

  pc::Scene scene;
  if (scenePath.empty()) {
    scene = pc::builtinScene();
  } else {
    auto loaded = pc::loadScene(scenePath, sidecarPath, sceneLoad);
    if (!loaded) return fail(loaded.error().message);
    scene = std::move(loaded.value());
  }
  pc::logInfo(pc::sidecarReport(scene));
  for (const std::string& warning : scene.warnings) pc::logWarn(warning);

  std::error_code ec;
  std::filesystem::create_directories(outDir, ec);
  if (ec) return fail("cannot create " + outDir + ": " + ec.message());

  pc::Result<pc::PathTraceResult> result = pc::Error{};
  {
    pc::Progress progress("reference",
                          std::uint64_t(pc::pathTraceTileCount(options.width, options.height)));
    result = pc::renderReference(scene, options, &progress);
  }
  if (!result) return fail(result.error().message);

  const std::filesystem::path dir(outDir);
  const std::filesystem::path linearPath = dir / (pfm ? "reference.pfm" : "reference.exr");
  const pc::Status written =
      pfm ? pc::writePfm(linearPath, result->image) : pc::writeExr(linearPath, result->image);
  if (!written) return fail(written.error().message);
  const std::filesystem::path pngPath = dir / "reference.png";
  const pc::Status png = pc::writePng(pngPath, result->image, scene.exposure);
  if (!png) return fail(png.error().message);

  std::printf("scene        %s\n", scene.name.c_str());
  std::printf("image        %d x %d, %d spp (%llu paths)\n", options.width, options.height,
              result->spp, static_cast<unsigned long long>(result->samples));
  std::printf("time         %.2f s\n", result->seconds);
  std::printf("halves PSNR  %.2f dB (two independent renders of half the samples)\n",
              result->halvesPsnr);
  std::printf("noise PSNR   %.2f dB (estimated, full image vs noise-free; halves + 6.02 dB)\n",
              result->noisePsnr);
  std::printf("wrote        %s, %s\n", linearPath.string().c_str(), pngPath.string().c_str());
  return 0;
}
