// The scene in Embree 3: one triangle geometry per instance, in world space. Animated
// instances get their vertices re-transformed on update(); the scene is committed again.
// Cut-out materials get intersection and occlusion filters that refuse uncovered hits.
// Owns the Embree device and scene (RAII). Thread-safe for queries after update().
#pragma once

#include <embree3/rtcore.h>

#include <glm/glm.hpp>
#include <memory>
#include <vector>

#include "../common/result.h"
#include "../common/scene.h"

namespace pc {

struct Hit {
  float t = 0.0f;
  unsigned instance = RTC_INVALID_GEOMETRY_ID;  // index into Scene::instances
  unsigned primitive = 0;
  glm::vec2 barycentric{0.0f};
  glm::vec3 geometricNormal{0.0f};  // world, unnormalized, as Embree reports it
};

// What shading needs at a hit.
struct SurfacePoint {
  glm::vec3 position{0.0f};
  // Shading normal: the interpolated vertex normal perturbed by the material's normal map
  // (shaders/interop/normal_map.h), flipped to the incoming ray's side as vertexNormal is.
  // Lights and bounces see the surface through it.
  glm::vec3 normal{0.0f};
  // The interpolated vertex normal alone, flipped to face the incoming ray: what offsets and
  // biases follow (the probe sampler's normal bias, screen-space occlusion) and what probe
  // rays shade with, as the GPU tracer has no normal maps.
  glm::vec3 vertexNormal{0.0f};
  glm::vec3 geometricNormal{0.0f};  // unit, flipped to face the incoming ray
  bool backface = false;            // the ray hit the back of the triangle's winding
  float extent = 0.0f;              // largest world coordinate of the triangle's corners
  glm::vec3 albedo{0.0f};           // the base colour (diffuse albedo of a dielectric)
  // The metallic-roughness model at the point (Material::metallic and roughness times the
  // texture); metallic 0 with roughness 1 is the plain Lambert surface.
  float metallic = 0.0f;
  float roughness = 1.0f;
  glm::vec3 emission{0.0f};  // radiance emitted toward the ray origin
  int material = 0;
};

class EmbreeScene {
 public:
  static Result<std::unique_ptr<EmbreeScene>> create(const Scene& scene);
  ~EmbreeScene();
  EmbreeScene(const EmbreeScene&) = delete;
  EmbreeScene& operator=(const EmbreeScene&) = delete;

  // Moves animated instances to their transforms in `state` and recommits; takes its
  // emission factors.
  void update(const SceneState& state);

  bool intersect(glm::vec3 origin, glm::vec3 dir, float tnear, float tfar, Hit& hit) const;
  bool occluded(glm::vec3 origin, glm::vec3 dir, float tnear, float tfar) const;
  // Closest hits for a packet of rays already in Embree's layout (throughput measurements
  // and the field update's batched tracing use this).
  void intersect1M(RTCRayHit* rays, unsigned count) const;

  SurfacePoint surface(const Hit& hit, glm::vec3 origin, glm::vec3 dir) const;

  const Scene& scene() const { return *scene_; }
  RTCScene handle() const { return rtcScene_; }

  // What the filter of a cut-out instance's geometry reads (Material::isCutOut).
  struct CutOut {
    RTCGeometry geometry = nullptr;
    const Mesh* mesh = nullptr;
    const Material* material = nullptr;
    const std::vector<Texture>* textures = nullptr;
  };

 private:
  EmbreeScene() = default;
  // Writes instance i's world-space vertices, normals and tangents for `transform`.
  void transformInstance(std::size_t i, const glm::mat4& transform);

  const Scene* scene_ = nullptr;
  RTCDevice device_ = nullptr;
  RTCScene rtcScene_ = nullptr;
  std::vector<RTCGeometry> geometries_;               // per instance
  std::vector<CutOut> cutOuts_;                       // per instance (unused when opaque)
  std::vector<std::vector<glm::vec3>> worldNormals_;  // per instance, per vertex
  // Per instance, per vertex of a normal-mapped mesh (else empty): the tangent in world space
  // and its handedness times the sign of the transform's determinant.
  std::vector<std::vector<glm::vec4>> worldTangents_;
  std::vector<glm::mat4> transforms_;
  std::vector<float> emissionScale_;  // the state's (SceneState::emissionScale)
  bool dynamic_ = false;              // any animated instance
};

}  // namespace pc
