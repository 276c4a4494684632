// energy: a closed box whose walls all have albedo a and emit Le. The converged field must
// hold irradiance pi Le / (1 - a) everywhere: any gain or loss in tracing, shading, blending
// or sampling shows up here.
#include <cmath>

#include "bench.h"
#include "common/field.h"
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

EnergyResult measure(float albedo, float emission, int updates, const std::string& backend) {
  Scene scene = furnaceBox(albedo, emission);
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
            return 0;
          }};
}

}  // namespace pc::bench
