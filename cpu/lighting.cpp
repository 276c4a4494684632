#include "lighting.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "../shaders/interop/shadow_roulette.h"

namespace pc {
namespace {

constexpr float kPi = 3.14159265358979f;

// A light's unshadowed irradiance at P and the shadow ray that decides it (far 0: the light
// does not reach P).
struct LightSample {
  glm::vec3 irradiance{0.0f};
  glm::vec3 wi{0.0f};
  float far = 0.0f;
};

LightSample lightSample(const gpu::GpuLight& light, glm::vec3 P, glm::vec3 N) {
  LightSample s;
  float distance = 0.0f;
  s.irradiance = gpu::pcLightIrradiance(light, P, N, s.wi, distance);
  s.far = distance * gpu::PC_SHADOW_FAR_SCALE;
  return s;
}

}  // namespace

template <class R>
std::size_t directLightSamples(std::span<const gpu::GpuLight> lights,
                               const EmissiveLights& emissive, glm::vec3 P, glm::vec3 shadowOrigin,
                               glm::vec3 N, R& rng, const DirectLightOptions& options,
                               std::vector<ShadowSample>& out) {
  const std::size_t first = out.size();
  const std::size_t lightCount = lights.size();
  // Up to kStackLights lights without a heap allocation per call.
  constexpr std::size_t kStackLights = 16;
  LightSample stackSamples[kStackLights];
  std::vector<LightSample> heapSamples(lightCount > kStackLights ? lightCount : 0);
  LightSample* samplesOf = lightCount > kStackLights ? heapSamples.data() : stackSamples;
  const bool roulette = options.shadowRouletteShare > 0.0f;
  float total = 0.0f;  // unshadowed punctual luminance, for the roulette only
  for (std::size_t i = 0; i < lightCount; ++i) {
    samplesOf[i] = lightSample(lights[i], P, N);
    if (roulette) total += luminance(samplesOf[i].irradiance);
  }
  for (std::size_t i = 0; i < lightCount; ++i) {
    const LightSample& ls = samplesOf[i];
    if (ls.far <= 0.0f) continue;
    const float weight =
        gpu::pcShadowRouletteWeight(luminance(ls.irradiance), total, options.shadowRouletteShare,
                                    options.shadowRouletteKey, int(i));
    if (weight == 0.0f) continue;
    out.push_back({shadowOrigin, ls.wi, ls.far,
                   weight == 1.0f ? ls.irradiance : ls.irradiance * weight, false});
  }

  const int samples = options.emissiveSamples;
  if (emissive.empty() || samples <= 0) return out.size() - first;
  const std::vector<EmissiveLights::Triangle>& tris = emissive.triangles();
  const std::vector<float>& cdf = emissive.cdf();
  for (int s = 0; s < samples; ++s) {
    // Stratified choice of triangle: one sample per 1/samples slice of the CDF, so a few
    // samples already spread over the emitters in proportion to their power.
    const float u = (float(s) + rng.uniform()) / float(samples);
    const std::size_t k = std::min<std::size_t>(
        std::upper_bound(cdf.begin(), cdf.end(), u) - cdf.begin(), tris.size() - 1);
    const float pTriangle = cdf[k] - (k > 0 ? cdf[k - 1] : 0.0f);
    if (pTriangle <= 0.0f) continue;
    const EmissiveLights::Triangle& tri = tris[k];
    const float u1 = rng.uniform();
    const float u2 = rng.uniform();
    const glm::vec3 Q = gpu::pcTrianglePoint(tri.p0, tri.e1, tri.e2, u1, u2);
    const float geometry = gpu::pcEmitterGeometry(Q, tri.normal, P, N);
    if (!(geometry > 0.0f)) continue;
    // Aim at a point lifted off the emitter so the emitter itself never shadows the sample.
    // The shadow ray runs from its origin straight to that point, and stops just short of it.
    const glm::vec3 target = gpu::pcOffsetRayOrigin(Q, tri.normal);
    const glm::vec3 toTarget = target - shadowOrigin;
    const float targetDistance = glm::length(toTarget);
    if (!(targetDistance > 0.0f)) continue;
    const float pdfArea = pTriangle / tri.area;
    out.push_back({shadowOrigin, toTarget / targetDistance,
                   targetDistance * gpu::PC_SHADOW_FAR_SCALE, tri.radiance * (geometry / pdfArea),
                   true});
  }
  return out.size() - first;
}

namespace {

// The light samples at P traced, each unshadowed one's `weigh(sample)` summed: punctual ones
// as they are, emitter ones averaged over the emitter sample count.
template <class R, class Weigh>
glm::vec3 sumUnshadowed(const EmbreeScene& scene, std::span<const gpu::GpuLight> lights,
                        const EmissiveLights& emissive, glm::vec3 P, glm::vec3 shadowOrigin,
                        glm::vec3 N, R& rng, const DirectLightOptions& options, Weigh weigh) {
  thread_local std::vector<ShadowSample> samples;
  samples.clear();
  directLightSamples(lights, emissive, P, shadowOrigin, N, rng, options, samples);
  if (options.shadowRayCount) *options.shadowRayCount += samples.size();
  glm::vec3 E(0.0f), sum(0.0f);
  for (const ShadowSample& s : samples) {
    if (scene.occluded(s.origin, s.dir, gpu::PC_SHADOW_NEAR, s.far)) continue;
    (s.emitter ? sum : E) += weigh(s);
  }
  return options.emissiveSamples > 0 && !emissive.empty() ? E + sum / float(options.emissiveSamples)
                                                          : E;
}

}  // namespace

template <class R>
glm::vec3 directIrradiance(const EmbreeScene& scene, std::span<const gpu::GpuLight> lights,
                           const EmissiveLights& emissive, glm::vec3 P, glm::vec3 shadowOrigin,
                           glm::vec3 N, R& rng, const DirectLightOptions& options) {
  return sumUnshadowed(scene, lights, emissive, P, shadowOrigin, N, rng, options,
                       [](const ShadowSample& s) { return s.irradiance; });
}

template <class R>
glm::vec3 directReflected(const EmbreeScene& scene, std::span<const gpu::GpuLight> lights,
                          const EmissiveLights& emissive, glm::vec3 P, glm::vec3 shadowOrigin,
                          const SurfaceBrdf& brdf, glm::vec3 V, R& rng,
                          const DirectLightOptions& options) {
  return sumUnshadowed(scene, lights, emissive, P, shadowOrigin, brdf.normal, rng, options,
                       [&](const ShadowSample& s) { return brdf.eval(V, s.dir) * s.irradiance; });
}

template std::size_t directLightSamples<RayRng>(std::span<const gpu::GpuLight>,
                                                const EmissiveLights&, glm::vec3, glm::vec3,
                                                glm::vec3, RayRng&, const DirectLightOptions&,
                                                std::vector<ShadowSample>&);
template glm::vec3 directIrradiance<Rng>(const EmbreeScene&, std::span<const gpu::GpuLight>,
                                         const EmissiveLights&, glm::vec3, glm::vec3, glm::vec3,
                                         Rng&, const DirectLightOptions&);
template glm::vec3 directReflected<Rng>(const EmbreeScene&, std::span<const gpu::GpuLight>,
                                        const EmissiveLights&, glm::vec3, glm::vec3,
                                        const SurfaceBrdf&, glm::vec3, Rng&,
                                        const DirectLightOptions&);
template glm::vec3 directIrradiance<RayRng>(const EmbreeScene&, std::span<const gpu::GpuLight>,
                                            const EmissiveLights&, glm::vec3, glm::vec3, glm::vec3,
                                            RayRng&, const DirectLightOptions&);

glm::vec3 sampleCosineHemisphere(glm::vec3 N, float u1, float u2) {
  // Uniform point on the unit disk, lifted onto the hemisphere (Malley's method).
  const float r = std::sqrt(u1);
  const float phi = 2.0f * kPi * u2;
  const float x = r * std::cos(phi), y = r * std::sin(phi);
  const float z = std::sqrt(std::max(0.0f, 1.0f - u1));
  // Orthonormal basis about N without branches on the dominant axis (Duff et al. 2017).
  const float sign = std::copysign(1.0f, N.z);
  const float a = -1.0f / (sign + N.z);
  const float b = N.x * N.y * a;
  const glm::vec3 t(1.0f + sign * N.x * N.x * a, sign * b, -sign * N.x);
  const glm::vec3 bt(b, sign + N.y * N.y * a, -N.y);
  return glm::normalize(x * t + y * bt + z * N);
}

}  // namespace pc
