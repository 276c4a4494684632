#include "embree_tracer.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>

#include "../common/split_sum_table.h"
#include "../shaders/interop/probe_hit_shading.h"
#include "../shaders/interop/probe_math.h"
#include "../shaders/interop/probe_update.h"
#include "../shaders/interop/shadow_roulette.h"
#include "field_hit_sampler.h"
#include "probe_blend.h"

namespace pc {

using Clock = std::chrono::steady_clock;
static double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

namespace {

// What a probe-ray hit reflects with (shaders/interop/probe_hit_shading.h): the vertex
// normal (the GPU tracer reads no normal maps) and the material's terms at the point.
struct HitMaterial {
  glm::vec3 normal{0.0f}, albedo{0.0f};
  float metallic = 0.0f, roughness = 1.0f;
  bool glossy() const { return gpu::pcHasSpecularLobe(metallic, roughness); }
  // Whether it reflects anything: a dielectric's coat reflects even where its base is black.
  bool reflects() const { return glossy() || albedo.x > 0 || albedo.y > 0 || albedo.z > 0; }
};

// A probe-ray hit waiting for its indirect light.
struct DeferredHit {
  glm::vec3 position;
  HitMaterial material;
};
constexpr std::uint32_t kNoDeferredHit = 0xFFFFFFFFu;  // a ray's key when it has none

// Morton code of a position quantized to the finest cascade's spacing (10 bits per axis).
std::uint32_t spatialKey(const Field& field, glm::vec3 p) {
  const gpu::CascadeDesc& c = field.cascade(0);
  glm::ivec3 q = glm::clamp(glm::ivec3(glm::floor((p - c.origin) / c.spacing)) + 512, 0, 1023);
  auto spread = [](std::uint32_t v) {
    v = (v | (v << 16)) & 0x030000FFu;
    v = (v | (v << 8)) & 0x0300F00Fu;
    v = (v | (v << 4)) & 0x030C30C3u;
    v = (v | (v << 2)) & 0x09249249u;
    return v;
  };
  return spread(std::uint32_t(q.x)) | spread(std::uint32_t(q.y)) << 1 |
         spread(std::uint32_t(q.z)) << 2;
}

// Sorts by the upper 32 bits (LSD radix, 8 bits a pass, stable): linear time where the hit
// count runs to millions. The four digits' histograms come from one read of `v`; `tmp` is
// scratch.
void radixSortByHighWord(std::vector<std::uint64_t>& v, std::vector<std::uint64_t>& tmp) {
  tmp.resize(v.size());
  std::size_t count[4][257] = {};
  for (std::uint64_t x : v)
    for (int d = 0; d < 4; ++d) ++count[d][((x >> (32 + 8 * d)) & 0xFF) + 1];
  for (int d = 0; d < 4; ++d) {
    std::size_t* c = count[d];
    for (int i = 0; i < 256; ++i) c[i + 1] += c[i];
    const int shift = 32 + 8 * d;
    for (std::uint64_t x : v) tmp[c[(x >> shift) & 0xFF]++] = x;
    v.swap(tmp);
  }
}

}  // namespace

// Traces the shadow rays of `samples` (one probe's) together; an occluded one comes back in
// `rays` with tfar < 0.
void EmbreeTracer::traceShadowRays(const std::vector<ShadowSample>& samples,
                                   std::vector<RTCRay>& rays) const {
  rays.resize(samples.size());
  for (std::size_t j = 0; j < samples.size(); ++j) {
    const ShadowSample& s = samples[j];
    RTCRay& r = rays[j];
    r.org_x = s.origin.x, r.org_y = s.origin.y, r.org_z = s.origin.z;
    r.dir_x = s.dir.x, r.dir_y = s.dir.y, r.dir_z = s.dir.z;
    r.tnear = gpu::PC_SHADOW_NEAR;
    r.tfar = s.far;
    r.time = 0.0f;
    r.mask = 0xFFFFFFFFu;
    r.id = 0;
    r.flags = 0;
  }
  if (rays.empty()) return;
  // One stream call for the probe's shadow rays, not one call per ray. Measured on pandora
  // (docs/BENCHMARKS.md): faster than rtcOccluded1 per ray and than packets of 16; the
  // coherent-stream flag was slower (these rays leave scattered hits).
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  rtcOccluded1M(embree_->handle(), &context, rays.data(), unsigned(rays.size()), sizeof(RTCRay));
}

struct EmbreeTracer::Scratch {
  std::vector<RayResult> results;     // per probe ray
  std::vector<std::uint32_t> keys;    // per probe ray: its hit's spatialKey, or kNoDeferredHit
  std::vector<DeferredHit> deferred;  // per probe ray, written where its key is set
  std::vector<std::uint64_t> order, sortTmp;
};

std::vector<glm::vec3> probeRayDirections(int rayCount, std::uint32_t rotationSeed) {
  glm::mat3 rotation = gpu::pcRandomRotation(rotationSeed);
  std::vector<glm::vec3> dirs(rayCount);
  for (int i = 0; i < rayCount; ++i) dirs[i] = rotation * gpu::pcFibonacciDirection(i, rayCount);
  return dirs;
}

std::vector<ProbeRef> allProbes(const Field& field) {
  std::vector<ProbeRef> probes;
  for (int k = 0; k < field.cascadeCount(); ++k) {
    const gpu::CascadeDesc& c = field.cascade(k);
    for (int s = 0; s < gpu::pcSlotCount(c); ++s)
      if (gpu::pcSlotValid(c, s)) probes.push_back({k, s});
  }
  return probes;
}

Result<std::unique_ptr<Tracer>> makeEmbreeTracer(const Scene& scene, const TracerOptions& options) {
  auto t = EmbreeTracer::create(scene, options);
  if (!t) return t.error();
  return std::unique_ptr<Tracer>(std::move(t).value());
}

Result<std::unique_ptr<EmbreeTracer>> EmbreeTracer::create(const Scene& scene,
                                                           const TracerOptions& options) {
  auto embree = EmbreeScene::create(scene);
  if (!embree) return embree.error();
  std::unique_ptr<EmbreeTracer> tracer(new EmbreeTracer(scene, std::move(embree).value(), options));
  if (Status s = tracer->setState(evaluateScene(scene, 0.0)); !s) return s.error();
  return tracer;
}

EmbreeTracer::EmbreeTracer(const Scene& scene, std::unique_ptr<EmbreeScene> embree,
                           const TracerOptions& options)
    : scene_(scene),
      embree_(std::move(embree)),
      options_(options),
      surfaces_(scene),
      scratch_(std::make_unique<Scratch>()) {}

EmbreeTracer::~EmbreeTracer() = default;

Status EmbreeTracer::setState(const SceneState& state) {
  lights_ = packLights(state);
  embree_->update(state);
  emissive_ = EmissiveLights::build(scene_, state, surfaces_);
  return Status::success();
}

Result<UpdateStats> EmbreeTracer::update(Field& field, const UpdateRequest& request) {
  UpdateStats stats;
  const auto t0 = Clock::now();
  const int rayCount = field.settings.raysPerProbe;
  const std::vector<glm::vec3> dirs = probeRayDirections(rayCount, request.rotationSeed);
  const std::size_t probeCount = request.probes.size();
  std::vector<RayResult>& results = scratch_->results;
  results.resize(probeCount * rayCount);
  const float inf = std::numeric_limits<float>::infinity();
  tbb::enumerable_thread_specific<std::uint64_t> shadowRaysOf(0);
  // Every probe shares the directions, so a miss's sky radiance is looked up once per
  // direction, not once per miss (about half of pandora's probe rays miss).
  std::vector<glm::vec3> sky(dirs.size());
  for (std::size_t i = 0; i < dirs.size(); ++i) sky[i] = scene_.sky.radiance(dirs[i]);

  // Phase 1: trace, shade with direct light and emission. Hits that need indirect light from
  // the field are deferred: evaluated in phase 1b in spatial order.
  const bool indirect = !(request.shading & kShadeNoIndirect);
  const auto backfaceIsSurface = [&](int material) {
    return material >= 0 && std::size_t(material) < scene_.materials.size() &&
           gpu::pcBackfaceIsSurface(scene_.materials[std::size_t(material)].alphaCutoff);
  };
  std::vector<std::uint32_t>& keys = scratch_->keys;
  std::vector<DeferredHit>& deferred = scratch_->deferred;
  keys.resize(indirect ? probeCount * rayCount : 0);
  deferred.resize(keys.size());
  const bool emitterSamples = options_.emissiveSamples > 0 && !emissive_.empty();
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, probeCount, 4), [&](const auto& range) {
    DirectLightOptions lightOptions;
    lightOptions.emissiveSamples = options_.emissiveSamples;
    lightOptions.shadowRouletteShare = options_.shadowRouletteShare;
    // One probe's shaded hits wait here while its shadow rays are traced together.
    std::vector<ShadowSample> samples;
    std::vector<std::uint32_t> firstSample(std::size_t(rayCount) + 1);
    std::vector<HitMaterial> materialOf(static_cast<std::size_t>(rayCount));
    std::vector<RTCRay> shadowRays;
    std::uint64_t shadowCount = 0;
    for (std::size_t p = range.begin(); p != range.end(); ++p) {
      const ProbeRef ref = request.probes[p];
      const glm::vec3 origin = field.probePosition(ref.cascade, ref.slot);
      const float near = gpu::pcProbeRayNear(field.cascade(ref.cascade));
      RayResult* out = &results[p * rayCount];
      samples.clear();
      for (int i = 0; i < rayCount; ++i) {
        firstSample[std::size_t(i)] = std::uint32_t(samples.size());
        materialOf[std::size_t(i)] = HitMaterial{};
        Hit hit;
        if (indirect) keys[p * rayCount + i] = kNoDeferredHit;
        if (!embree_->intersect(origin, dirs[i], near, inf, hit)) {
          out[i] = {sky[i], inf};
          continue;
        }
        SurfacePoint sp = embree_->surface(hit, origin, dirs[i]);
        // surface() already turns a backface's normals toward the ray and drops its emission,
        // which is how a cut-out's back is shaded (pcBackfaceIsSurface).
        if (sp.backface && !backfaceIsSurface(sp.material)) {
          out[i] = {glm::vec3(0.0f), -hit.t};
          continue;
        }
        const auto rayIndex = std::uint32_t(p * rayCount + std::size_t(i));
        lightOptions.shadowRouletteKey = gpu::pcShadowRouletteKey(request.rotationSeed, rayIndex);
        // The GPU shade pass's stream for this ray: the same emitter samples.
        RayRng rng(std::uint32_t(request.rotationSeed), rayIndex);
        const glm::vec3 shadowOrigin =
            gpu::pcShadowOrigin(sp.position, sp.geometricNormal, sp.extent);
        // The vertex normal, not the normal-mapped one: the GPU tracer reads no normal maps,
        // and both backends must trace the same field.
        directLightSamples(lights_, emissive_, sp.position, shadowOrigin, sp.vertexNormal, rng,
                           lightOptions, samples);
        const HitMaterial material{sp.vertexNormal, sp.albedo, sp.metallic, sp.roughness};
        materialOf[std::size_t(i)] = material;
        // The emitted light for now; the direct light joins it once the shadow rays are in.
        out[i] = {emissive_.sampled(sp.material) ? glm::vec3(0.0f) : sp.emission, hit.t};
        if (indirect && material.reflects()) {
          deferred[p * rayCount + i] = {sp.position, material};
          keys[p * rayCount + i] = spatialKey(field, sp.position);
        }
      }
      firstSample[std::size_t(rayCount)] = std::uint32_t(samples.size());
      shadowCount += samples.size();
      traceShadowRays(samples, shadowRays);
      for (int i = 0; i < rayCount; ++i) {
        const std::uint32_t begin = firstSample[std::size_t(i)],
                            end = firstSample[std::size_t(i) + 1];
        if (begin == end) continue;
        const HitMaterial& m = materialOf[std::size_t(i)];
        // Lambert: albedo / pi x the irradiance, summed first (as always). Glossy: each
        // sample through the BRDF for its direction (pcProbeHitLightWeight).
        const bool glossy = m.glossy();
        const glm::vec3 V = -dirs[std::size_t(i)];
        glm::vec3 punctual(0.0f), emitter(0.0f);
        for (std::uint32_t j = begin; j < end; ++j) {
          if (shadowRays[j].tfar < 0.0f) continue;  // occluded
          const ShadowSample& s = samples[j];
          (s.emitter ? emitter : punctual) +=
              glossy ? gpu::pcProbeHitLightWeight(m.normal, V, s.dir, m.albedo, m.metallic,
                                                  m.roughness) *
                           s.irradiance
                     : s.irradiance;
        }
        const glm::vec3 light =
            emitterSamples ? punctual + emitter / float(options_.emissiveSamples) : punctual;
        out[i].radiance =
            out[i].radiance + (glossy ? light : m.albedo * (1.0f / gpu::PC_PI) * light);
      }
    }
    shadowRaysOf.local() += shadowCount;
  });

  // Phase 1b: indirect light at the hits from the field of the previous update. Sampling the
  // field touches the tiles of eight probes per hit; in ray order those are scattered over the
  // atlases and most reads miss the caches. Sorted along a Morton curve, consecutive hits share
  // their cages and the tiles stay cached.
  if (indirect) {
    std::vector<std::uint64_t>& order = scratch_->order;
    order.clear();
    for (std::size_t r = 0; r < keys.size(); ++r)
      if (keys[r] != kNoDeferredHit) order.push_back(std::uint64_t(keys[r]) << 32 | r);
    radixSortByHighWord(order, scratch_->sortTmp);
    const FieldHitSampler sampler(field);
    const SplitSumTable& table = splitSumTable();
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, order.size(), 256), [&](const auto& range) {
          for (std::size_t j = range.begin(); j != range.end(); ++j) {
            const std::size_t r = std::size_t(order[j] & 0xFFFFFFFFu);
            const DeferredHit& h = deferred[r];
            const HitMaterial& m = h.material;
            const glm::vec3 V = -dirs[r % std::size_t(rayCount)];
            const glm::vec3 E = sampler.irradiance(h.position, m.normal, V);
            // A glossy hit reads the field a second time, about its lobe's direction.
            glm::vec3 lobeE(0.0f);
            glm::vec2 ab(0.0f);
            if (m.glossy()) {
              const glm::vec3 lobeNormal = gpu::pcProbeHitSpecularNormal(m.normal, V, m.roughness);
              lobeE = sampler.irradiance(h.position, m.normal, lobeNormal, V);
              ab = lookupSplitSum(table, std::max(glm::dot(m.normal, V), 0.0f), m.roughness);
            }
            results[r].radiance += gpu::pcProbeHitIndirect(m.normal, V, m.albedo, m.metallic,
                                                           m.roughness, E, lobeE, ab);
          }
        });
  }
  stats.traceMs = msSince(t0);
  stats.probeRays = std::uint64_t(probeCount) * rayCount;
  for (std::uint64_t n : shadowRaysOf) stats.shadowRays += n;

  // Phase 2: blend every probe (disjoint tiles, so in parallel), then mark changed bricks.
  const auto t1 = Clock::now();
  std::vector<float> change(probeCount, 0.0f);
  const BlendTaps taps = BlendTaps::build(dirs.data(), rayCount, field.settings.distanceExponent);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, probeCount, 8), [&](const auto& range) {
    for (std::size_t p = range.begin(); p != range.end(); ++p) {
      const ProbeRef ref = request.probes[p];
      change[p] = blendProbe(field, ref.cascade, ref.slot, &results[p * rayCount], dirs.data(),
                             rayCount, taps);
    }
  });
  const std::uint64_t next = field.version + 1;
  for (std::size_t p = 0; p < probeCount; ++p) {
    if (change[p] <= request.changeThreshold) continue;
    const ProbeRef ref = request.probes[p];
    std::uint64_t& v = field.brickVersions[ref.cascade][ref.slot / gpu::PC_PROBES_PER_BRICK];
    if (v != next) {
      v = next;
      ++stats.bricksChanged;
    }
  }
  if (stats.bricksChanged > 0) field.version = next;
  stats.blendMs = msSince(t1);
  stats.probesUpdated = int(probeCount);
  stats.totalMs = msSince(t0);
  return stats;
}

double EmbreeTracer::traceOnly(const Field& field, const UpdateRequest& request,
                               std::uint64_t* hits) const {
  const int rayCount = field.settings.raysPerProbe;
  const std::vector<glm::vec3> dirs = probeRayDirections(rayCount, request.rotationSeed);
  const std::size_t probeCount = request.probes.size();
  const float inf = std::numeric_limits<float>::infinity();
  std::atomic<std::uint64_t> hitCount{0};
  const auto t0 = Clock::now();
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, probeCount, 4), [&](const auto& range) {
    std::uint64_t local = 0;
    for (std::size_t p = range.begin(); p != range.end(); ++p) {
      const ProbeRef ref = request.probes[p];
      const glm::vec3 origin = field.probePosition(ref.cascade, ref.slot);
      const float near = gpu::pcProbeRayNear(field.cascade(ref.cascade));
      for (int i = 0; i < rayCount; ++i) {
        Hit hit;
        local += embree_->intersect(origin, dirs[i], near, inf, hit) ? 1 : 0;
      }
    }
    hitCount += local;
  });
  double ms = msSince(t0);
  if (hits) *hits = hitCount;
  return ms;
}

}  // namespace pc
