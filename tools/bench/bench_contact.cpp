// contact: contact darkening at a concave edge. A block on a floor (common/scene_contact.h),
// rendered probe-lit without and with the screen-space ambient occlusion of the indirect
// light (shaders/interop/screen_ao.h) and path traced; the error against the reference in a
// band along the line where the block meets the floor, in 8-bit levels of the tone-mapped
// image, and the PSNR of the whole image.
#include <filesystem>

#include "bench.h"
#include "bench_common.h"
#include "common/scene_contact.h"
#include "cpu/camera.h"
#include "cpu/contact_band.h"
#include "cpu/probe_lit_render.h"
#include "cpu/render_setup.h"

namespace pc::bench {

namespace fs = std::filesystem;

Benchmark addContact(CLI::App& app) {
  auto* cmd = app.add_subcommand("contact", "contact darkening: error along a block's contact");
  static std::string outDir;
  static float band = 0.15f;
  static RenderSetup setup;
  cmd->add_option("--band", band, "half-width of the band along the contact, world units")
      ->capture_default_str();
  cmd->add_option("--out", outDir, "write the images here");
  addRenderOptions(*cmd, setup);
  return {cmd, [] {
            const Scene scene = contactScene();
            std::printf("machine: %s\n", machineDescription().c_str());
            auto camera = sceneCamera(scene, 0);
            if (!camera) return 1;
            auto field = bakeSceneField(scene, setup.updates);
            if (!field) {
              std::printf("contact: bake failed: %s\n", field.error().message.c_str());
              return 1;
            }
            auto reference = cachedReference(scene, *camera, setup);
            if (!reference) {
              std::printf("contact: reference failed: %s\n", reference.error().message.c_str());
              return 1;
            }
            auto cpu = prepareCpuRender(scene, setup.width, setup.height, *camera, 0, 0.0);
            if (!cpu) return 1;
            const PinholeCamera pinhole(*camera, setup.width, setup.height);
            const std::vector<bool> mask =
                contactBandMask(traceViewSurfaces(*cpu->embree, pinhole, setup.width, setup.height),
                                contactSceneEdges(), band);
            const Image8 ref = tonemap(reference->image, scene.exposure);
            std::printf("%-10s %10s %12s %8s %8s\n", "ao radius", "band |err|", "band signed",
                        "pixels", "PSNR dB");
            for (float radius : {0.0f, setup.aoRadius}) {
              ProbeLitOptions lit = probeLitOptions(setup, *camera);
              lit.aoRadius = radius;
              auto image =
                  renderProbeLit(*cpu->embree, cpu->state, cpu->emissive, *field, *camera, lit);
              const Image8 img = tonemap(image, scene.exposure);
              const BandError e = bandError(img, ref, mask);
              const double psnr = psnr8(img, ref);
              std::printf("%-10.2f %10.2f %12.2f %8d %8.2f\n", radius, e.meanAbs, e.meanSigned,
                          e.pixels, psnr);
              const std::string tag = radius > 0.0f ? "ao_on" : "ao_off";
              figure("contact_band_error_" + tag, e.meanAbs, "levels");
              figure("contact_band_bias_" + tag, e.meanSigned, "levels");
              figure("contact_psnr_" + tag, psnr, "dB");
              if (!outDir.empty()) {
                std::error_code ec;
                fs::create_directories(outDir, ec);
                writePng(fs::path(outDir) / ("probe_lit_" + tag + ".png"), img);
                writePng(fs::path(outDir) / ("diff_" + tag + ".png"), differenceImage(img, ref));
              }
            }
            if (!outDir.empty()) writePng(fs::path(outDir) / "reference.png", ref);
            return 0;
          }};
}

}  // namespace pc::bench
