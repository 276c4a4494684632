// The scene.json sidecar (docs/SCENES.md): unit scale and up axis for what the scene file
// holds, plus lights, cameras, sky, exposure, probe volumes and animations in world units,
// and per-material metallic and roughness.
// Every problem is reported with the sidecar's path and the JSON pointer of the bad value.
#include <cmath>
#include <fstream>
#include <glm/gtc/matrix_transform.hpp>
#include <nlohmann/json.hpp>
#include <sstream>
#include <vector>

#include "common/data_folders.h"
#include "common/scene_loaders.h"
#include "shaders/interop/field_desc.h"

namespace pc::scene_detail {

namespace fs = std::filesystem;
using json = nlohmann::json;

// The names of data/sidecars/*.json (set by common/CMakeLists.txt), comma-separated.
#ifndef PC_SHIPPED_SIDECARS
#define PC_SHIPPED_SIDECARS ""
#endif

bool isShippedSidecar(std::string_view name) {
  std::string_view list = PC_SHIPPED_SIDECARS;
  while (!list.empty()) {
    const std::size_t comma = list.find(',');
    if (list.substr(0, comma) == name) return true;
    list = comma == std::string_view::npos ? std::string_view() : list.substr(comma + 1);
  }
  return false;
}

std::vector<fs::path> sidecarFolders() {
  std::vector<fs::path> folders;
  for (const fs::path& folder : dataFolders()) folders.push_back(folder / "sidecars");
  return folders;
}

Result<fs::path> findSidecar(const fs::path& scene, const fs::path& explicitSidecar) {
  std::error_code ec;
  if (!explicitSidecar.empty()) {
    if (!fs::is_regular_file(explicitSidecar, ec))
      return Error{explicitSidecar.string() + ": sidecar file not found"};
    return explicitSidecar;
  }
  const fs::path dir = scene.parent_path();
  if (fs::is_regular_file(dir / "scene.json", ec)) return dir / "scene.json";
  // The file's stem first: one folder may hold several scenes (CornellBox-Original.obj, ...).
  const std::string names[] = {scene.stem().string() + ".json",
                               fs::absolute(dir, ec).filename().string() + ".json"};
  for (const fs::path& folder : sidecarFolders())
    for (const std::string& name : names)
      if (fs::is_regular_file(folder / name, ec)) return folder / name;
  // A shared scene without the sidecar made for it loses its lights and volumes and bakes
  // something else without a word: a copy of the tools that lacks its data stops instead.
  for (const std::string& name : names)
    if (isShippedSidecar(name))
      return Error{scene.string() + ": its sidecar " + name +
                   " (one of probecast's own) is in none of " + dataFolderList("sidecars") +
                   "; set $PROBECAST_DATA to the folder holding sidecars/, or give --sidecar"};
  return fs::path();
}

namespace {

// The most probes the volumes may hold in all: 2^22, about 17 GB of atlases.
constexpr std::uint64_t kMaxSidecarProbes = std::uint64_t(1) << 22;

// Thrown while reading the sidecar, caught in applySidecar: `pointer` locates the bad value.
struct SidecarError {
  std::string pointer, message;
};

std::string typeName(const json& j) { return j.type_name(); }

[[noreturn]] void fail(const std::string& ptr, const std::string& msg) {
  throw SidecarError{ptr.empty() ? "/" : ptr, msg};
}

float number(const json& j, const std::string& ptr) {
  if (!j.is_number()) fail(ptr, "expected a number, got " + typeName(j));
  double v = j.get<double>();
  if (!std::isfinite(v)) fail(ptr, "number is not finite");
  return float(v);
}

float positive(const json& j, const std::string& ptr) {
  float v = number(j, ptr);
  if (!(v > 0.0f)) fail(ptr, "expected a positive number, got " + std::to_string(v));
  return v;
}

std::string string(const json& j, const std::string& ptr) {
  if (!j.is_string()) fail(ptr, "expected a string, got " + typeName(j));
  return j.get<std::string>();
}

glm::vec3 vec3(const json& j, const std::string& ptr) {
  if (!j.is_array() || j.size() != 3) fail(ptr, "expected an array of 3 numbers");
  return {number(j[0], ptr + "/0"), number(j[1], ptr + "/1"), number(j[2], ptr + "/2")};
}

glm::vec3 direction(const json& j, const std::string& ptr) {
  glm::vec3 d = vec3(j, ptr);
  if (glm::length(d) < 1e-12f) fail(ptr, "direction has zero length");
  return glm::normalize(d);
}

const json& array(const json& j, const std::string& ptr) {
  if (!j.is_array()) fail(ptr, "expected an array, got " + typeName(j));
  return j;
}

// Checks `obj` is an object whose keys are all in `known` ("_..." keys are comments).
void object(const json& obj, const std::string& ptr, std::initializer_list<const char*> known) {
  if (!obj.is_object()) fail(ptr, "expected an object, got " + typeName(obj));
  for (const auto& [key, value] : obj.items()) {
    if (!key.empty() && key[0] == '_') continue;
    bool ok = false;
    for (const char* k : known) ok = ok || key == k;
    if (!ok) fail(ptr + "/" + key, "unknown key '" + key + "'");
  }
}

std::string at(const std::string& ptr, std::size_t i) { return ptr + "/" + std::to_string(i); }

// Object-to-world conversion for what the scene file holds: Z-up files turn to Y-up (x, y, z)
// -> (x, z, -y), then everything scales by unit_scale.
struct Conversion {
  float scale = 1.0f;
  glm::mat4 rotation{1.0f};
  glm::mat4 matrix() const { return glm::scale(glm::mat4(1.0f), glm::vec3(scale)) * rotation; }
  glm::vec3 point(glm::vec3 p) const { return glm::vec3(matrix() * glm::vec4(p, 1.0f)); }
  glm::vec3 dir(glm::vec3 d) const { return glm::vec3(rotation * glm::vec4(d, 0.0f)); }
};

void applyConversion(Scene& scene, const Conversion& c) {
  glm::mat4 m = c.matrix();
  for (Instance& inst : scene.instances) inst.transform = m * inst.transform;
  // The file's keyframed nodes move in the file's frame: the conversion follows them.
  for (Animation& a : scene.animations)
    if (a.kind == Animation::Kind::Keyframes) a.base = m * a.base;
  for (Light& l : scene.lights) {
    l.position = c.point(l.position);
    l.direction = glm::normalize(c.dir(l.direction));
    l.range *= c.scale;
  }
  for (Camera& cam : scene.cameras) {
    cam.position = c.point(cam.position);
    cam.forward = glm::normalize(c.dir(cam.forward));
    cam.up = glm::normalize(c.dir(cam.up));
  }
}

Light parseLight(const json& j, const std::string& ptr) {
  object(j, ptr,
         {"name", "type", "position", "direction", "target", "color", "intensity", "range",
          "inner_cone", "outer_cone", "animation"});
  Light l;
  if (!j.contains("type")) fail(ptr, "light has no 'type'");
  std::string type = string(j["type"], ptr + "/type");
  if (type == "point") {
    l.type = LightType::Point;
  } else if (type == "spot") {
    l.type = LightType::Spot;
  } else if (type == "directional") {
    l.type = LightType::Directional;
  } else {
    fail(ptr + "/type", "unknown light type '" + type + "' (expected point, spot or directional)");
  }
  if (j.contains("name")) l.name = string(j["name"], ptr + "/name");
  if (j.contains("position")) l.position = vec3(j["position"], ptr + "/position");
  if (j.contains("direction") && j.contains("target"))
    fail(ptr, "give either 'direction' or 'target', not both");
  if (j.contains("direction")) l.direction = direction(j["direction"], ptr + "/direction");
  if (j.contains("target")) {
    glm::vec3 d = vec3(j["target"], ptr + "/target") - l.position;
    if (glm::length(d) < 1e-12f) fail(ptr + "/target", "target equals position");
    l.direction = glm::normalize(d);
  }
  if (l.type != LightType::Point && !j.contains("direction") && !j.contains("target"))
    fail(ptr, type + " light needs a 'direction' or a 'target'");
  if (j.contains("color")) l.color = vec3(j["color"], ptr + "/color");
  if (j.contains("intensity")) l.intensity = number(j["intensity"], ptr + "/intensity");
  if (l.intensity < 0.0f) fail(ptr + "/intensity", "intensity is negative");
  if (j.contains("range")) l.range = number(j["range"], ptr + "/range");
  if (j.contains("inner_cone"))
    l.innerConeAngle = glm::radians(number(j["inner_cone"], ptr + "/inner_cone"));
  if (j.contains("outer_cone"))
    l.outerConeAngle = glm::radians(number(j["outer_cone"], ptr + "/outer_cone"));
  if (l.type == LightType::Spot && !(l.innerConeAngle <= l.outerConeAngle))
    fail(ptr, "inner_cone is larger than outer_cone");
  return l;
}

Camera parseCamera(const json& j, const std::string& ptr) {
  object(j, ptr, {"name", "position", "target", "yaw", "pitch", "fov"});
  Camera c;
  if (j.contains("name")) c.name = string(j["name"], ptr + "/name");
  if (!j.contains("position")) fail(ptr, "camera has no 'position'");
  c.position = vec3(j["position"], ptr + "/position");
  bool angles = j.contains("yaw") || j.contains("pitch");
  if (j.contains("target") == angles) fail(ptr, "give either 'target' or 'yaw'/'pitch'");
  if (j.contains("target")) {
    glm::vec3 d = vec3(j["target"], ptr + "/target") - c.position;
    if (glm::length(d) < 1e-12f) fail(ptr + "/target", "target equals position");
    c.forward = glm::normalize(d);
  } else {
    // yaw 0 looks down -Z, positive yaw turns toward +X; positive pitch looks up.
    float yaw = j.contains("yaw") ? glm::radians(number(j["yaw"], ptr + "/yaw")) : 0.0f;
    float pitch = j.contains("pitch") ? glm::radians(number(j["pitch"], ptr + "/pitch")) : 0.0f;
    c.forward = glm::vec3(std::sin(yaw) * std::cos(pitch), std::sin(pitch),
                          -std::cos(yaw) * std::cos(pitch));
  }
  // Up is world up made orthogonal to forward (a camera looking straight up keeps +Z's side).
  glm::vec3 right = glm::cross(c.forward, glm::vec3(0, 1, 0));
  if (glm::length(right) < 1e-6f) right = glm::vec3(1, 0, 0);
  c.up = glm::normalize(glm::cross(glm::normalize(right), c.forward));
  if (j.contains("fov")) {
    float fov = number(j["fov"], ptr + "/fov");
    if (!(fov > 0.0f && fov < 180.0f)) fail(ptr + "/fov", "fov must be in (0, 180) degrees");
    c.yfov = glm::radians(fov);
  }
  return c;
}

// A volume's own update settings (VolumeSettings): each key optional, range-checked, and an
// error that names the volume (its index in `volumes`) and the key.
VolumeSettings parseVolumeSettings(const json& j, const std::string& ptr, std::size_t index) {
  VolumeSettings s;
  const std::string volume = "volume " + std::to_string(index) + ": ";
  auto inRange = [&](const char* key, float lo, float hi, bool hiOpen) -> std::optional<float> {
    if (!j.contains(key)) return std::nullopt;
    const float v = number(j[key], ptr + "/" + key);
    if (v < lo || v > hi || (hiOpen && v == hi)) {
      std::ostringstream range;
      range << "[" << lo << ", " << hi << (hiOpen ? ")" : "]");
      fail(ptr + "/" + key,
           volume + key + " must be in " + range.str() + ", got " + std::to_string(v));
    }
    return v;
  };
  s.hysteresis = inRange("hysteresis", 0.0f, 1.0f, true);
  s.normalBias = inRange("normal_bias", 0.0f, 1.0f, false);
  s.viewBias = inRange("view_bias", 0.0f, 1.0f, false);
  s.blendMargin = inRange("blend_margin", 0.0f, 4.0f, false);
  if (j.contains("encoding")) {
    const json& e = j["encoding"];
    std::optional<ProbeEncoding> encoding;
    if (e.is_string()) encoding = parseProbeEncoding(e.get<std::string>());
    if (!encoding)
      fail(ptr + "/encoding",
           volume + "encoding must be \"octahedral\", \"sh1\" or \"sh2\", got " + e.dump());
    s.encoding = encoding;
  }
  if (j.contains("max_ray_distance")) {
    const float v = number(j["max_ray_distance"], ptr + "/max_ray_distance");
    if (!(v > 0.0f))
      fail(ptr + "/max_ray_distance",
           volume + "max_ray_distance must be positive (world units), got " + std::to_string(v));
    s.maxRayDistance = v;
  }
  if (j.contains("follow")) {
    if (!j["follow"].is_boolean())
      fail(ptr + "/follow", volume + "follow must be true or false, got " + j["follow"].dump());
    s.follow = j["follow"].get<bool>();
  }
  // Every cascade is traced in one pass with one set of ray directions (both tracers).
  if (j.contains("rays_per_probe"))
    fail(ptr + "/rays_per_probe", volume +
                                      "rays_per_probe is the field's, not a volume's: give "
                                      "--rays to probecast-bake or probecast-server");
  return s;
}

ProbeVolume parseVolume(const json& j, const std::string& ptr, std::size_t index) {
  object(j, ptr,
         {"origin", "spacing", "counts", "min", "max", "hysteresis", "normal_bias", "view_bias",
          "max_ray_distance", "blend_margin", "rays_per_probe", "encoding", "follow"});
  ProbeVolume v;
  v.settings = parseVolumeSettings(j, ptr, index);
  if (!j.contains("spacing")) fail(ptr, "volume has no 'spacing'");
  v.spacing = positive(j["spacing"], ptr + "/spacing");
  if (j.contains("origin")) {
    if (j.contains("min") || j.contains("max")) fail(ptr, "give origin+counts or min+max");
    v.origin = vec3(j["origin"], ptr + "/origin");
    if (!j.contains("counts")) fail(ptr, "volume with 'origin' needs 'counts'");
    glm::vec3 c = vec3(j["counts"], ptr + "/counts");
    for (int a = 0; a < 3; ++a) {
      if (c[a] < 1.0f || c[a] > 4096.0f || c[a] != std::floor(c[a]))
        fail(at(ptr + "/counts", a), "count must be an integer in [1, 4096]");
      v.counts[a] = int(c[a]);
    }
  } else {
    if (!j.contains("min") || !j.contains("max")) fail(ptr, "give origin+counts or min+max");
    if (j.contains("counts")) fail(ptr + "/counts", "'counts' goes with 'origin', not min/max");
    glm::vec3 lo = vec3(j["min"], ptr + "/min"), hi = vec3(j["max"], ptr + "/max");
    // As many probes as fit in the box at this spacing, the grid centred in the box.
    for (int a = 0; a < 3; ++a) {
      if (hi[a] < lo[a]) fail(at(ptr + "/max", a), "max is below min");
      float n = std::floor((hi[a] - lo[a]) / v.spacing + 1e-4f) + 1.0f;
      if (n > 4096.0f) fail(ptr + "/spacing", "more than 4096 probes along an axis");
      v.counts[a] = int(n);
    }
    v.origin = 0.5f * (lo + hi) - 0.5f * v.spacing * glm::vec3(v.counts - 1);
  }
  return v;
}

Sky parseSky(const json& j, const std::string& ptr) {
  object(j, ptr, {"color", "zenith", "horizon", "ground", "intensity"});
  Sky s;
  if (j.contains("color")) {
    if (j.contains("zenith") || j.contains("horizon") || j.contains("ground"))
      fail(ptr, "give either 'color' or zenith/horizon/ground");
    s.zenith = s.horizon = s.ground = vec3(j["color"], ptr + "/color");
  }
  if (j.contains("zenith")) s.zenith = vec3(j["zenith"], ptr + "/zenith");
  if (j.contains("horizon")) s.horizon = vec3(j["horizon"], ptr + "/horizon");
  if (j.contains("ground")) s.ground = vec3(j["ground"], ptr + "/ground");
  if (j.contains("intensity")) {
    float k = number(j["intensity"], ptr + "/intensity");
    s.zenith *= k;
    s.horizon *= k;
    s.ground *= k;
  }
  return s;
}

// Parses one animation; its targets (light and instance names) are resolved by the caller.
Animation parseAnimation(const json& j, const std::string& ptr) {
  object(j, ptr,
         {"name", "type", "points", "period", "axis", "pivot", "degrees_per_second", "lights",
          "instances"});
  Animation a;
  if (!j.contains("type")) fail(ptr, "animation has no 'type'");
  std::string type = string(j["type"], ptr + "/type");
  if (type == "path") {
    a.kind = Animation::Kind::Path;
    if (!j.contains("points")) fail(ptr, "path animation has no 'points'");
    const json& pts = array(j["points"], ptr + "/points");
    if (pts.empty()) fail(ptr + "/points", "path has no points");
    for (std::size_t i = 0; i < pts.size(); ++i)
      a.points.push_back(vec3(pts[i], at(ptr + "/points", i)));
    if (j.contains("period")) a.period = positive(j["period"], ptr + "/period");
  } else if (type == "rotate") {
    a.kind = Animation::Kind::Rotate;
    if (j.contains("axis")) a.axis = direction(j["axis"], ptr + "/axis");
    if (j.contains("pivot")) a.pivot = vec3(j["pivot"], ptr + "/pivot");
    if (j.contains("degrees_per_second"))
      a.radiansPerSecond =
          glm::radians(number(j["degrees_per_second"], ptr + "/degrees_per_second"));
  } else {
    fail(ptr + "/type", "unknown animation type '" + type + "' (expected path or rotate)");
  }
  return a;
}

// Float in [0, 1] at `ptr`.
float unitInterval(const json& j, const std::string& ptr) {
  const float v = number(j, ptr);
  if (v < 0.0f || v > 1.0f) fail(ptr, "expected a number in [0, 1], got " + std::to_string(v));
  return v;
}

// materials[]: per material name, metallic and roughness that replace the file's. The value
// given is uniform over the surface: the material's metallic-roughness texture is dropped.
void applyMaterialOverrides(Scene& scene, const json& list) {
  for (std::size_t i = 0; i < list.size(); ++i) {
    const std::string ptr = at("/materials", i);
    const json& j = list[i];
    object(j, ptr, {"name", "metallic", "roughness"});
    if (!j.contains("name")) fail(ptr, "a material override needs a name");
    const std::string name = string(j["name"], ptr + "/name");
    bool found = false;
    for (Material& m : scene.materials) {
      if (m.name != name) continue;
      found = true;
      if (j.contains("metallic")) m.metallic = unitInterval(j["metallic"], ptr + "/metallic");
      if (j.contains("roughness")) m.roughness = unitInterval(j["roughness"], ptr + "/roughness");
      m.metallicRoughnessTexture = -1;
    }
    if (!found) fail(ptr + "/name", "no material named '" + name + "'");
  }
}

bool instanceMatches(const Scene& scene, const Instance& inst, const std::string& name) {
  if (inst.name == name) return true;
  if (inst.mesh < 0 || std::size_t(inst.mesh) >= scene.meshes.size()) return false;
  const std::string& mesh = scene.meshes[inst.mesh].name;
  // "chair" names every primitive mesh "chair/0", "chair/1", ... made from glTF mesh "chair".
  return mesh == name || (mesh.size() > name.size() && mesh.compare(0, name.size(), name) == 0 &&
                          mesh[name.size()] == '/');
}

void applyJson(Scene& scene, const json& root) {
  object(root, "",
         {"unit_scale", "up_axis", "exposure", "emissive_mode", "sky", "lights", "keep_file_lights",
          "cameras", "volumes", "animations", "materials"});
  Conversion conv;
  if (root.contains("unit_scale")) conv.scale = positive(root["unit_scale"], "/unit_scale");
  if (root.contains("up_axis")) {
    std::string up = string(root["up_axis"], "/up_axis");
    if (up == "z" || up == "Z") {
      conv.rotation = glm::rotate(glm::mat4(1.0f), glm::radians(-90.0f), glm::vec3(1, 0, 0));
    } else if (up != "y" && up != "Y") {
      fail("/up_axis", "unknown up axis '" + up + "' (expected \"y\" or \"z\")");
    }
  }
  applyConversion(scene, conv);

  if (root.contains("exposure")) scene.exposure = positive(root["exposure"], "/exposure");
  if (root.contains("emissive_mode")) {
    std::string m = string(root["emissive_mode"], "/emissive_mode");
    if (m == "auto") {
      scene.emissiveMode = EmissiveMode::Auto;
    } else if (m == "lights") {
      scene.emissiveMode = EmissiveMode::Lights;
    } else if (m == "field") {
      scene.emissiveMode = EmissiveMode::Field;
    } else {
      fail("/emissive_mode", "unknown emissive mode '" + m + "' (expected auto, lights or field)");
    }
  }
  if (root.contains("sky")) scene.sky = parseSky(root["sky"], "/sky");
  if (root.contains("materials"))
    applyMaterialOverrides(scene, array(root["materials"], "/materials"));

  if (root.contains("keep_file_lights")) {
    if (!root["keep_file_lights"].is_boolean())
      fail("/keep_file_lights",
           "expected true or false, got " + typeName(root["keep_file_lights"]));
    if (!root["keep_file_lights"].get<bool>()) scene.lights.clear();
  }
  // Light animation names are resolved once all animations are known.
  struct Pending {
    std::size_t light;
    std::string name, pointer;
  };
  std::vector<Pending> lightAnimations;
  if (root.contains("lights")) {
    const json& lights = array(root["lights"], "/lights");
    for (std::size_t i = 0; i < lights.size(); ++i) {
      std::string ptr = at("/lights", i);
      scene.lights.push_back(parseLight(lights[i], ptr));
      if (lights[i].contains("animation"))
        lightAnimations.push_back({scene.lights.size() - 1,
                                   string(lights[i]["animation"], ptr + "/animation"),
                                   ptr + "/animation"});
    }
  }
  if (root.contains("cameras")) {
    // Sidecar cameras come first: cameras[0] is every tool's default view.
    const json& cams = array(root["cameras"], "/cameras");
    std::vector<Camera> mine;
    for (std::size_t i = 0; i < cams.size(); ++i)
      mine.push_back(parseCamera(cams[i], at("/cameras", i)));
    scene.cameras.insert(scene.cameras.begin(), mine.begin(), mine.end());
  }
  if (root.contains("volumes")) {
    const json& vols = array(root["volumes"], "/volumes");
    scene.volumes.clear();
    for (std::size_t i = 0; i < vols.size(); ++i)
      scene.volumes.push_back(parseVolume(vols[i], at("/volumes", i), i));
    if (vols.size() > std::size_t(gpu::PC_MAX_CASCADES))
      fail("/volumes", std::to_string(vols.size()) + " volumes; a field has at most " +
                           std::to_string(gpu::PC_MAX_CASCADES) + " cascades");
    for (std::size_t i = 1; i < scene.volumes.size(); ++i)
      if (scene.volumes[i].spacing < scene.volumes[i - 1].spacing)
        fail(at("/volumes", i) + "/spacing", "cascades must be ordered finest first");
    // Every probe holds about 4 KB of atlases on every machine that holds the field: checked
    // here, before anything is allocated for it.
    std::uint64_t probes = 0;
    for (std::size_t i = 0; i < scene.volumes.size(); ++i) {
      const glm::ivec3 n = scene.volumes[i].counts;
      probes += std::uint64_t(n.x) * std::uint64_t(n.y) * std::uint64_t(n.z);
      if (probes > kMaxSidecarProbes)
        fail(at("/volumes", i),
             "the volumes hold " + std::to_string(probes) + " probes up to here; at most " +
                 std::to_string(kMaxSidecarProbes) + " in all (each holds about 4 KB of atlases)");
    }
  }

  // The sidecar's animations follow those the scene file brought (glTF keyframes).
  const int firstAnimation = int(scene.animations.size());
  std::vector<std::string> animationNames;
  if (root.contains("animations")) {
    const json& anims = array(root["animations"], "/animations");
    for (std::size_t i = 0; i < anims.size(); ++i) {
      std::string ptr = at("/animations", i);
      Animation a = parseAnimation(anims[i], ptr);
      int index = int(scene.animations.size());
      scene.animations.push_back(a);
      animationNames.push_back(anims[i].contains("name") ? string(anims[i]["name"], ptr + "/name")
                                                         : std::string());
      if (anims[i].contains("lights")) {
        const json& names = array(anims[i]["lights"], ptr + "/lights");
        for (std::size_t k = 0; k < names.size(); ++k) {
          std::string name = string(names[k], at(ptr + "/lights", k));
          bool found = false;
          for (Light& l : scene.lights)
            if (l.name == name) l.animation = index, found = true;
          if (!found) fail(at(ptr + "/lights", k), "no light named '" + name + "'");
        }
      }
      if (anims[i].contains("instances")) {
        const json& names = array(anims[i]["instances"], ptr + "/instances");
        for (std::size_t k = 0; k < names.size(); ++k) {
          std::string name = string(names[k], at(ptr + "/instances", k));
          bool found = false;
          for (Instance& inst : scene.instances)
            if (instanceMatches(scene, inst, name)) inst.animation = index, found = true;
          if (!found) fail(at(ptr + "/instances", k), "no node or mesh named '" + name + "'");
        }
      }
    }
  }
  for (const Pending& p : lightAnimations) {
    int found = -1;
    for (std::size_t i = 0; i < animationNames.size(); ++i)
      if (animationNames[i] == p.name) found = int(i);
    if (found < 0) fail(p.pointer, "no animation named '" + p.name + "'");
    scene.lights[p.light].animation = firstAnimation + found;
  }
}

}  // namespace

Status applySidecar(Scene& scene, const fs::path& sidecar) {
  const std::string file = sidecar.string();
  std::ifstream in(sidecar, std::ios::binary);
  if (!in) return Error{file + ": cannot open sidecar"};
  std::stringstream text;
  text << in.rdbuf();
  json root;
  try {
    root = json::parse(text.str(), nullptr, true, /*ignore_comments=*/true);
  } catch (const json::exception& e) {
    // parse_error, or out_of_range for a number beyond double's range ("1e400").
    // Drop nlohmann's "[json.exception.parse_error.101] " tag; keep line and column.
    std::string what = e.what();
    if (auto p = what.find("] "); what.rfind("[json.exception", 0) == 0 && p != std::string::npos)
      what = what.substr(p + 2);
    return Error{file + ": invalid JSON: " + what};
  }
  try {
    applyJson(scene, root);
  } catch (const SidecarError& e) {
    return Error{file + ": at " + e.pointer + ": " + e.message};
  } catch (const json::exception& e) {
    return Error{file + ": " + e.what()};
  }
  return Status::success();
}

}  // namespace pc::scene_detail

namespace pc {

std::string sidecarReport(const Scene& scene) {
  if (!scene.sidecar.empty()) return "scene " + scene.name + ": sidecar " + scene.sidecar.string();
  if (scene.source.empty()) return "scene " + scene.name + ": built in, no sidecar";
  std::string where = (scene.source.parent_path() / "scene.json").string();
  for (const std::filesystem::path& f : scene_detail::sidecarFolders()) where += ", " + f.string();
  return "scene " + scene.name + ": no sidecar (looked for " + where + ")";
}

std::optional<ProbeEncoding> parseProbeEncoding(std::string_view name) {
  if (name == "octahedral") return ProbeEncoding::Octahedral;
  if (name == "sh1") return ProbeEncoding::Sh1;
  if (name == "sh2") return ProbeEncoding::Sh2;
  return std::nullopt;
}

const char* probeEncodingName(ProbeEncoding encoding) {
  switch (encoding) {
    case ProbeEncoding::Sh1:
      return "sh1";
    case ProbeEncoding::Sh2:
      return "sh2";
    case ProbeEncoding::Octahedral:
      break;
  }
  return "octahedral";
}

}  // namespace pc
