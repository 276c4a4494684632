// Shared steps of the image benchmarks: bake a field for a scene, render it probe-lit,
// path-trace the reference (cached on disk by scene hash, camera, size and samples) and
// compare.
#pragma once

#include <CLI/CLI.hpp>
#include <optional>
#include <string>
#include <vector>

#include "common/field.h"
#include "common/image.h"
#include "common/result.h"
#include "common/scene.h"
#include "cpu/probe_lit_render.h"
#include "shaders/interop/screen_ao.h"

namespace pc::bench {

struct RenderSetup {
  int width = 320, height = 240;
  int spp = 512;     // reference paths per pixel
  int updates = 64;  // bake updates
  int camera = 0;
  // Primary samples of the probe-lit render, stratified in the pixel: 16 bring the error at
  // high-contrast edges under the references' own noise, so that the figures measure light,
  // not aliasing (docs/BENCHMARKS.md, "Edges").
  int primarySamples = 16;
  int emissiveSamples = 32;
  // Ambient occlusion radius of the probe-lit render's indirect light, in probe spacings
  // (ProbeLitOptions::aoRadius); 0: none.
  float aoRadius = gpu::PC_AO_DEFAULT_RADIUS;
  std::string cacheDir = "build/reference-cache";
  bool autoVolumes = false;  // place cascades from the geometry, ignoring the sidecar's
  // Every cascade's irradiance encoding, overriding the volumes' own (quality --encoding).
  std::optional<ProbeEncoding> encoding;
  std::string backend = "embree";  // the bake's tracer (makeTracer's names)
};
void addRenderOptions(CLI::App& cmd, RenderSetup& setup);
// --backend: the tracer that bakes the field (RenderSetup::backend).
void addBakeBackendOption(CLI::App& cmd, RenderSetup& setup);

struct Comparison {
  double psnr = 0, psnrLinear = 0, ssim = 0;
  double referenceNoisePsnr = 0;  // expected PSNR of the reference vs its noise-free limit
  double bakeSeconds = 0, referenceSeconds = 0;
  int probes = 0;
  Image probeLit, reference;
  Field field;  // the baked field the probe-lit image was rendered from
};

// Bakes the scene's field, renders camera `setup.camera` probe-lit and path traced, compares.
// Writes probe_lit.png/.exr, reference.png/.exr and diff.png into `outDir` when not empty.
// The probe-lit render's options for `setup` and `camera`: size, samples, contact occlusion.
ProbeLitOptions probeLitOptions(const RenderSetup& setup, const Camera& camera);

Result<Comparison> compareWithReference(const Scene& scene, const RenderSetup& setup,
                                        const std::string& outDir);
// cascades > 1: the first volume plus coarser ones around the same centre, each with twice
// the spacing of the one before and the same counts (nested cascades, as a camera-centred
// field would hold).
// autoVolumes: the cascades placed from the geometry (sceneVolumes) even where the scene has
// its own. encoding: every cascade's, overriding the volumes' own; SH coefficients are
// rounded to float16 after the bake, as files store them.
Result<Field> bakeSceneField(const Scene& scene, int updates, double* seconds = nullptr,
                             int cascades = 0, bool autoVolumes = false,
                             std::optional<ProbeEncoding> encoding = std::nullopt,
                             const std::string& backend = "embree");
// Bytes per probe of the field's irradiance at 16 bits per value (irradianceBytesPerProbe),
// averaged over its real probes; `withVisibility` adds the depth moments and occlusion tiles.
double fieldBytesPerProbe(const Field& field, bool withVisibility);

// Path-traced reference, from the cache when an identical render is there.
struct Reference {
  Image image;
  double noisePsnr = 0, seconds = 0;
};
Result<Reference> cachedReference(const Scene& scene, const Camera& camera,
                                  const RenderSetup& setup);

// Scene files under the shared scenes folder (one per folder; CornellBox-Original for the
// McGuire set), for --all.
std::vector<std::string> sharedSceneFiles();
// Every .gltf, .glb and .obj file under `dir` (its subfolders too, to a depth of 3, as sample
// collections nest them), sorted; an error when `dir` is not a readable folder.
Result<std::vector<std::string>> sceneFilesIn(const std::string& dir);
std::string sceneSlug(const Scene& scene);

// The generated terrain of `flight` and `sdf`: gentle hills with a ripple, the ground's height
// at (x, z) and its normal there.
float groundHeight(float x, float z);
glm::vec3 groundNormal(float x, float z);

}  // namespace pc::bench
