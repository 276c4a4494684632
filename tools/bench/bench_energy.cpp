// energy: a closed box whose walls all have albedo a and emit Le. The converged field must
// hold irradiance pi Le / (1 - a) everywhere: any gain or loss in tracing, shading, blending
// or sampling shows up here. With glossy walls (metals of base colour a and roughness r) a
// wall reflects a share rho(N.V) = a A + B of what arrives (the split-sum table), which
// depends on the view, so there is no single figure: the converged irradiance must lie
// between pi Le / (1 - min rho) and pi Le / (1 - max rho).
#include <algorithm>
#include <cmath>

#include "bench.h"
#include "common/field.h"
#include "common/split_sum_table.h"
#include "server/bake.h"
#include "server/embree_tracer.h"
#include "shaders/interop/probe_update.h"

namespace pc::bench {

namespace {

struct EnergyResult {
  double expected = 0, meanTexel = 0, worstTexel = 0, meanSampled = 0;
  double errorMean = 0, errorWorst = 0, errorSampled = 0;
  int probes = 0;
};

// The walls' reflected share rho(N.V) over N.V: its least and largest value (min, max) for
// a metal of base colour `albedo` and `roughness`.
glm::dvec2 metalAlbedoRange(float albedo, float roughness) {
  glm::dvec2 range(1e9, -1e9);
  for (int i = 0; i <= 100; ++i) {
    const float NdotV = std::max(float(i) / 100.0f, gpu::PC_SPLIT_SUM_MIN_NDOTV);
    const glm::vec2 ab = lookupSplitSum(splitSumTable(), NdotV, roughness);
    const double rho = double(albedo * ab.x + ab.y);
    range = glm::dvec2(std::min(range.x, rho), std::max(range.y, rho));
  }
  return range;
}

// roughness < 0: Lambert walls; else metal walls of that roughness.
EnergyResult measure(float albedo, float emission, int updates, const std::string& backend,
                     float roughness = -1.0f) {
  Scene scene = furnaceBox(albedo, emission);
  if (roughness >= 0.0f) {
    scene.materials[0].metallic = 1.0f;
    scene.materials[0].roughness = roughness;
  }
  Field field = Field::create(scene.volumes, FieldSettings{});
  auto tracer = makeTracer(scene, backend);
  if (!tracer) {
    std::fprintf(stderr, "energy: %s\n", tracer.error().message.c_str());
    std::exit(1);
  }
  BakeOptions options;
  options.updates = updates;
  if (auto baked = bakeField(field, **tracer, options); !baked) {
    std::fprintf(stderr, "energy: %s\n", baked.error().message.c_str());
    std::exit(1);
  }

  EnergyResult r;
  r.expected = gpu::PC_PI * emission / (1.0 - albedo);
  double sum = 0;
  long texels = 0;
  for (const ProbeRef& p : allProbes(field)) {
    if (field.probe(p.cascade, p.slot).state == gpu::PC_PROBE_INSIDE) continue;
    ++r.probes;
    for (const glm::vec3& d : [] {
           std::vector<glm::vec3> dirs;
           for (int i = 0; i < 64; ++i) dirs.push_back(gpu::pcFibonacciDirection(i, 64));
           return dirs;
         }()) {
      glm::vec3 e = fetchIrradiance(field, p.cascade, p.slot, d);
      double v = (e.x + e.y + e.z) / 3.0;
      sum += v;
      ++texels;
      if (texels == 1 || std::abs(v - r.expected) > std::abs(r.worstTexel - r.expected))
        r.worstTexel = v;
    }
  }
  r.meanTexel = sum / double(std::max(texels, 1L));
  // What shading sees: the field sampled on the walls, facing into the box.
  double sampled = 0;
  int samples = 0;
  for (int i = 0; i < 200; ++i) {
    glm::vec3 n = gpu::pcFibonacciDirection(i, 200);
    glm::vec3 axis = glm::abs(n);
    glm::vec3 N = axis.x > axis.y && axis.x > axis.z ? glm::vec3(-glm::sign(n.x), 0, 0)
                  : axis.y > axis.z                  ? glm::vec3(0, -glm::sign(n.y), 0)
                                                     : glm::vec3(0, 0, -glm::sign(n.z));
    glm::vec3 center = 0.5f * (scene.boundsMin + scene.boundsMax);
    glm::vec3 P = center + n * (0.5f * (scene.boundsMax.x - scene.boundsMin.x)) /
                               std::max(axis.x, std::max(axis.y, axis.z));
    glm::vec4 s = sampleField(field, P, N, N, gpu::PC_SAMPLE_DEFAULT);
    sampled += (s.x + s.y + s.z) / 3.0;
    ++samples;
  }
  r.meanSampled = sampled / samples;
  r.errorMean = std::abs(r.meanTexel - r.expected) / r.expected;
  r.errorWorst = std::abs(r.worstTexel - r.expected) / r.expected;
  r.errorSampled = std::abs(r.meanSampled - r.expected) / r.expected;
  return r;
}

}  // namespace

Benchmark addEnergy(CLI::App& app) {
  auto* cmd = app.add_subcommand("energy", "furnace box: converged irradiance vs pi Le/(1-a)");
  static int updates = 128;
  static float emission = 1.0f;
  static std::string backend = "embree";
  cmd->add_option("--updates", updates, "field updates to converge");
  cmd->add_option("--backend", backend,
                  "tracer that updates the field: embree, vulkan (ray tracing), sdf (distance "
                  "field in Vulkan compute) or auto")
      ->capture_default_str();
  cmd->add_option("--emission", emission, "emitted radiance Le of every wall");
  return {cmd, [] {
            std::printf(
                "energy: closed box, all walls albedo a and emission Le=%.3g, %s field, %d "
                "updates\n",
                emission, backend.c_str(), updates);
            std::printf("%6s %12s %12s %12s %12s %10s %10s %10s\n", "albedo", "expected",
                        "mean texel", "worst texel", "sampled", "err mean", "err worst",
                        "err sampl");
            double errors[2];
            const float albedos[2] = {0.5f, 0.8f};
            for (int i = 0; i < 2; ++i) {
              EnergyResult r = measure(albedos[i], emission, updates, backend);
              std::printf("%6.2f %12.5f %12.5f %12.5f %12.5f %9.3f%% %9.3f%% %9.3f%%\n", albedos[i],
                          r.expected, r.meanTexel, r.worstTexel, r.meanSampled, 100 * r.errorMean,
                          100 * r.errorWorst, 100 * r.errorSampled);
              errors[i] = std::max(r.errorMean, r.errorSampled);
            }
            figure("energy_error_a50", errors[0], "relative");
            figure("energy_error_a80", errors[1], "relative");
            // Glossy walls: the field between the bounds that the walls' least and largest
            // reflected shares give.
            const float metal = 0.8f, roughness = 0.5f;
            const EnergyResult g = measure(metal, emission, updates, backend, roughness);
            const glm::dvec2 rho = metalAlbedoRange(metal, roughness);
            const double lo = gpu::PC_PI * emission / (1.0 - rho.x),
                         hi = gpu::PC_PI * emission / (1.0 - rho.y);
            std::printf(
                "metal walls, base %.2f, roughness %.2f: reflected share %.3f..%.3f, irradiance "
                "bounds %.5f..%.5f; mean texel %.5f, worst texel %.5f, sampled %.5f\n",
                metal, roughness, rho.x, rho.y, lo, hi, g.meanTexel, g.worstTexel, g.meanSampled);
            const bool within = g.meanTexel >= lo && g.meanTexel <= hi && g.meanSampled >= lo &&
                                g.meanSampled <= hi;
            figure("energy_glossy_mean_texel", g.meanTexel, "W/m^2");
            figure("energy_glossy_within_bounds", within ? 1.0 : 0.0, "bool");
            return 0;
          }};
}

}  // namespace pc::bench
