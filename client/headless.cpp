// Headless front end: no window system at all; every frame is read back and written.
#include <cstdio>
#include <filesystem>

#include "camera.h"
#include "client_app.h"
#include "client_setup.h"
#include "common/image.h"
#include "common/log.h"
#include "renderer.h"

namespace pc::client {

int runHeadless(const ClientConfig& config) {
  auto scene = loadClientScene(config);
  if (!scene) {
    logError(scene.error().message);
    return 1;
  }
  auto camera = clientCamera(*scene, config);
  if (!camera) {
    logError(camera.error().message);
    return 1;
  }
  FieldMirror mirror;
  if (!loadFallbackField(*scene, config, mirror)) return 1;  // logged
  auto ctx = createClientContext(config, {});
  if (!ctx) {
    logError(ctx.error().message);
    return 2;
  }
  logInfo("Vulkan device: " + (*ctx)->deviceName());

  RendererOptions ro;
  ro.width = config.width;
  ro.height = config.height;
  ro.views = config.stereo ? 2 : 1;
  ro.msaa = config.msaa;
  ro.rasterizer = config.rasterizer;
  ro.textureMipmaps = config.textureMipmaps;
  ro.shadows = config.shadows;
  ro.sampleFlags = config.sampleFlags;
  ro.aoRadius = config.aoRadius;
  ro.foveaRadius = config.foveaRadius;
  auto renderer = Renderer::create(**ctx, *scene, mirror, ro);
  if (!renderer) {
    logError("renderer: " + renderer.error().message);
    return 1;
  }
  std::error_code ec;
  std::filesystem::create_directories(config.outDir, ec);

  int status = 0;
  for (int frame = 0; frame < std::max(1, config.frames); ++frame) {
    FrameInput input;
    input.probeView = config.probeView;
    input.time = config.startTime + frame * std::max(0.0, config.dt);
    if (config.stereo) {
      input.cameras[0] = offsetCamera(*camera, -0.5f * config.ipd);
      input.cameras[1] = offsetCamera(*camera, 0.5f * config.ipd);
    } else {
      input.cameras[0] = *camera;
    }
    auto images = (*renderer)->renderOffscreen(input);
    if (!images) {
      logError("frame " + std::to_string(frame) + ": " + images.error().message);
      return 1;
    }
    for (std::size_t v = 0; v < images->display.size(); ++v) {
      char name[256];
      const char* eye = config.stereo ? (v == 0 ? "_left" : "_right") : "";
      std::snprintf(name, sizeof name, "%s_%04d%s", config.prefix.c_str(), frame, eye);
      const std::filesystem::path base = std::filesystem::path(config.outDir) / name;
      Status png = writePng(base.string() + ".png", images->display[v]);
      Status exr =
          config.writeExr ? writeExr(base.string() + ".exr", images->linear[v]) : Status::success();
      if (!png || !exr) {
        logError((png ? exr : png).error().message);
        status = 1;
      }
    }
    const FrameTimings& t = (*renderer)->lastTimings();
    if (t.valid) {
      char line[160];
      std::snprintf(line, sizeof line,
                    "frame %d: GPU %.2f ms (probe pass %.2f ms, shadows %.2f ms)", frame,
                    t.frameMs(), t.probeMs, t.shadowMs);
      logInfo(line);
    }
  }
  (*renderer).reset();
  if ((*ctx)->validationErrorCount() > 0) {
    logError("validation errors: " + std::to_string((*ctx)->validationErrorCount()));
    return 3;
  }
  return status;
}

}  // namespace pc::client
