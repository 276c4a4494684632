// quality: the probe-lit render (direct light + indirect from a baked field) and the client's
// render of the same field against the path-traced reference of the same camera, as PSNR on
// tone-mapped 8-bit sRGB, SSIM and LDR-FLIP. --all takes every scene under the shared scenes
// folder that has lights, --scenes DIR every scene file in a folder; both write one table
// (quality.md, quality.json) and an image grid (grid.png) into --out. A scene that fails to load
// or render is reported by name and the others are still measured.
#include <cmath>
#include <ctime>
#include <filesystem>
#include <memory>
#include <set>

#include "bench.h"
#include "bench_common.h"
#include "client/renderer.h"
#include "common/image_flip.h"
#include "quality_report.h"

namespace pc::bench {

namespace fs = std::filesystem;

namespace {

struct QualityOptions {
  std::string scenePath = "builtin", sidecar, outDir, scenesDir;
  bool all = false, noClient = false;
  bool singleSunMap = false;  // the client's sun with one map over the whole scene
  // The client renders at this many times the size on each axis (with its 4x MSAA) and is
  // box-filtered down in linear light: 16 samples at a geometric edge, as the probe-lit
  // render's 16 primary samples; at 1 it is measured as drawn.
  int clientSupersample = 2;
  double pixelsPerDegree = kFlipDefaultPixelsPerDegree;
  RenderSetup setup;
};

Scores score(const Image8& test, const Image8& reference, double ppd) {
  return {psnr8(test, reference), ssim8(test, reference), flip(test, reference, ppd).mean};
}

// The client renderer's image of `field`, or why there is none. One Vulkan context serves every
// scene; where none can be made the client columns say so and the CPU figures still come.
class ClientRenders {
 public:
  ClientRenders(bool enabled, bool sunCascades) : sunCascades_(sunCascades) {
    if (!enabled) {
      note_ = "--no-client";
      return;
    }
    vk::ContextOptions co;
    co.allowCpuDevice = true;
    auto ctx = vk::Context::create(co);
    if (!ctx) {
      note_ = "no Vulkan device";
      std::printf("quality: no client renders: %s\n", ctx.error().message.c_str());
      return;
    }
    ctx_ = std::move(ctx).value();
  }
  const std::string& note() const { return note_; }
  Result<Image8> render(const Scene& scene, const Field& field, const Camera& camera,
                        const RenderSetup& setup, int supersample) {
    if (!ctx_) return Error{note_};
    client::FieldMirror mirror;
    mirror.reset(field, 0.0);
    client::RendererOptions ro;
    ro.width = setup.width * supersample;
    ro.height = setup.height * supersample;
    ro.aoRadius = setup.aoRadius;  // the probe-lit render applies the same occlusion
    ro.shadows.sunCascades = sunCascades_;
    auto renderer = client::Renderer::create(*ctx_, scene, mirror, ro);
    if (!renderer) return Error{"client renderer: " + renderer.error().message};
    client::FrameInput input;
    input.cameras[0] = camera;
    auto frame = (*renderer)->renderOffscreen(input);
    if (!frame) return Error{"client frame: " + frame.error().message};
    if (supersample == 1) return std::move(frame->display[0]);
    return tonemap(boxDownsample(frame->linear[0], supersample), scene.exposure);
  }

 private:
  std::unique_ptr<vk::Context> ctx_;
  std::string note_;
  bool sunCascades_ = true;
};

std::string today() {
  const std::time_t now = std::time(nullptr);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%d", std::gmtime(&now));
  return buf;
}

// The command line this run stands for, for the report.
std::string commandLine(const QualityOptions& o) {
  std::string c = "probecast-bench quality";
  if (o.all) c += " --all";
  if (!o.scenesDir.empty()) c += " --scenes " + o.scenesDir;
  if (!o.all && o.scenesDir.empty()) c += " --scene " + o.scenePath;
  c += " --width " + std::to_string(o.setup.width) + " --height " + std::to_string(o.setup.height) +
       " --spp " + std::to_string(o.setup.spp) + " --updates " + std::to_string(o.setup.updates);
  if (o.setup.autoVolumes) c += " --auto-volumes";
  if (o.setup.backend != "embree") c += " --backend " + o.setup.backend;
  c += " --aa " + std::to_string(o.setup.primarySamples);
  if (o.setup.encoding) c += std::string(" --encoding ") + probeEncodingName(*o.setup.encoding);
  if (o.singleSunMap) c += " --single-sun-map";
  if (o.noClient)
    c += " --no-client";
  else
    c += " --client-supersample " + std::to_string(o.clientSupersample);
  return c;
}

// Measures one scene file into a row; any failure becomes the row's error.
QualityRow measure(const std::string& path, const QualityOptions& o, bool many,
                   ClientRenders& clients, std::set<std::string>& slugs, bool* skipped) {
  QualityRow row;
  row.file = path;
  row.scene = fs::path(path).stem().string();
  auto scene = loadBenchScene(path, many ? std::string() : o.sidecar);
  if (!scene) {
    row.error = scene.error().message;
    return row;
  }
  // Two files of one name (a model's .gltf and .glb) get their own rows and folders.
  row.scene = sceneSlug(*scene);
  for (int k = 2; !slugs.insert(row.scene).second; ++k)
    row.scene = sceneSlug(*scene) + "-" + std::to_string(k);
  // A lit sky lights a scene as well as lights do (the white furnace has nothing else).
  if (!scene->hasLights() && scene->sky.isBlack()) {
    *skipped = true;
    return row;
  }
  const std::string outDir =
      o.outDir.empty() ? std::string() : (fs::path(o.outDir) / row.scene).string();
  auto r = compareWithReference(*scene, o.setup, outDir);
  if (!r) {
    row.error = r.error().message;
    return row;
  }
  row.volumes = o.setup.autoVolumes || scene->volumes.empty() ? "auto" : "sidecar";
  row.probes = r->probes;
  row.cascades = r->field.cascadeCount();
  row.spacing = r->field.cascadeCount() ? r->field.cascade(0).spacing : 0.0f;
  row.bytesPerProbe = fieldBytesPerProbe(r->field, false);
  row.bytesPerProbeWithVisibility = fieldBytesPerProbe(r->field, true);
  row.referenceNoisePsnr = r->referenceNoisePsnr;
  row.bakeSeconds = r->bakeSeconds;
  row.referenceSeconds = r->referenceSeconds;
  row.reference = tonemap(r->reference, scene->exposure);
  row.probeLitImage = tonemap(r->probeLit, scene->exposure);
  row.probeLit = score(row.probeLitImage, row.reference, o.pixelsPerDegree);
  row.probeLit.psnrNoiseFree = psnrWithoutReferenceNoise(row.probeLit.psnr, r->referenceNoisePsnr);
  row.probeLitFlip = flipErrorImage(flip(row.probeLitImage, row.reference, o.pixelsPerDegree));
  auto camera = sceneCamera(*scene, o.setup.camera);
  auto client = camera ? clients.render(*scene, r->field, *camera, o.setup, o.clientSupersample)
                       : Result<Image8>(camera.error());
  if (client) {
    row.clientImage = std::move(client).value();
    row.client = score(row.clientImage, row.reference, o.pixelsPerDegree);
    row.client->psnrNoiseFree = psnrWithoutReferenceNoise(row.client->psnr, r->referenceNoisePsnr);
    row.clientFlip = flipErrorImage(flip(row.clientImage, row.reference, o.pixelsPerDegree));
  } else {
    row.clientNote = client.error().message;
  }
  if (!outDir.empty()) {
    writePng(fs::path(outDir) / "flip_probe_lit.png", row.probeLitFlip);
    if (row.client) {
      writePng(fs::path(outDir) / "client.png", row.clientImage);
      writePng(fs::path(outDir) / "flip_client.png", row.clientFlip);
    }
  }
  return row;
}

void printRow(const QualityRow& r) {
  if (!r.error.empty()) {
    std::printf("%-28s error: %s\n", r.scene.c_str(), r.error.c_str());
    return;
  }
  std::printf("%-28s %-7s %7d %7.3g %8.2f %7.2f %6.3f %6.4f", r.scene.c_str(), r.volumes.c_str(),
              r.probes, r.spacing, r.probeLit.psnr, r.probeLit.psnrNoiseFree, r.probeLit.ssim,
              r.probeLit.flip);
  if (r.client) {
    std::printf(" %8.2f %7.2f %6.3f %6.4f", r.client->psnr, r.client->psnrNoiseFree, r.client->ssim,
                r.client->flip);
  } else {
    std::printf(" %8s %7s %6s %6s", "n/a", "", "", "");
  }
  std::printf(" %8.1f %7.1f %7.1f\n", r.referenceNoisePsnr, r.bakeSeconds, r.referenceSeconds);
}

void printFigures(const QualityRow& r, bool many) {
  const std::string suffix = many ? "." + r.scene : std::string();
  figure("psnr_probe_vs_reference" + suffix, r.probeLit.psnr, "dB");
  if (std::isfinite(r.probeLit.psnrNoiseFree))
    figure("psnr_probe_vs_noise_free_reference_est" + suffix, r.probeLit.psnrNoiseFree, "dB");
  figure("ssim_probe_vs_reference" + suffix, r.probeLit.ssim, "ratio");
  figure("flip_probe_vs_reference" + suffix, r.probeLit.flip, "ratio");
  figure("bytes_per_probe" + suffix, r.bytesPerProbe, "bytes");
  figure("bytes_per_probe_with_visibility" + suffix, r.bytesPerProbeWithVisibility, "bytes");
  if (r.client) {
    figure("psnr_client_vs_reference" + suffix, r.client->psnr, "dB");
    if (std::isfinite(r.client->psnrNoiseFree))
      figure("psnr_client_vs_noise_free_reference_est" + suffix, r.client->psnrNoiseFree, "dB");
    figure("ssim_client_vs_reference" + suffix, r.client->ssim, "ratio");
    figure("flip_client_vs_reference" + suffix, r.client->flip, "ratio");
  }
}

int run(QualityOptions o) {
  std::vector<std::string> scenes;
  const bool many = o.all || !o.scenesDir.empty();
  if (o.all) {
    scenes = sharedSceneFiles();
    if (scenes.empty())
      std::printf("quality: no shared scenes folder at %s: nothing to measure there\n",
                  PC_SCENES_DIR);
  }
  if (!o.scenesDir.empty()) {
    auto files = sceneFilesIn(o.scenesDir);
    if (!files) {
      std::printf("quality: --scenes %s\n", files.error().message.c_str());
      return 1;
    }
    if (files->empty())
      std::printf("quality: no .gltf, .glb or .obj under %s\n", o.scenesDir.c_str());
    scenes.insert(scenes.end(), files->begin(), files->end());
  }
  if (!many) scenes = {o.scenePath};
  if (many && o.outDir.empty()) o.outDir = "out/quality";
  std::printf("machine: %s\n", machineDescription().c_str());
  std::printf("%-28s %-7s %7s %7s %8s %7s %6s %6s %8s %7s %6s %6s %8s %7s %7s\n", "scene",
              "volumes", "probes", "spacing", "lit dB", "nf est", "SSIM", "FLIP", "client",
              "nf est", "SSIM", "FLIP", "ref noise", "bake s", "ref s");
  ClientRenders clients(!o.noClient, !o.singleSunMap);
  std::vector<QualityRow> rows;
  std::set<std::string> slugs;
  int failures = 0;
  for (const std::string& path : scenes) {
    bool skipped = false;
    QualityRow row = measure(path, o, many, clients, slugs, &skipped);
    if (skipped) {
      std::printf("%-28s skipped: no lights and a black sky\n", row.scene.c_str());
      continue;
    }
    printRow(row);
    if (row.error.empty()) {
      printFigures(row, many);
    } else {
      ++failures;
    }
    // Images are only kept until the grid is written; rows are small otherwise.
    rows.push_back(std::move(row));
  }
  std::printf(
      "(ref noise: expected PSNR of the reference against its own noise-free limit, from two\n"
      " half-sample renders; it must sit well above the measured PSNR for the figure to hold.\n"
      " nf est: the PSNR expected against that noise-free limit, the reference's noise taken out\n"
      " of the measured error; '-' or nan where the measure is within 1 dB of the noise)\n");
  if (!o.outDir.empty()) {
    QualityRun info{commandLine(o), machineDescription(), today(),         o.setup.width,
                    o.setup.height, o.setup.spp,          o.setup.updates, o.pixelsPerDegree};
    if (Status s = writeQualityReport(o.outDir, info, rows); !s) {
      std::printf("quality: %s\n", s.error().message.c_str());
      return 1;
    }
    std::printf("report: %s/quality.md, quality.json, grid.png\n", o.outDir.c_str());
  }
  return failures ? 1 : 0;
}

}  // namespace

Benchmark addQuality(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "quality", "probe-lit and client renders vs path-traced reference (PSNR, SSIM, FLIP)");
  static QualityOptions o;
  cmd->add_option("--scene", o.scenePath, "scene file, or 'builtin'");
  cmd->add_option("--sidecar", o.sidecar, "scene.json sidecar (with --scene)");
  addSceneLoadOptions(*cmd, sceneLoadOptions());
  cmd->add_flag("--all", o.all, "every scene with lights under the shared scenes folder");
  cmd->add_option("--scenes", o.scenesDir,
                  "every .gltf/.glb/.obj under this folder (each with its sidecar, if any)");
  cmd->add_option("--out", o.outDir,
                  "write the images, quality.md/.json and grid.png here (--all or --scenes: "
                  "out/quality unless given)");
  cmd->add_flag("--auto-volumes", o.setup.autoVolumes,
                "place the cascades from the geometry even where a sidecar names volumes");
  cmd->add_flag("--no-client", o.noClient, "skip the client renders (no Vulkan)");
  cmd->add_flag("--single-sun-map", o.singleSunMap,
                "the client's sun shadowed by one map over the whole scene instead of cascades "
                "fitted to the view (to compare the two)");
  cmd->add_option("--client-supersample", o.clientSupersample,
                  "render the client at this many times the size per axis and box-filter it "
                  "down (1: as drawn)")
      ->check(CLI::Range(1, 4))
      ->capture_default_str();
  cmd->add_option("--ppd", o.pixelsPerDegree, "FLIP's observer: pixels per degree of view")
      ->check(CLI::PositiveNumber);
  addRenderOptions(*cmd, o.setup);
  addBakeBackendOption(*cmd, o.setup);
  cmd->add_option_function<std::string>(
         "--encoding",
         // IsMember below has checked the name already.
         [](const std::string& name) { o.setup.encoding = parseProbeEncoding(name); },
         "every cascade's irradiance encoding: octahedral, sh1 or sh2 (overrides the volumes')")
      ->check(CLI::IsMember({"octahedral", "sh1", "sh2"}));
  return {cmd, [] { return run(o); }};
}

}  // namespace pc::bench
