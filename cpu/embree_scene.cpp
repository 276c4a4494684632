#include "embree_scene.h"

#include <cmath>
#include <cstring>
#include <string>

#include "../common/log.h"
#include "../shaders/interop/normal_map.h"
#include "../shaders/interop/probe_math.h"

namespace pc {
namespace {

const char* deviceErrorName(RTCError code) {
  switch (code) {
    case RTC_ERROR_NONE:
      return "no error";
    case RTC_ERROR_INVALID_ARGUMENT:
      return "invalid argument";
    case RTC_ERROR_INVALID_OPERATION:
      return "invalid operation";
    case RTC_ERROR_OUT_OF_MEMORY:
      return "out of memory";
    case RTC_ERROR_UNSUPPORTED_CPU:
      return "unsupported CPU";
    case RTC_ERROR_CANCELLED:
      return "cancelled";
    default:
      return "unknown error";
  }
}

// Embree reports errors through this callback as well as through rtcGetDeviceError; logging
// them here names the failing call's message, which the error code alone does not.
void onDeviceError(void*, RTCError code, const char* message) {
  logError(std::string("embree: ") + deviceErrorName(code) + ": " + (message ? message : ""));
}

RTCIntersectContext makeContext() {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  return context;
}

RTCRay makeRay(glm::vec3 origin, glm::vec3 dir, float tnear, float tfar) {
  RTCRay ray{};
  ray.org_x = origin.x;
  ray.org_y = origin.y;
  ray.org_z = origin.z;
  ray.dir_x = dir.x;
  ray.dir_y = dir.y;
  ray.dir_z = dir.z;
  ray.tnear = tnear;
  ray.tfar = tfar;
  ray.mask = 0xFFFFFFFFu;
  ray.flags = 0;
  ray.time = 0.0f;
  return ray;
}

glm::vec3 rgb(glm::vec4 v) { return glm::vec3(v.x, v.y, v.z); }

// Intersection and occlusion filter of cut-out geometries: a candidate hit whose material is
// not covered there (coveredAt) is refused, and the ray goes on.
void cutOutFilter(const RTCFilterFunctionNArguments* args) {
  const auto* cut = static_cast<const EmbreeScene::CutOut*>(args->geometryUserPtr);
  const auto* index = static_cast<const std::uint32_t*>(
      rtcGetGeometryBufferData(cut->geometry, RTC_BUFFER_TYPE_INDEX, 0));
  const Mesh& mesh = *cut->mesh;
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] != -1) continue;
    glm::vec2 uv(0.0f);
    if (mesh.uvs.size() == mesh.positions.size()) {
      const unsigned prim = RTCHitN_primID(args->hit, args->N, i);
      const float u = RTCHitN_u(args->hit, args->N, i), v = RTCHitN_v(args->hit, args->N, i);
      uv = (1.0f - u - v) * mesh.uvs[index[3 * prim]] + u * mesh.uvs[index[3 * prim + 1]] +
           v * mesh.uvs[index[3 * prim + 2]];
    }
    if (!coveredAt(*cut->material, *cut->textures, uv)) args->valid[i] = 0;
  }
}

}  // namespace

Result<std::unique_ptr<EmbreeScene>> EmbreeScene::create(const Scene& scene) {
  std::unique_ptr<EmbreeScene> self(new EmbreeScene());
  self->scene_ = &scene;
  self->device_ = rtcNewDevice(nullptr);
  if (!self->device_) {
    return Error{std::string("cannot create the Embree device: ") +
                 deviceErrorName(rtcGetDeviceError(nullptr))};
  }
  rtcSetDeviceErrorFunction(self->device_, onDeviceError, nullptr);

  for (const Instance& inst : scene.instances) {
    if (inst.animation >= 0) self->dynamic_ = true;
  }
  self->rtcScene_ = rtcNewScene(self->device_);
  if (!self->rtcScene_) return Error{"cannot create the Embree scene"};
  // Static scenes get the best BVH; with animated instances the scene is rebuilt every
  // update, so a faster build pays off more than the last few percent of trace speed.
  rtcSetSceneFlags(self->rtcScene_, self->dynamic_ ? RTC_SCENE_FLAG_DYNAMIC : RTC_SCENE_FLAG_NONE);
  rtcSetSceneBuildQuality(self->rtcScene_,
                          self->dynamic_ ? RTC_BUILD_QUALITY_MEDIUM : RTC_BUILD_QUALITY_HIGH);

  const std::size_t count = scene.instances.size();
  self->geometries_.assign(count, nullptr);
  self->cutOuts_.assign(count, CutOut{});  // never resized again: filters point into it
  self->worldNormals_.resize(count);
  self->worldTangents_.resize(count);
  self->transforms_.resize(count);
  for (std::size_t i = 0; i < count; ++i) {
    const Instance& inst = scene.instances[i];
    if (inst.mesh < 0 || std::size_t(inst.mesh) >= scene.meshes.size()) {
      return Error{"instance " + std::to_string(i) + " names mesh " + std::to_string(inst.mesh) +
                   " of " + std::to_string(scene.meshes.size())};
    }
    const Mesh& mesh = scene.meshes[inst.mesh];
    const std::size_t triangles = mesh.triangleCount();
    if (triangles == 0 || mesh.positions.empty()) continue;  // nothing to hit; id left unused

    RTCGeometry geom = rtcNewGeometry(self->device_, RTC_GEOMETRY_TYPE_TRIANGLE);
    if (!geom) return Error{"cannot create an Embree geometry for instance " + std::to_string(i)};
    self->geometries_[i] = geom;  // owned from here on, released by the destructor
    // Animated instances only move rigidly, so refitting their BVH keeps it good enough.
    rtcSetGeometryBuildQuality(
        geom, inst.animation >= 0 ? RTC_BUILD_QUALITY_REFIT : RTC_BUILD_QUALITY_HIGH);

    auto* index = static_cast<std::uint32_t*>(rtcSetNewGeometryBuffer(
        geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(std::uint32_t), triangles));
    void* vertex = rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                           3 * sizeof(float), mesh.positions.size());
    if (!index || !vertex) return Error{"out of memory for instance " + std::to_string(i)};
    for (std::uint32_t idx : mesh.indices) {
      if (idx >= mesh.positions.size()) {
        return Error{"mesh '" + mesh.name + "' has an index past its vertices"};
      }
    }
    std::memcpy(index, mesh.indices.data(), triangles * 3 * sizeof(std::uint32_t));
    // A mirroring transform turns counter-clockwise triangles clockwise in world space; swap
    // two corners so the world winding still marks the front face (as glTF specifies).
    if (glm::determinant(glm::mat3(inst.transform)) < 0.0f) {
      for (std::size_t t = 0; t < triangles; ++t) std::swap(index[3 * t + 1], index[3 * t + 2]);
    }
    self->transformInstance(i, inst.transform);
    if (mesh.material >= 0 && std::size_t(mesh.material) < scene.materials.size() &&
        scene.materials[mesh.material].isCutOut()) {
      self->cutOuts_[i] = CutOut{geom, &mesh, &scene.materials[mesh.material], &scene.textures};
      rtcSetGeometryUserData(geom, &self->cutOuts_[i]);
      rtcSetGeometryIntersectFilterFunction(geom, cutOutFilter);
      rtcSetGeometryOccludedFilterFunction(geom, cutOutFilter);
    }
    rtcCommitGeometry(geom);
    rtcAttachGeometryByID(self->rtcScene_, geom, static_cast<unsigned>(i));
  }
  rtcCommitScene(self->rtcScene_);
  const RTCError err = rtcGetDeviceError(self->device_);
  if (err != RTC_ERROR_NONE) {
    return Error{std::string("Embree scene build failed: ") + deviceErrorName(err)};
  }
  return self;
}

EmbreeScene::~EmbreeScene() {
  for (RTCGeometry geom : geometries_) {
    if (geom) rtcReleaseGeometry(geom);
  }
  if (rtcScene_) rtcReleaseScene(rtcScene_);
  if (device_) rtcReleaseDevice(device_);
}

void EmbreeScene::transformInstance(std::size_t i, const glm::mat4& transform) {
  const Mesh& mesh = scene_->meshes[scene_->instances[i].mesh];
  auto* vertex =
      static_cast<float*>(rtcGetGeometryBufferData(geometries_[i], RTC_BUFFER_TYPE_VERTEX, 0));
  for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
    const glm::vec3 p = glm::vec3(transform * glm::vec4(mesh.positions[v], 1.0f));
    vertex[3 * v + 0] = p.x;
    vertex[3 * v + 1] = p.y;
    vertex[3 * v + 2] = p.z;
  }
  // Normals follow the inverse transpose so they stay perpendicular under non-uniform scale.
  const glm::mat3 normalMatrix = glm::transpose(glm::inverse(glm::mat3(transform)));
  std::vector<glm::vec3>& normals = worldNormals_[i];
  normals.resize(mesh.normals.size());
  for (std::size_t v = 0; v < mesh.normals.size(); ++v) {
    const glm::vec3 n = normalMatrix * mesh.normals[v];
    const float len = glm::length(n);
    normals[v] = len > 0.0f ? n / len : glm::vec3(0.0f);
  }
  // Tangents lie in the surface, so they follow the transform itself; a mirroring transform
  // flips the frame's handedness.
  std::vector<glm::vec4>& tangents = worldTangents_[i];
  const bool mapped = mesh.material >= 0 && std::size_t(mesh.material) < scene_->materials.size() &&
                      scene_->materials[mesh.material].normalTexture >= 0;
  tangents.resize(mapped ? mesh.tangents.size() : 0);
  const float mirror = glm::determinant(glm::mat3(transform)) < 0.0f ? -1.0f : 1.0f;
  for (std::size_t v = 0; v < tangents.size(); ++v)
    tangents[v] =
        glm::vec4(glm::mat3(transform) * glm::vec3(mesh.tangents[v]), mesh.tangents[v].w * mirror);
  transforms_[i] = transform;
}

void EmbreeScene::update(const SceneState& state) {
  emissionScale_ = state.emissionScale;
  bool changed = false;
  for (std::size_t i = 0; i < geometries_.size(); ++i) {
    if (!geometries_[i] || scene_->instances[i].animation < 0) continue;
    if (i >= state.instanceTransforms.size()) continue;
    const glm::mat4& transform = state.instanceTransforms[i];
    if (transform == transforms_[i]) continue;
    transformInstance(i, transform);
    rtcUpdateGeometryBuffer(geometries_[i], RTC_BUFFER_TYPE_VERTEX, 0);
    rtcCommitGeometry(geometries_[i]);
    changed = true;
  }
  if (changed) rtcCommitScene(rtcScene_);
}

bool EmbreeScene::intersect(glm::vec3 origin, glm::vec3 dir, float tnear, float tfar,
                            Hit& hit) const {
  RTCIntersectContext context = makeContext();
  RTCRayHit rayhit{};
  rayhit.ray = makeRay(origin, dir, tnear, tfar);
  rayhit.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rayhit.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(rtcScene_, &context, &rayhit);
  if (rayhit.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
  hit.t = rayhit.ray.tfar;
  hit.instance = rayhit.hit.geomID;
  hit.primitive = rayhit.hit.primID;
  hit.barycentric = glm::vec2(rayhit.hit.u, rayhit.hit.v);
  hit.geometricNormal = glm::vec3(rayhit.hit.Ng_x, rayhit.hit.Ng_y, rayhit.hit.Ng_z);
  return true;
}

bool EmbreeScene::occluded(glm::vec3 origin, glm::vec3 dir, float tnear, float tfar) const {
  RTCIntersectContext context = makeContext();
  RTCRay ray = makeRay(origin, dir, tnear, tfar);
  rtcOccluded1(rtcScene_, &context, &ray);
  return ray.tfar < 0.0f;  // Embree sets tfar to -inf when it finds any hit
}

void EmbreeScene::intersect1M(RTCRayHit* rays, unsigned count) const {
  RTCIntersectContext context = makeContext();
  rtcIntersect1M(rtcScene_, &context, rays, count, sizeof(RTCRayHit));
}

SurfacePoint EmbreeScene::surface(const Hit& hit, glm::vec3 origin, glm::vec3 dir) const {
  (void)origin;  // the position comes from the triangle itself, which is more precise
  SurfacePoint sp;
  const Instance& inst = scene_->instances[hit.instance];
  const Mesh& mesh = scene_->meshes[inst.mesh];
  RTCGeometry geom = geometries_[hit.instance];
  const auto* index =
      static_cast<const std::uint32_t*>(rtcGetGeometryBufferData(geom, RTC_BUFFER_TYPE_INDEX, 0));
  const auto* vertex =
      static_cast<const float*>(rtcGetGeometryBufferData(geom, RTC_BUFFER_TYPE_VERTEX, 0));
  const std::uint32_t i0 = index[3 * hit.primitive + 0];
  const std::uint32_t i1 = index[3 * hit.primitive + 1];
  const std::uint32_t i2 = index[3 * hit.primitive + 2];
  auto corner = [&](std::uint32_t i) {
    return glm::vec3(vertex[3 * i], vertex[3 * i + 1], vertex[3 * i + 2]);
  };
  const glm::vec3 p0 = corner(i0), p1 = corner(i1), p2 = corner(i2);
  const float u = hit.barycentric.x, v = hit.barycentric.y, w = 1.0f - u - v;
  sp.position = w * p0 + u * p1 + v * p2;
  sp.extent = gpu::pcTriangleExtent(p0, p1, p2);

  // The front face is the counter-clockwise side (glTF, OBJ). Computing it from the world
  // corners keeps the convention independent of how Embree orients its own Ng.
  glm::vec3 ng = glm::cross(p1 - p0, p2 - p0);
  const float ngLength = glm::length(ng);
  ng = ngLength > 0.0f ? ng / ngLength : -glm::normalize(dir);
  sp.backface = glm::dot(dir, ng) > 0.0f;
  sp.geometricNormal = sp.backface ? -ng : ng;

  glm::vec3 ns = sp.geometricNormal;
  const std::vector<glm::vec3>& normals = worldNormals_[hit.instance];
  if (normals.size() == mesh.positions.size()) {
    const glm::vec3 n = w * normals[i0] + u * normals[i1] + v * normals[i2];
    const float len = glm::length(n);
    if (len > 0.0f) ns = n / len;
  }
  // Keep the shading normal on the side the ray arrived from, like the geometric one.
  const float side = glm::dot(ns, sp.geometricNormal) < 0.0f ? -1.0f : 1.0f;
  sp.vertexNormal = side * ns;
  sp.normal = sp.vertexNormal;

  glm::vec2 uv(0.0f);
  if (mesh.uvs.size() == mesh.positions.size()) {
    uv = w * mesh.uvs[i0] + u * mesh.uvs[i1] + v * mesh.uvs[i2];
  }
  sp.material = mesh.material;
  if (mesh.material >= 0 && std::size_t(mesh.material) < scene_->materials.size()) {
    const Material& mat = scene_->materials[mesh.material];
    const auto texture = [&](int t) {
      return t >= 0 && std::size_t(t) < scene_->textures.size()
                 ? rgb(scene_->textures[t].sample(uv))
                 : glm::vec3(1.0f);
    };
    sp.albedo = mat.baseColor * texture(mat.baseColorTexture);
    sp.metallic = mat.metallic;
    sp.roughness = mat.roughness;
    if (mat.metallicRoughnessTexture >= 0) {  // linear data: B metallic, G roughness
      const glm::vec3 mr = texture(mat.metallicRoughnessTexture);
      sp.metallic *= mr.z;
      sp.roughness *= mr.y;
    }
    // Emitters are one-sided: their back does not glow.
    if (mat.isEmissive() && !sp.backface)
      sp.emission = mat.emissive * texture(mat.emissiveTexture) *
                    (std::size_t(mesh.material) < emissionScale_.size()
                         ? emissionScale_[std::size_t(mesh.material)]
                         : 1.0f);
    // The map perturbs the unflipped normal in the mesh's own frame; the result is then turned
    // as the vertex normal was, so the back of a two-sided surface sees the mirrored relief.
    const std::vector<glm::vec4>& tangents = worldTangents_[hit.instance];
    if (mat.normalTexture >= 0 && std::size_t(mat.normalTexture) < scene_->textures.size() &&
        tangents.size() == mesh.positions.size() && mesh.uvs.size() == mesh.positions.size()) {
      const glm::vec4 t = w * tangents[i0] + u * tangents[i1] + v * tangents[i2];
      const glm::vec3 m = gpu::pcNormalMapDirection(texture(mat.normalTexture), mat.normalScale);
      sp.normal = side * gpu::pcPerturbNormal(ns, glm::vec3(t), t.w, m);
    }
  }
  return sp;
}

}  // namespace pc
