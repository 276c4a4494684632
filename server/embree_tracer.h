// The CPU backend of the Tracer interface, on Embree 3 and TBB: all cores trace, shade and
// blend. Also exposes the bare probe-ray trace, the ceiling the full update is measured
// against.
#pragma once

#include <memory>

#include "../cpu/embree_scene.h"
#include "../cpu/lighting.h"
#include "tracer.h"

namespace pc {

class EmbreeTracer final : public Tracer {
 public:
  static Result<std::unique_ptr<EmbreeTracer>> create(const Scene& scene,
                                                      const TracerOptions& options);
  ~EmbreeTracer() override;
  std::string name() const override { return "embree"; }
  // Neither fails: the scene and its buffers were made by create.
  Status setState(const SceneState& state) override;
  Result<UpdateStats> update(Field& field, const UpdateRequest& request) override;

  // Traces the same probe rays as update() (closest hit only, no shading or blending) and
  // returns the milliseconds taken; `hits` counts rays that hit geometry.
  double traceOnly(const Field& field, const UpdateRequest& request, std::uint64_t* hits) const;

  const EmbreeScene& embree() const { return *embree_; }

 private:
  EmbreeTracer(const Scene& scene, std::unique_ptr<EmbreeScene> embree,
               const TracerOptions& options);
  void traceShadowRays(const std::vector<ShadowSample>& samples, std::vector<RTCRay>& rays) const;
  const Scene& scene_;
  std::unique_ptr<EmbreeScene> embree_;
  TracerOptions options_;
  std::vector<gpu::GpuLight> lights_;  // the state's lights, packed once per state
  EmissiveSurfaces surfaces_;          // found once: setState only places them
  EmissiveLights emissive_;
  // One update's per-ray buffers (tens of MB at full updates), kept from one update to the
  // next: allocated fresh, every update paid for their pages again.
  struct Scratch;
  std::unique_ptr<Scratch> scratch_;
};

// Ray directions of one update: the Fibonacci set under the update's random rotation.
std::vector<glm::vec3> probeRayDirections(int rayCount, std::uint32_t rotationSeed);

}  // namespace pc
