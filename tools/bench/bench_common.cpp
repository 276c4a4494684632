#include "bench_common.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "common/volume_placement.h"
#include "cpu/path_tracer.h"
#include "cpu/probe_lit_render.h"
#include "server/bake.h"
#include "server/embree_tracer.h"
#include "server/tracer.h"

namespace pc::bench {

namespace fs = std::filesystem;

void addRenderOptions(CLI::App& cmd, RenderSetup& s) {
  cmd.add_option("--width", s.width, "image width");
  cmd.add_option("--height", s.height, "image height");
  cmd.add_option("--spp", s.spp, "reference paths per pixel");
  cmd.add_option("--updates", s.updates, "field updates for the bake");
  cmd.add_option("--camera", s.camera, "camera index");
  cmd.add_option("--aa", s.primarySamples,
                 "primary samples per pixel of the probe-lit render (stratified)")
      ->capture_default_str();
  cmd.add_option("--ao-radius", s.aoRadius,
                 "ambient occlusion radius of the indirect light, in probe spacings (0: off)")
      ->capture_default_str();
  cmd.add_option("--cache", s.cacheDir, "folder for cached reference renders ('' to disable)");
}

void addBakeBackendOption(CLI::App& cmd, RenderSetup& s) {
  cmd.add_option("--backend", s.backend,
                 "tracer that bakes the field: embree, vulkan (ray tracing), sdf (distance field "
                 "in Vulkan compute) or auto")
      ->capture_default_str();
}

std::string sceneSlug(const Scene& scene) {
  std::string slug = scene.source.empty() ? scene.name : scene.source.stem().string();
  for (char& c : slug)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_') c = '-';
  return slug;
}

std::vector<std::string> sharedSceneFiles() {
  std::vector<std::string> files;
  const fs::path root = PC_SCENES_DIR;
  if (!fs::is_directory(root)) return files;
  std::vector<fs::path> dirs;
  for (const auto& e : fs::directory_iterator(root))
    if (e.is_directory()) dirs.push_back(e.path());
  std::sort(dirs.begin(), dirs.end());
  for (const fs::path& d : dirs) {
    std::vector<fs::path> candidates;
    for (const auto& e : fs::directory_iterator(d)) {
      std::string ext = e.path().extension().string();
      if (ext == ".glb" || ext == ".gltf" || ext == ".obj") candidates.push_back(e.path());
    }
    std::sort(candidates.begin(), candidates.end());
    for (const fs::path& c : candidates) {
      // Of the McGuire variants, the classic box is the one the figures name.
      if (d.filename() == "mcguire-cornellbox" && c.stem() != "CornellBox-Original") continue;
      files.push_back(c.string());
    }
  }
  return files;
}

Result<std::vector<std::string>> sceneFilesIn(const std::string& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return Error{dir + ": not a folder"};
  std::vector<std::string> files;
  fs::recursive_directory_iterator it(dir, fs::directory_options::skip_permission_denied, ec);
  if (ec) return Error{dir + ": cannot read: " + ec.message()};
  for (; it != fs::recursive_directory_iterator(); it.increment(ec)) {
    if (ec) return Error{dir + ": cannot read: " + ec.message()};
    if (it.depth() >= 3) it.disable_recursion_pending();
    std::string ext = it->path().extension().string();
    for (char& ch : ext) ch = char(std::tolower(static_cast<unsigned char>(ch)));
    if ((ext == ".glb" || ext == ".gltf" || ext == ".obj") && it->is_regular_file(ec))
      files.push_back(it->path().string());
  }
  std::sort(files.begin(), files.end());
  return files;
}

Result<Field> bakeSceneField(const Scene& scene, int updates, double* seconds, int cascades,
                             bool autoVolumes, std::optional<ProbeEncoding> encoding,
                             const std::string& backend) {
  std::vector<ProbeVolume> volumes = sceneVolumes(scene, autoVolumes);
  if (encoding) {
    for (ProbeVolume& v : volumes) v.settings.encoding = encoding;
  }
  if (cascades > 1) {
    const ProbeVolume base = volumes.front();
    const glm::vec3 centre = base.origin + 0.5f * base.spacing * glm::vec3(base.counts - 1);
    volumes = {base};
    for (int k = 1; k < cascades; ++k) {
      ProbeVolume v = base;
      v.spacing = base.spacing * float(1 << k);
      v.origin = centre - 0.5f * v.spacing * glm::vec3(v.counts - 1);
      volumes.push_back(v);
    }
  }
  Field field = Field::create(volumes, FieldSettings{});
  field.sceneHash = scene.hash;
  auto tracer = makeTracer(scene, backend);
  if (!tracer) return tracer.error();
  BakeOptions options;
  options.updates = updates;
  auto stats = bakeField(field, **tracer, options);
  if (!stats) return stats.error();
  if (seconds) *seconds = stats->ms / 1000.0;
  roundShToHalf(field);
  return field;
}

double fieldBytesPerProbe(const Field& field, bool withVisibility) {
  double bytes = 0;
  int probes = 0;
  for (int k = 0; k < field.cascadeCount(); ++k) {
    const glm::ivec3 n = field.cascade(k).counts;
    const int count = n.x * n.y * n.z;
    bytes += double(count) * irradianceBytesPerProbe(ProbeEncoding(field.encoding(k)));
    probes += count;
  }
  if (probes == 0) return 0;
  // Depth moments (2 values) and occlusion (1) per texel, at 16 bits, in every encoding.
  const int visibility = 2 * (2 * gpu::PC_DEPTH_TEXELS * gpu::PC_DEPTH_TEXELS +
                              gpu::PC_OCCLUSION_TEXELS * gpu::PC_OCCLUSION_TEXELS);
  return bytes / probes + (withVisibility ? visibility : 0);
}

// Bumped when the path tracer's output changes, so that no older cached image stands in for it
// (2: secondary rays leave from pcShadowOrigin, the lights evaluated at the hit point).
constexpr int kReferenceVersion = 2;

Result<Reference> cachedReference(const Scene& scene, const Camera& camera,
                                  const RenderSetup& setup) {
  char key[160];
  std::snprintf(key, sizeof key, "%016llx-%08x-%dx%d-%dspp-v%d", (unsigned long long)scene.hash,
                unsigned(std::hash<std::string>{}(
                    std::to_string(camera.position.x) + std::to_string(camera.position.y) +
                    std::to_string(camera.position.z) + std::to_string(camera.forward.x) +
                    std::to_string(camera.forward.y) + std::to_string(camera.forward.z) +
                    std::to_string(camera.yfov))),
                setup.width, setup.height, setup.spp, kReferenceVersion);
  fs::path exr, meta;
  if (!setup.cacheDir.empty()) {
    exr = fs::path(setup.cacheDir) / (std::string(key) + ".exr");
    meta = fs::path(setup.cacheDir) / (std::string(key) + ".txt");
    if (fs::exists(exr) && fs::exists(meta)) {
      auto image = readImage(exr);
      std::ifstream in(meta);
      Reference r;
      if (image && (in >> r.noisePsnr >> r.seconds)) {
        r.image = std::move(image).value();
        return r;
      }
    }
  }
  PathTraceOptions options;
  options.width = setup.width;
  options.height = setup.height;
  options.spp = setup.spp;
  options.explicitCamera = camera;
  Progress progress("reference " + sceneSlug(scene),
                    std::uint64_t(pathTraceTileCount(setup.width, setup.height)));
  auto result = renderReference(scene, options, &progress);
  if (!result) return result.error();
  Reference r{std::move(result->image), result->noisePsnr, result->seconds};
  if (!exr.empty()) {
    std::error_code ec;
    fs::create_directories(exr.parent_path(), ec);
    if (writeExr(exr, r.image)) {
      std::ofstream(meta) << r.noisePsnr << " " << r.seconds << "\n";
    }
  }
  return r;
}

ProbeLitOptions probeLitOptions(const RenderSetup& setup, const Camera& camera) {
  ProbeLitOptions lit;
  lit.width = setup.width;
  lit.height = setup.height;
  lit.primarySamples = setup.primarySamples;
  lit.emissiveSamples = setup.emissiveSamples;
  lit.explicitCamera = camera;
  lit.aoRadius = setup.aoRadius;
  return lit;
}

Result<Comparison> compareWithReference(const Scene& scene, const RenderSetup& setup,
                                        const std::string& outDir) {
  Comparison c;
  auto camera = sceneCamera(scene, setup.camera);
  if (!camera) return camera.error();
  auto field = bakeSceneField(scene, setup.updates, &c.bakeSeconds, 0, setup.autoVolumes,
                              setup.encoding, setup.backend);
  if (!field) return field.error();
  c.probes = field->probeCount();
  c.field = std::move(field).value();

  const ProbeLitOptions lit = probeLitOptions(setup, *camera);
  auto probeLit = renderProbeLit(scene, c.field, lit);
  if (!probeLit) return probeLit.error();
  c.probeLit = std::move(probeLit).value();

  auto reference = cachedReference(scene, *camera, setup);
  if (!reference) return reference.error();
  c.reference = std::move(reference->image);
  c.referenceNoisePsnr = reference->noisePsnr;
  c.referenceSeconds = reference->seconds;

  Image8 a = tonemap(c.probeLit, scene.exposure), b = tonemap(c.reference, scene.exposure);
  c.psnr = psnr8(a, b);
  c.ssim = ssim8(a, b);
  c.psnrLinear = psnrLinear(c.probeLit, c.reference);
  if (!outDir.empty()) {
    std::error_code ec;
    fs::create_directories(outDir, ec);
    writePng(fs::path(outDir) / "probe_lit.png", a);
    writePng(fs::path(outDir) / "reference.png", b);
    writeExr(fs::path(outDir) / "probe_lit.exr", c.probeLit);
    writeExr(fs::path(outDir) / "reference.exr", c.reference);
    writePng(fs::path(outDir) / "diff.png", differenceImage(a, b));
  }
  return c;
}

float groundHeight(float x, float z) {
  return 10.0f * std::sin(x * 0.011f) * std::cos(z * 0.013f) +
         2.0f * std::sin(x * 0.07f + 1.0f) * std::cos(z * 0.05f);
}

glm::vec3 groundNormal(float x, float z) {
  const float e = 0.5f;
  const float dx = (groundHeight(x + e, z) - groundHeight(x - e, z)) / (2 * e);
  const float dz = (groundHeight(x, z + e) - groundHeight(x, z - e)) / (2 * e);
  return glm::normalize(glm::vec3(-dx, 1.0f, -dz));
}

}  // namespace pc::bench
