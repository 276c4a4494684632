// The scene every module works on: meshes split by material, materials, textures, instances,
// lights, cameras, sky, probe volumes and simple animations. Loaded from glTF 2.0 or OBJ+MTL
// plus an optional scene.json sidecar, or built in. World space is Y-up, in scene units after
// the sidecar's unit scale.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "result.h"

namespace pc {

// The linear value of each 8-bit sRGB code (what Texture::sample decodes texels with).
const std::array<float, 256>& srgbDecodeTable();

// What a texture lookup outside [0, 1] reads, per axis (Vulkan's and glTF's address modes).
enum class TextureWrap : std::uint8_t { Repeat, ClampToEdge, MirroredRepeat };

struct Texture {
  std::string name;
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgba;  // 8-bit sRGB (linear when `linear`), row 0 at the top
  TextureWrap wrapU = TextureWrap::Repeat, wrapV = TextureWrap::Repeat;
  // Data rather than colour (normal maps): the codes are linear values / 255, never decoded
  // from sRGB (the client uploads such a texture as UNORM, the others as SRGB).
  bool linear = false;
  // Bilinear with the texture's wrap modes, as a Vulkan sampler with linear filtering reads
  // level 0; returns linear RGB (alpha linear).
  glm::vec4 sample(glm::vec2 uv) const;
};

struct Material {
  std::string name;
  glm::vec3 baseColor{0.8f};  // linear albedo, multiplied by the texture
  int baseColorTexture = -1;  // index into Scene::textures
  glm::vec3 emissive{0.0f};   // linear emitted radiance, multiplied by the texture
  int emissiveTexture = -1;
  // Cut-outs (foliage cards, grilles): the surface exists where baseAlpha x the alpha texture's
  // channel (bilinear, as Texture::sample gives it: colour channels decoded from sRGB, alpha
  // linear) is at least alphaCutoff. alphaCutoff 0: opaque everywhere, no test. Every tracer
  // and renderer applies the same test (coveredAt; the shaders through GpuMaterial and the
  // client's DrawData).
  float alphaCutoff = 0.0f;
  float baseAlpha = 1.0f;
  int alphaTexture = -1;  // index into Scene::textures, -1: baseAlpha alone
  int alphaChannel = 3;   // 0-3: which channel of alphaTexture (glTF: 3; OBJ map_d: 0)
  // Tangent-space normal map (glTF normalTexture): a linear texture whose RGB holds the
  // normal's tangent, bitangent and normal components as (c + 1) / 2; x and y are scaled by
  // normalScale. Applied where the mesh has tangents and texture coordinates
  // (shadingNormal); -1: none.
  int normalTexture = -1;
  float normalScale = 1.0f;
  // glTF's metallic-roughness model: `metallic` blends a dielectric (0) into a metal (1),
  // `roughness` is the perceptual roughness (GGX alpha = roughness^2). Both are multiplied by
  // metallicRoughnessTexture where there is one (a linear texture: B metallic, G roughness).
  // The defaults, metallic 0 and roughness 1, are the diffuse surface every renderer drew
  // before: a point whose metallic is 0 and roughness 1 reflects by Lambert's law alone, with
  // no specular lobe (isDiffuseOnly), so OBJ scenes and glTF files that say so look as before.
  float metallic = 0.0f;
  float roughness = 1.0f;
  int metallicRoughnessTexture = -1;  // index into Scene::textures, -1: the factors alone
  bool isEmissive() const { return emissive.x > 0 || emissive.y > 0 || emissive.z > 0; }
  bool isCutOut() const { return alphaCutoff > 0.0f; }
  // Lambert alone everywhere: no point of the surface has a specular lobe.
  bool isDiffuseOnly() const {
    return metallicRoughnessTexture < 0 && metallic == 0.0f && roughness == 1.0f;
  }
};

// Whether `material`'s surface exists at `uv` (always, unless it is a cut-out).
bool coveredAt(const Material& material, const std::vector<Texture>& textures, glm::vec2 uv);

struct Mesh {
  std::string name;
  std::vector<glm::vec3> positions;  // object space
  std::vector<glm::vec3> normals;    // one per position, unit length (generated when missing)
  std::vector<glm::vec2> uvs;        // one per position, or empty; (0,0) is the image's top left
                                     // (glTF convention; OBJ v is flipped on load)
  // One per position, or empty: xyz the unit tangent (along increasing u), w = +1 or -1 the
  // handedness, the bitangent being w x cross(normal, tangent) (glTF TANGENT). Read from the
  // file or generated on load for meshes whose material has a normal map (generateTangents).
  std::vector<glm::vec4> tangents;
  std::vector<std::uint32_t> indices;  // triangles
  int material = 0;
  std::size_t triangleCount() const { return indices.size() / 3; }
};

enum class LightType { Point, Spot, Directional };

// Radiometric units: point and spot `intensity` is radiant intensity (W/sr) so irradiance is
// intensity * cos / d^2; directional `intensity` is irradiance (W/m^2) at normal incidence.
struct Light {
  std::string name;
  LightType type = LightType::Point;
  glm::vec3 position{0.0f};
  glm::vec3 direction{0.0f, -1.0f, 0.0f};  // where the light travels (spot, directional)
  glm::vec3 color{1.0f};
  float intensity = 1.0f;
  float range = 0.0f;           // 0: unlimited (inverse square only)
  float innerConeAngle = 0.0f;  // radians (spot)
  float outerConeAngle = 0.7853982f;
  int animation = -1;  // index into Scene::animations
};

struct Camera {
  std::string name;
  glm::vec3 position{0.0f, 0.0f, 5.0f};
  glm::vec3 forward{0.0f, 0.0f, -1.0f};
  glm::vec3 up{0.0f, 1.0f, 0.0f};
  float yfov = 0.7853982f;  // vertical field of view, radians
};

// Sky radiance by direction: zenith above, horizon at y = 0, ground below (linear). Between them
// the radiance is interpolated linearly in dir.y: horizon..zenith for y > 0, horizon..ground below.
struct Sky {
  glm::vec3 zenith{0.0f}, horizon{0.0f}, ground{0.0f};
  glm::vec3 radiance(glm::vec3 dir) const;
  bool isBlack() const;
  // The renderers' last fallback for indirect light where no probe holds data: the irradiance
  // an open sky gives (pi x its mean radiance), or a dim grey under a black sky so that shapes
  // stay visible. The client and the CPU probe-lit render use the same term.
  glm::vec3 ambientIrradiance() const;
};

// How a volume's probes store irradiance: octahedral tiles, or spherical-harmonics coefficients
// of band 1 or 2 (shaders/interop/sh_probe.h). Values equal the shared PC_ENCODING_* constants.
// Sidecar and command-line names: "octahedral", "sh1", "sh2".
enum class ProbeEncoding : int { Octahedral = 0, Sh1 = 1, Sh2 = 2 };
std::optional<ProbeEncoding> parseProbeEncoding(std::string_view name);
const char* probeEncodingName(ProbeEncoding encoding);

// A volume's own update settings (the sidecar's per-volume keys, docs/SCENES.md); each one
// unset takes the field's (FieldSettings, common/field.h). Units as there: biases and blend
// margin in fractions of the volume's spacing, the ray distance in world units.
struct VolumeSettings {
  std::optional<float> hysteresis;      // [0, 1)
  std::optional<float> normalBias;      // [0, 1]
  std::optional<float> viewBias;        // [0, 1]
  std::optional<float> maxRayDistance;  // > 0
  std::optional<float> blendMargin;     // [0, 4]
  std::optional<ProbeEncoding> encoding;
  // The cascade follows the viewers (common/field_scroll.h): a server moves it, by whole
  // spacings, to keep the viewers near its middle. Baking ignores it.
  std::optional<bool> follow;
};

// One cascade of probes. Cascades are ordered finest first.
struct ProbeVolume {
  glm::vec3 origin{0.0f};  // world position of probe (0,0,0)
  float spacing = 1.0f;
  glm::ivec3 counts{8};
  VolumeSettings settings;
};

// One animated property of a glTF node over time (a glTF animation channel with its sampler).
// Times are seconds, increasing; values hold xyz (w unused) for translation and scale and xyzw
// for rotation, one per key, or three per key (in-tangent, value, out-tangent) for cubic
// splines. The track loops with the period of the glTF animation it came from.
struct KeyframeTrack {
  enum class Property : std::uint8_t { Translation, Rotation, Scale } property;
  enum class Interpolation : std::uint8_t { Step, Linear, CubicSpline } interpolation;
  std::vector<float> times;
  std::vector<glm::vec4> values;
  float period = 0.0f;  // the animation's length: the latest key of all its channels
};

// A node on the way from a glTF root to an animated instance or light: its rest transform and
// the tracks (indices into Animation::tracks) that move it. A node given as a matrix is never
// animated (glTF forbids it), so it keeps the matrix.
struct KeyframedNode {
  glm::vec3 translation{0.0f};
  glm::quat rotation{1.0f, 0.0f, 0.0f, 0.0f};
  glm::vec3 scale{1.0f};
  bool hasMatrix = false;
  glm::mat4 matrix{1.0f};
  std::vector<int> tracks;
};

// A light moving along a looping polyline, or an instance rotating about an axis, or a glTF
// keyframed node chain. A path is closed (the last point leads back to the first) and every
// segment takes period / points.size() seconds; an instance on a path is translated by
// path(t) - points[0]. A keyframed instance's transform is base * the product of its chain's
// local transforms at t (root first), replacing its rest transform; a keyframed light sits at
// that transform's origin and shines along its -Z.
struct Animation {
  enum class Kind { Path, Rotate, Keyframes } kind = Kind::Path;
  std::vector<glm::vec3> points;     // Path: positions visited in order
  float period = 4.0f;               // Path: seconds per loop
  glm::vec3 axis{0.0f, 1.0f, 0.0f};  // Rotate
  glm::vec3 pivot{0.0f};             // Rotate: world-space point the axis goes through
  float radiansPerSecond = 0.5f;     // Rotate
  // Keyframes: every track of the file, shared by all the animations made from it.
  std::shared_ptr<const std::vector<KeyframeTrack>> tracks;
  std::vector<KeyframedNode> chain;  // Keyframes: root first
  glm::mat4 base{1.0f};              // Keyframes: the scene conversion applied after the chain
};

// The object-to-world transform a keyframed animation gives at time t.
glm::mat4 keyframedTransform(const Animation& a, double time);

struct Instance {
  std::string name;  // glTF node name, or the mesh name
  int mesh = 0;
  glm::mat4 transform{1.0f};  // object to world at time 0
  int animation = -1;
};

// How emissive surfaces light the scene: sampled as area lights with shadow rays (sharp
// direct light, for small bright emitters) or only through the probe field (for large dim
// emitters, where sampling is noisy and the field is accurate).
enum class EmissiveMode { Auto, Lights, Field };

struct Scene {
  std::string name;
  std::filesystem::path source;       // file it came from, empty when built in
  std::filesystem::path sidecar;      // scene.json that was applied, empty when none
  std::vector<std::string> warnings;  // non-fatal problems met while loading (missing textures)
  std::vector<Mesh> meshes;
  std::vector<Material> materials;
  std::vector<Texture> textures;
  std::vector<Instance> instances;
  std::vector<Light> lights;
  std::vector<Camera> cameras;
  std::vector<Animation> animations;
  std::vector<ProbeVolume> volumes;  // empty: derive from bounds (see defaultVolumes)
  Sky sky;
  EmissiveMode emissiveMode = EmissiveMode::Auto;
  float exposure = 1.0f;   // scale applied before tone mapping by every renderer
  std::uint64_t hash = 0;  // of geometry, materials, lights: names the scene on the wire

  glm::vec3 boundsMin{0.0f}, boundsMax{0.0f};  // world, at time 0
  std::size_t triangleCount() const;           // over instances (a mesh drawn twice counts twice)
  bool hasLights() const;                      // any light or emissive material
  bool hasCutOuts() const;  // any drawn material that is a cut-out (Material::isCutOut)
  // The material instance `inst` is drawn with, or null when its mesh or material is invalid.
  const Material* materialOf(const Instance& inst) const;
};

// What a scene file, which may come from anyone, is allowed to read and to make us allocate.
// Each limit is checked before the memory it guards is allocated (from file headers and
// accessor counts where the format gives them), and exceeding one is an error naming the file,
// what exceeded it and the limit.
struct SceneLoadOptions {
  // Files a scene names (glTF buffers and images, OBJ material libraries and texture maps) must
  // resolve, symbolic links followed, to a place inside the scene file's folder; true lifts
  // that (tools: --allow-outside-paths). data: URIs are always read.
  bool allowOutsidePaths = false;
  // Texels per side of one texture, read from the image header before decoding.
  int maxTextureSize = 8192;
  // Texels of all the scene's textures together (512 Mi: 2 GiB as 8-bit RGBA).
  std::uint64_t maxSceneTexels = std::uint64_t(512) << 20;
  // Triangles the meshes hold, and triangles drawn over all instances.
  std::uint64_t maxTriangles = 50'000'000;
};

// Loads .gltf/.glb/.obj; `sidecar` (scene.json format, see docs/SCENES.md) may be empty, in
// which case <scene dir>/scene.json, then <scene file stem>.json and <scene dir name>.json in
// the sidecar folders (beside the executable in sidecars/, the install's
// share/probecast/sidecars, $PROBECAST_DATA/sidecars) are tried in that order;
// Scene::sidecar names the one applied. Errors name the file and the
// problem: "<file>: <problem>", and for a sidecar "<file>: at <JSON pointer>: <problem>".
Result<Scene> loadScene(const std::filesystem::path& path,
                        const std::filesystem::path& sidecar = {},
                        const SceneLoadOptions& options = {});
// Cornell-style room with a moving light and a rotating block; needs no files.
Scene builtinScene();
// A closed cube of side `size` whose walls all have albedo `albedo` and emit `emission`
// (EmissiveMode::Field): the energy-conservation test scene, with a 4x4x4 probe volume.
Scene furnaceBox(float albedo, float emission, float size = 2.0f);
// Cascades covering the scene's bounds when the scene names none.
std::vector<ProbeVolume> defaultVolumes(const Scene& scene, int maxProbesPerAxis = 24);

// Lights and instance transforms at animation time t (seconds).
struct SceneState {
  double time = 0.0;
  std::vector<Light> lights;
  std::vector<glm::mat4> instanceTransforms;
  // Runtime edits (common/scene_edits.h): the last `addedLights` of `lights` were added by
  // edits (point lights, after the scene's own); per material, a factor on its emission (empty:
  // all 1); the edit version the state includes (0: none, the animation alone).
  std::uint32_t addedLights = 0;
  std::vector<float> emissionScale;
  std::uint64_t editVersion = 0;
  float emissionScaleOf(int material) const {
    return material >= 0 && std::size_t(material) < emissionScale.size()
               ? emissionScale[std::size_t(material)]
               : 1.0f;
  }
};
SceneState evaluateScene(const Scene& scene, double time);

// The camera `index` of the scene, or one looking at the scene's bounds when it has none
// (index 0 only); an error naming the index and the scene's camera count otherwise.
Result<Camera> sceneCamera(const Scene& scene, int index);

// One line for the log saying where a loaded scene's sidecar came from, or where none was
// found: a run from a copy of the tools that misses its sidecar loses the scene's lights and
// volumes, and must say so at once.
std::string sidecarReport(const Scene& scene);

}  // namespace pc
