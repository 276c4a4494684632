// probecast-bake: converges a scene's probe field (on the CPU with Embree, or with --backend on
// a GPU: ray-tracing pipelines or the SDF tracer's compute passes) and writes it as a baked .probes
// file. With --render DIR it also renders the scene's camera lit by that field and path traced, and
// writes both images, their difference and a summary (timings, PSNR).
#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "common/image.h"
#include "common/log.h"
#include "common/output_path.h"
#include "common/temp_file.h"
#include "common/volume_placement.h"
#include "cpu/path_tracer.h"
#include "cpu/probe_lit_render.h"
#include "protocol/baked_file.h"
#include "server/bake.h"
#include "server/tracer.h"
#include "server/vulkan_tracer.h"
#include "tools/command_line.h"

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

static double secondsSince(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

int main(int argc, char** argv) {
  CLI::App app{"Bake a probe field (and optionally check it against the path-traced reference)"};
  std::string scenePath = "builtin", sidecar, out = "field.probes", renderDir, backend = "embree";
  int updates = 96, rays = 256, width = 480, height = 360, spp = 512, camera = 0, aa = 4;
  double time = 0.0;
  bool half = false, autoVolumes = false;
  app.add_option("--scene", scenePath, "glTF/OBJ scene, or 'builtin' (a Cornell-style room)");
  app.add_option("--sidecar", sidecar, "scene.json sidecar (lights, cameras, volumes)");
  app.add_option("--backend", backend,
                 "tracer: embree (default), vulkan (any Vulkan ray-tracing device, lavapipe "
                 "included), sdf (a distance field traced in compute on any Vulkan device) or "
                 "auto (a GPU with ray tracing, else a GPU for sdf, else embree)")
      ->capture_default_str();
  int gpuFailSubmission = 0;
  app.add_option("--gpu-fail-submission", gpuFailSubmission,
                 "failure drill: the GPU tracer's N-th submission fails as a lost device would "
                 "(0: never)")
      ->check(CLI::Range(0, 1 << 30));
  pc::VulkanTracerOptions vulkan;
  app.add_flag("--ldm-occlusion", vulkan.ldmOcclusion,
               "vulkan and sdf backends: the occlusion tiles from layered depth maps (rasterized "
               "in compute) instead of the probe rays (docs/LDM.md)");
  app.add_option("--ldm-directions", vulkan.ldm.directions,
                 "--ldm-occlusion: LDMs, each traced both ways")
      ->check(CLI::Range(1, pc::gpu::PC_LDM_MAX_DIRECTIONS))
      ->capture_default_str();
  app.add_option("--ldm-resolution", vulkan.ldm.resolution,
                 "--ldm-occlusion: pixels a side of each LDM")
      ->check(CLI::Range(8, 2048))
      ->capture_default_str();
  app.add_option("--updates", updates, "field updates")->check(CLI::Range(1, 1000000));
  std::string encoding;
  app.add_option("--encoding", encoding,
                 "every volume's irradiance encoding, overriding the sidecar's: octahedral, sh1 "
                 "or sh2 (SH needs the embree backend)")
      ->check(CLI::IsMember({"octahedral", "sh1", "sh2"}));
  app.add_option("--rays", rays, "rays per probe per update")
      ->check(CLI::Range(pc::kMinRaysPerProbe, pc::kMaxRaysPerProbe));
  app.add_option("--time", time, "animation time of the baked state (seconds)")->check(pc::kFinite);
  // Files are -o/--output and folders --out in every tool; --out named this file before.
  app.add_option("-o,--output", out, "output .probes file");
  app.add_option("--out", out, "deprecated: -o/--output FILE")->group("Deprecated");
  app.add_flag("--half", half, "store irradiance and occlusion as float16");
  app.add_flag("--auto-volumes", autoVolumes,
               "place the cascades from the geometry even where the sidecar names volumes");
  app.add_option("--render", renderDir, "also render probe-lit and path-traced images here");
  app.add_option("--width", width, "image width (--render)")->check(CLI::Range(1, 16384));
  app.add_option("--height", height, "image height (--render)")->check(CLI::Range(1, 16384));
  app.add_option("--spp", spp, "reference paths per pixel (--render)")
      ->check(CLI::Range(1, 1 << 20));
  app.add_option("--camera", camera, "camera index (--render)")->check(CLI::NonNegativeNumber);
  app.add_option("--aa", aa, "primary samples per pixel of the probe-lit render (--render)")
      ->check(CLI::Range(1, 4096));
  float aoRadius = pc::gpu::PC_AO_DEFAULT_RADIUS;
  app.add_option("--ao-radius", aoRadius,
                 "ambient occlusion of the probe-lit render's indirect light (GTAO): radius in "
                 "probe spacings, 0 off (--render)")
      ->check(pc::kFinite & CLI::NonNegativeNumber);
  pc::SceneLoadOptions sceneLoad;
  pc::addSceneLoadOptions(app, sceneLoad);
  if (auto code = pc::parseCommandLine(app, argc, argv)) return *code;
  // A signal during the bake ends it as before; during the write it also removes the
  // temporary file, so that no <out>.tmp.<pid> is left behind.
  pc::installTempFileCleanup();

  pc::Result<pc::Scene> scene = scenePath == "builtin"
                                    ? pc::Result<pc::Scene>(pc::builtinScene())
                                    : pc::loadScene(scenePath, sidecar, sceneLoad);
  if (!scene) {
    pc::logError(scene.error().message);
    return 1;
  }
  pc::logInfo(pc::sidecarReport(*scene));
  for (const std::string& w : scene->warnings) pc::logWarn(w);
  // The outputs and the render's camera are checked before the bake, not after it.
  if (pc::Status s = pc::prepareOutputFile(out); !s) {
    pc::logError(s.error().message + "; nothing baked");
    return 1;
  }
  if (!renderDir.empty()) {
    if (pc::Status s = pc::prepareOutputDir(renderDir); !s) {
      pc::logError(s.error().message + "; nothing baked");
      return 1;
    }
    if (auto cam = pc::sceneCamera(*scene, camera); !cam) {
      pc::logError(cam.error().message);
      return 1;
    }
  }

  pc::FieldSettings settings;
  settings.raysPerProbe = rays;
  // Volumes from the sidecar (checked against the geometry), else placed from the geometry.
  std::vector<pc::ProbeVolume> volumes = pc::sceneVolumes(*scene, autoVolumes);
  if (!encoding.empty()) {
    for (pc::ProbeVolume& v : volumes) v.settings.encoding = pc::parseProbeEncoding(encoding);
  }
  pc::Field field = pc::Field::create(volumes, settings);
  field.sceneHash = scene->hash;
  vulkan.failSubmission = gpuFailSubmission;
  auto tracer = pc::makeTracer(*scene, backend, {}, &vulkan);
  if (!tracer) {
    pc::logError("tracer: " + tracer.error().message);
    return 1;
  }
  pc::logInfo("tracer: " + (*tracer)->name());

  nlohmann::json summary;
  summary["scene"] = scene->name;
  summary["tracer"] = (*tracer)->name();
  summary["triangles"] = scene->triangleCount();
  summary["probes"] = field.probeCount();
  summary["cascades"] = field.cascadeCount();
  {
    pc::Progress progress("bake", std::uint64_t(updates));
    pc::BakeOptions options;
    options.updates = updates;
    options.progress = [&](int, int) {
      progress.advance();
      return true;
    };
    // Nothing written where the tracer fails: a bake stopped part way is no baked field.
    auto failed = [](const pc::Error& e) {
      pc::logError("bake failed: " + e.message +
                   "; nothing written (--backend embree bakes on the CPU)");
      return 1;
    };
    if (pc::Status s = (*tracer)->setState(pc::evaluateScene(*scene, time)); !s)
      return failed(s.error());
    auto baked = pc::bakeField(field, **tracer, options);
    if (!baked) return failed(baked.error());
    const pc::BakeStats& stats = *baked;
    const double mrays = double(stats.probeRays + stats.shadowRays) / (stats.ms * 1e3);
    summary["bake"] = {{"updates", stats.updates},
                       {"seconds", stats.ms / 1000.0},
                       {"probe_rays", stats.probeRays},
                       {"shadow_rays", stats.shadowRays},
                       {"mrays_per_s", mrays}};
    std::printf(
        "baked %d probes in %d cascades: %d updates, %.2f s, %.2f Mrays/s (probe + shadow rays)\n",
        field.probeCount(), field.cascadeCount(), stats.updates, stats.ms / 1000.0, mrays);
  }
  pc::BakedWriteOptions writeOptions;
  writeOptions.halfPrecision = half;
  if (pc::Status s = pc::writeBakedField(out, field, writeOptions); !s) {
    pc::logError(s.error().message);
    return 1;
  }
  summary["file"] = {{"path", out}, {"bytes", fs::file_size(out)}};
  std::printf("wrote %s (%ju bytes)\n", out.c_str(), std::uintmax_t(fs::file_size(out)));
  if (renderDir.empty()) return 0;

  // ---- check: probe-lit render vs path-traced reference ----
  auto cam = pc::sceneCamera(*scene, camera);
  if (!cam) {
    pc::logError(cam.error().message);
    return 1;
  }
  // Render from the file just written, as a client would.
  auto loaded = pc::readBakedField(out, scene->hash);
  if (!loaded) {
    pc::logError(loaded.error().message);
    return 1;
  }
  pc::ProbeLitOptions lit;
  lit.width = width, lit.height = height, lit.primarySamples = aa, lit.explicitCamera = *cam,
  lit.time = time, lit.aoRadius = aoRadius;
  auto t0 = Clock::now();
  pc::Image probeLit;
  {
    pc::Progress progress("probe-lit render", std::uint64_t(pc::probeLitProgressTotal(lit)));
    auto image = pc::renderProbeLit(*scene, *loaded, lit, &progress);
    if (!image) {
      pc::logError(image.error().message);
      return 1;
    }
    probeLit = std::move(image).value();
  }
  const double litSeconds = secondsSince(t0);
  pc::PathTraceOptions pt;
  pt.width = width, pt.height = height, pt.spp = spp, pt.explicitCamera = *cam, pt.time = time;
  pc::PathTraceResult reference;
  {
    pc::Progress progress("reference", std::uint64_t(pc::pathTraceTileCount(width, height)));
    auto r = pc::renderReference(*scene, pt, &progress);
    if (!r) {
      pc::logError(r.error().message);
      return 1;
    }
    reference = std::move(r).value();
  }
  pc::Image8 a = pc::tonemap(probeLit, scene->exposure),
             b = pc::tonemap(reference.image, scene->exposure);
  const double psnr = pc::psnr8(a, b), ssim = pc::ssim8(a, b),
               psnrLin = pc::psnrLinear(probeLit, reference.image);
  const fs::path dir(renderDir);
  for (pc::Status s :
       {pc::writePng(dir / "probe_lit.png", a), pc::writePng(dir / "reference.png", b),
        pc::writeExr(dir / "probe_lit.exr", probeLit),
        pc::writeExr(dir / "reference.exr", reference.image),
        pc::writePng(dir / "difference.png", pc::differenceImage(a, b))}) {
    if (!s) pc::logError(s.error().message);
  }
  summary["render"] = {{"width", width}, {"height", height}, {"camera", cam->name}};
  summary["probe_lit"] = {{"seconds", litSeconds}, {"primary_samples", aa}};
  summary["reference"] = {{"seconds", reference.seconds},
                          {"spp", reference.spp},
                          {"own_noise_psnr_db", reference.noisePsnr}};
  summary["psnr_probe_vs_reference_db"] = psnr;
  summary["ssim_probe_vs_reference"] = ssim;
  summary["psnr_linear_db"] = psnrLin;
  std::ofstream(dir / "summary.json") << summary.dump(2) << "\n";
  std::ofstream txt(dir / "summary.txt");
  char text[1024];
  std::snprintf(text, sizeof text,
                "scene            %s (%zu triangles)\n"
                "field            %d probes, %d cascades, baked in %.2f s\n"
                "probe-lit render %dx%d, %.2f s\n"
                "reference        %d spp, %.2f s, own noise ~%.1f dB PSNR\n"
                "PSNR             %.2f dB (8-bit sRGB, tone-mapped)   linear %.2f dB   SSIM %.4f\n",
                scene->name.c_str(), scene->triangleCount(), field.probeCount(),
                field.cascadeCount(), summary["bake"]["seconds"].get<double>(), width, height,
                litSeconds, reference.spp, reference.seconds, reference.noisePsnr, psnr, psnrLin,
                ssim);
  txt << text;
  std::printf("%s", text);
  std::printf("images and summary in %s\n", renderDir.c_str());
  return 0;
}
