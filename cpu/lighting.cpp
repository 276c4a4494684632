#include "lighting.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>

#include "../shaders/interop/shadow_roulette.h"

namespace pc {
namespace {

constexpr float kPi = 3.14159265358979f;
// Shadow rays start a hair past their (already offset) origin and stop a hair short of the
// light, so neither the receiver nor the emitter itself counts as an occluder.
constexpr float kShadowNear = 1e-4f;
constexpr float kShadowFarScale = 1.0f - 1e-4f;

glm::mat4 instanceTransform(const Scene& scene, const SceneState& state, std::size_t i) {
  return i < state.instanceTransforms.size() ? state.instanceTransforms[i]
                                             : scene.instances[i].transform;
}

const Material* materialOf(const Scene& scene, const Mesh& mesh) {
  return mesh.material >= 0 && std::size_t(mesh.material) < scene.materials.size()
             ? &scene.materials[mesh.material]
             : nullptr;
}

// Mean emitted radiance over a triangle: the emissive texture at four interior points is a
// cheap stand-in for its integral, enough to weight light selection and the estimate.
glm::vec3 triangleRadiance(const Scene& scene, const Mesh& mesh, const Material& mat,
                           std::uint32_t i0, std::uint32_t i1, std::uint32_t i2) {
  if (mat.emissiveTexture < 0 || std::size_t(mat.emissiveTexture) >= scene.textures.size() ||
      mesh.uvs.size() != mesh.positions.size()) {
    return mat.emissive;
  }
  const Texture& tex = scene.textures[mat.emissiveTexture];
  const glm::vec2 a = mesh.uvs[i0], b = mesh.uvs[i1], c = mesh.uvs[i2];
  const glm::vec3 bary[4] = {{1.0f / 3, 1.0f / 3, 1.0f / 3},
                             {2.0f / 3, 1.0f / 6, 1.0f / 6},
                             {1.0f / 6, 2.0f / 3, 1.0f / 6},
                             {1.0f / 6, 1.0f / 6, 2.0f / 3}};
  glm::vec3 sum(0.0f);
  for (const glm::vec3& w : bary) {
    const glm::vec4 t = tex.sample(w.x * a + w.y * b + w.z * c);
    sum += glm::vec3(t.x, t.y, t.z);
  }
  return mat.emissive * sum * 0.25f;
}

// Smooth fall-off to zero at `range` (the window glTF's KHR_lights_punctual suggests), so
// limited-range lights do not end in a visible edge.
float rangeWindow(float distance, float range) {
  if (range <= 0.0f) return 1.0f;
  const float r = distance / range;
  const float w = std::clamp(1.0f - r * r * r * r, 0.0f, 1.0f);
  return w * w;
}

float spotFactor(const Light& light, glm::vec3 towardLight) {
  const float cosOuter = std::cos(light.outerConeAngle);
  const float cosInner = std::cos(std::min(light.innerConeAngle, light.outerConeAngle));
  const float cosAngle = glm::dot(-towardLight, glm::normalize(light.direction));
  if (cosInner - cosOuter <= 1e-6f) return cosAngle >= cosOuter ? 1.0f : 0.0f;
  const float t = std::clamp((cosAngle - cosOuter) / (cosInner - cosOuter), 0.0f, 1.0f);
  return t * t * (3.0f - 2.0f * t);
}

// A punctual light's unshadowed irradiance at P and the shadow ray that decides it (far 0:
// the light does not reach P).
struct PunctualSample {
  glm::vec3 irradiance{0.0f};
  glm::vec3 wi{0.0f};
  float far = 0.0f;
};

PunctualSample punctualSample(const Light& light, glm::vec3 P, glm::vec3 N) {
  const glm::vec3 power = light.color * light.intensity;
  if (light.type == LightType::Directional) {
    const glm::vec3 wi = -glm::normalize(light.direction);
    const float cosTheta = glm::dot(N, wi);
    if (cosTheta <= 0.0f) return {};
    return {power * cosTheta, wi, INFINITY};
  }
  const glm::vec3 toLight = light.position - P;
  const float d2 = glm::dot(toLight, toLight);
  if (d2 <= 0.0f) return {};
  const float d = std::sqrt(d2);
  const glm::vec3 wi = toLight / d;
  const float cosTheta = glm::dot(N, wi);
  if (cosTheta <= 0.0f) return {};
  float scale = cosTheta / d2 * rangeWindow(d, light.range);
  if (light.type == LightType::Spot) scale *= spotFactor(light, wi);
  if (scale <= 0.0f) return {};
  return {power * scale, wi, d * kShadowFarScale};
}

}  // namespace

bool emissiveAsLights(EmissiveMode mode, double emissiveArea, double totalArea) {
  switch (mode) {
    case EmissiveMode::Lights:
      return true;
    case EmissiveMode::Field:
      return false;
    case EmissiveMode::Auto:
      // Small bright emitters (lamps, screens) cast sharp shadows that only light sampling
      // with shadow rays resolves, and a probe field is too coarse to hold them. Large dim
      // emitters (glowing walls, skylight panels) light everything softly: sampling them is
      // noisy for little gain, while the field captures their smooth light well.
      return emissiveArea > 0.0 && emissiveArea < kEmissiveLightsMaxAreaShare * totalArea;
  }
  return false;
}

EmissiveSurfaces::EmissiveSurfaces(const Scene& scene) {
  const SceneState rest = evaluateScene(scene, 0.0);
  for (std::size_t i = 0; i < scene.instances.size(); ++i) {
    const Instance& inst = scene.instances[i];
    if (inst.mesh < 0 || std::size_t(inst.mesh) >= scene.meshes.size()) continue;
    const Mesh& mesh = scene.meshes[inst.mesh];
    const Material* mat = materialOf(scene, mesh);
    const bool glows = mat && mat->isEmissive();
    const glm::mat4 m = instanceTransform(scene, rest, i);
    for (std::size_t t = 0; t + 2 < mesh.indices.size(); t += 3) {
      const std::uint32_t i0 = mesh.indices[t], i1 = mesh.indices[t + 1], i2 = mesh.indices[t + 2];
      if (std::max({i0, i1, i2}) >= mesh.positions.size()) continue;
      const glm::vec3 p0 = glm::vec3(m * glm::vec4(mesh.positions[i0], 1.0f));
      const glm::vec3 p1 = glm::vec3(m * glm::vec4(mesh.positions[i1], 1.0f));
      const glm::vec3 p2 = glm::vec3(m * glm::vec4(mesh.positions[i2], 1.0f));
      const float twiceArea = glm::length(glm::cross(p1 - p0, p2 - p0));
      if (twiceArea <= 0.0f) continue;
      const float area = 0.5f * twiceArea;
      totalArea_ += area;
      if (!glows) continue;
      emissiveArea_ += area;
      const glm::vec3 radiance = triangleRadiance(scene, mesh, *mat, i0, i1, i2);
      if (luminance(radiance) <= 0.0f) continue;
      sources_.push_back({i, i0, i1, i2, radiance});
    }
  }
}

EmissiveLights EmissiveLights::build(const Scene& scene, const SceneState& state) {
  return build(scene, state, EmissiveSurfaces(scene));
}

EmissiveLights EmissiveLights::build(const Scene& scene, const SceneState& state,
                                     const EmissiveSurfaces& surfaces) {
  EmissiveLights lights;
  lights.sampledMaterials_.assign(scene.materials.size(), false);
  if (!emissiveAsLights(scene.emissiveMode, surfaces.emissiveArea_, surfaces.totalArea_))
    return lights;
  for (std::size_t m = 0; m < scene.materials.size(); ++m) {
    lights.sampledMaterials_[m] = scene.materials[m].isEmissive();
  }
  // Only the emitting triangles are placed at `state`.
  std::size_t placed = SIZE_MAX;
  glm::mat4 m(1.0f);
  float side = 1.0f;
  for (const EmissiveSurfaces::Source& src : surfaces.sources_) {
    if (src.instance != placed) {
      placed = src.instance;
      m = instanceTransform(scene, state, src.instance);
      // A mirroring transform flips the winding, and with it which side is the front.
      side = glm::determinant(glm::mat3(m)) < 0.0f ? -1.0f : 1.0f;
    }
    const Mesh& mesh = scene.meshes[scene.instances[src.instance].mesh];
    const glm::vec3 p0 = glm::vec3(m * glm::vec4(mesh.positions[src.i0], 1.0f));
    const glm::vec3 p1 = glm::vec3(m * glm::vec4(mesh.positions[src.i1], 1.0f));
    const glm::vec3 p2 = glm::vec3(m * glm::vec4(mesh.positions[src.i2], 1.0f));
    const glm::vec3 cross = glm::cross(p1 - p0, p2 - p0);
    const float twiceArea = glm::length(cross);
    if (twiceArea <= 0.0f) continue;
    lights.triangles_.push_back(
        {p0, p1 - p0, p2 - p0, side * cross / twiceArea, 0.5f * twiceArea, src.radiance});
  }
  if (lights.triangles_.empty()) return lights;
  double sum = 0.0;
  lights.cdf_.reserve(lights.triangles_.size());
  for (const Triangle& tri : lights.triangles_) {
    sum += double(luminance(tri.radiance)) * tri.area * kPi;
    lights.cdf_.push_back(static_cast<float>(sum));
  }
  for (float& c : lights.cdf_) c = static_cast<float>(c / sum);
  lights.cdf_.back() = 1.0f;  // not empty: the list has triangles
  lights.totalPower_ = static_cast<float>(sum);
  return lights;
}

bool EmissiveLights::sampled(int material) const {
  return material >= 0 && std::size_t(material) < sampledMaterials_.size() &&
         sampledMaterials_[material];
}

template <class R>
glm::vec3 directIrradiance(const EmbreeScene& scene, const SceneState& state,
                           const EmissiveLights& emissive, glm::vec3 P, glm::vec3 shadowOrigin,
                           glm::vec3 N, R& rng, const DirectLightOptions& options) {
  glm::vec3 E(0.0f);
  std::uint64_t shadowRays = 0;
  // Counted locally and added once: the counter may be shared by a thread's many calls.
  struct Count {
    std::uint64_t& local;
    std::uint64_t* total;
    ~Count() {
      if (total) *total += local;
    }
  } count{shadowRays, options.shadowRayCount};
  const std::size_t lightCount = state.lights.size();
  // Up to kStackLights lights without a heap allocation per call.
  constexpr std::size_t kStackLights = 16;
  PunctualSample stackSamples[kStackLights];
  std::vector<PunctualSample> heapSamples(lightCount > kStackLights ? lightCount : 0);
  PunctualSample* samplesOf = lightCount > kStackLights ? heapSamples.data() : stackSamples;
  const bool roulette = options.shadowRouletteShare > 0.0f;
  float total = 0.0f;  // unshadowed punctual luminance, for the roulette only
  for (std::size_t i = 0; i < lightCount; ++i) {
    samplesOf[i] = punctualSample(state.lights[i], P, N);
    if (roulette) total += luminance(samplesOf[i].irradiance);
  }
  for (std::size_t i = 0; i < lightCount; ++i) {
    const PunctualSample& ls = samplesOf[i];
    if (ls.far <= 0.0f) continue;
    const float weight =
        gpu::pcShadowRouletteWeight(luminance(ls.irradiance), total, options.shadowRouletteShare,
                                    options.shadowRouletteKey, int(i));
    if (weight == 0.0f) continue;
    ++shadowRays;
    if (scene.occluded(shadowOrigin, ls.wi, kShadowNear, ls.far)) continue;
    E += weight == 1.0f ? ls.irradiance : ls.irradiance * weight;
  }

  const int samples = options.emissiveSamples;
  if (emissive.empty() || samples <= 0) return E;
  const std::vector<EmissiveLights::Triangle>& tris = emissive.triangles();
  const std::vector<float>& cdf = emissive.cdf();
  glm::vec3 sum(0.0f);
  for (int s = 0; s < samples; ++s) {
    // Stratified choice of triangle: one sample per 1/samples slice of the CDF, so a few
    // samples already spread over the emitters in proportion to their power.
    const float u = (float(s) + rng.uniform()) / float(samples);
    const std::size_t k = std::min<std::size_t>(
        std::upper_bound(cdf.begin(), cdf.end(), u) - cdf.begin(), tris.size() - 1);
    const float pTriangle = cdf[k] - (k > 0 ? cdf[k - 1] : 0.0f);
    if (pTriangle <= 0.0f) continue;
    const EmissiveLights::Triangle& tri = tris[k];
    // Uniform point on the triangle (square-root warp of the unit square).
    const float r = std::sqrt(rng.uniform());
    const float v = rng.uniform();
    const glm::vec3 Q = tri.p0 + r * (1.0f - v) * tri.e1 + r * v * tri.e2;

    const glm::vec3 toLight = Q - P;
    const float d2 = glm::dot(toLight, toLight);
    if (d2 <= 0.0f) continue;
    const float d = std::sqrt(d2);
    const glm::vec3 wi = toLight / d;
    const float cosSurface = glm::dot(N, wi);
    const float cosLight = -glm::dot(tri.normal, wi);  // one-sided: only the front emits
    if (cosSurface <= 0.0f || cosLight <= 0.0f) continue;
    // Aim at a point lifted off the emitter so the emitter itself never shadows the sample.
    // The shadow ray runs from its origin straight to that point, and stops just short of it.
    const glm::vec3 target = offsetRayOrigin(Q, tri.normal);
    const glm::vec3 toTarget = target - shadowOrigin;
    const float targetDistance = glm::length(toTarget);
    if (targetDistance <= 0.0f) continue;
    ++shadowRays;
    if (scene.occluded(shadowOrigin, toTarget / targetDistance, kShadowNear,
                       targetDistance * kShadowFarScale))
      continue;
    const float pdfArea = pTriangle / tri.area;
    sum += tri.radiance * (cosSurface * cosLight / (d2 * pdfArea));
  }
  return E + sum / float(samples);
}

template glm::vec3 directIrradiance<Rng>(const EmbreeScene&, const SceneState&,
                                         const EmissiveLights&, glm::vec3, glm::vec3, glm::vec3,
                                         Rng&, const DirectLightOptions&);
template glm::vec3 directIrradiance<RayRng>(const EmbreeScene&, const SceneState&,
                                            const EmissiveLights&, glm::vec3, glm::vec3, glm::vec3,
                                            RayRng&, const DirectLightOptions&);

glm::vec3 offsetRayOrigin(glm::vec3 P, glm::vec3 n) {
  // Move the point a fixed number of float steps (ulps) along the normal, so the offset
  // scales with the rounding error of the coordinates themselves: large scenes get larger
  // offsets, small ones smaller. Near zero, ulps become tiny and a small absolute offset
  // takes over. (After Wächter and Binder, "A Fast and Robust Method for Avoiding
  // Self-Intersection", Ray Tracing Gems, 2019.)
  constexpr float kNearZero = 1.0f / 32.0f;
  constexpr float kAbsoluteStep = 1.0f / 65536.0f;
  constexpr float kUlpsPerUnitNormal = 256.0f;
  glm::vec3 out;
  for (int c = 0; c < 3; ++c) {
    const float p = P[c];
    if (std::fabs(p) < kNearZero) {
      out[c] = p + kAbsoluteStep * n[c];
      continue;
    }
    const auto ulps = static_cast<std::int32_t>(kUlpsPerUnitNormal * n[c]);
    // Moving away from zero means adding to the bit pattern's magnitude; the sign of the
    // coordinate decides which way that is.
    const std::int32_t bits = std::bit_cast<std::int32_t>(p) + (p < 0.0f ? -ulps : ulps);
    out[c] = std::bit_cast<float>(bits);
  }
  return out;
}

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
