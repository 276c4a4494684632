// glTF 2.0 (.gltf, .glb) through tinygltf: triangle primitives (one pc::Mesh each), the node
// hierarchy, base colour and emission (with their textures), normal maps with their tangents,
// KHR_lights_punctual, perspective cameras and node animations (translation, rotation, scale);
// what else a file holds is named in warnings (scene_gltf_unused.h). Every index the file holds
// is checked before it is followed.
#include <stb_image.h>  // declarations only; the implementation is in scene_model.cpp
#include <tiny_gltf.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <limits>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <tuple>

#include "common/scene_gltf_unused.h"
#include "common/scene_loaders.h"

namespace pc::scene_detail {

namespace {

// Extensions whose meaning we honour (or that change nothing we read); a file that requires
// any other one cannot be shown correctly and is refused.
// (ior and specular only shape specular reflection, which diffuse GI does not use.)
const std::set<std::string> kSupportedExtensions = {
    "KHR_lights_punctual", "KHR_materials_emissive_strength", "KHR_mesh_quantization",
    "KHR_materials_ior",   "KHR_materials_specular",          "KHR_texture_transform",
};

// Thrown inside this file only, turned into an Error at loadGltf's boundary.
struct GltfError {
  std::string message;
};

class GltfReader {
 public:
  GltfReader(const tinygltf::Model& model, Scene& scene, const SceneLoadOptions& options)
      : m_(model), scene_(scene), options_(options) {}

  void readScene() {
    int sceneIndex = m_.defaultScene >= 0 ? m_.defaultScene : 0;
    std::vector<int> roots;
    if (!m_.scenes.empty()) {
      check(sceneIndex, m_.scenes.size(), "scene");
      roots = m_.scenes[sceneIndex].nodes;
    } else {
      // No scene list: every node that is nobody's child is a root.
      std::vector<bool> isChild(m_.nodes.size(), false);
      for (const auto& n : m_.nodes)
        for (int c : n.children)
          if (c >= 0 && std::size_t(c) < isChild.size()) isChild[c] = true;
      for (std::size_t i = 0; i < m_.nodes.size(); ++i)
        if (!isChild[i]) roots.push_back(int(i));
    }
    readAnimations();
    for (int r : roots) visit(r, glm::mat4(1.0f), 0);
  }

 private:
  static void check(int index, std::size_t size, const char* what) {
    if (index < 0 || std::size_t(index) >= size)
      throw GltfError{std::string(what) + " index " + std::to_string(index) + " out of range (" +
                      std::to_string(size) + " " + what + "s)"};
  }

  static glm::mat4 localMatrix(const tinygltf::Node& n) {
    if (n.matrix.size() == 16) {
      float v[16];
      for (int i = 0; i < 16; ++i) v[i] = float(n.matrix[i]);
      return glm::make_mat4(v);  // glTF matrices are column-major, as glm's
    }
    glm::mat4 t(1.0f), r(1.0f), s(1.0f);
    if (n.translation.size() == 3)
      t = glm::translate(
          glm::mat4(1.0f),
          glm::vec3(float(n.translation[0]), float(n.translation[1]), float(n.translation[2])));
    if (n.rotation.size() == 4) {
      glm::quat q(float(n.rotation[3]), float(n.rotation[0]), float(n.rotation[1]),
                  float(n.rotation[2]));
      r = glm::mat4_cast(glm::normalize(q));
    }
    if (n.scale.size() == 3)
      s = glm::scale(glm::mat4(1.0f),
                     glm::vec3(float(n.scale[0]), float(n.scale[1]), float(n.scale[2])));
    return t * r * s;
  }

  void visit(int nodeIndex, const glm::mat4& parent, int depth) {
    check(nodeIndex, m_.nodes.size(), "node");
    // A cycle in the hierarchy would recurse forever; real files are far shallower.
    if (depth > 256) throw GltfError{"node hierarchy deeper than 256 (a cycle?)"};
    // Nodes that list one child twice, level after level, make a few bytes of file visit
    // 2^depth nodes, each an instance: the visits are bounded as the depth is.
    if (++nodeVisits_ > kMaxNodeVisits)
      throw GltfError{"node hierarchy reaches more than " + std::to_string(kMaxNodeVisits) +
                      " nodes (nodes reached through many paths?)"};
    const tinygltf::Node& node = m_.nodes[nodeIndex];
    glm::mat4 world = parent * localMatrix(node);
    std::string nodeName = node.name.empty() ? "node" + std::to_string(nodeIndex) : node.name;
    path_.push_back(nodeIndex);
    int animation = -2;  // made when the first instance or light of this visit needs it
    const auto animationHere = [&] {
      if (animation == -2) animation = chainAnimation();
      return animation;
    };

    if (node.mesh >= 0) {
      check(node.mesh, m_.meshes.size(), "mesh");
      for (int meshIndex : meshesFor(node.mesh)) {
        drawnTriangles_ += scene_.meshes[std::size_t(meshIndex)].triangleCount();
        if (Status s = checkTriangleLimit(
                "node '" + nodeName + "': the triangles drawn over all instances", drawnTriangles_,
                options_);
            !s)
          throw GltfError{s.error().message};
        Instance inst;
        inst.name = nodeName;
        inst.mesh = meshIndex;
        inst.transform = world;
        inst.animation = animationHere();
        scene_.instances.push_back(inst);
      }
    }
    if (node.camera >= 0) addCamera(node.camera, world, nodeName);
    auto ext = node.extensions.find("KHR_lights_punctual");
    if (ext != node.extensions.end() && ext->second.IsObject() && ext->second.Has("light")) {
      const tinygltf::Value& li = ext->second.Get("light");
      if (!li.IsNumber()) throw GltfError{"node '" + nodeName + "': light index is not a number"};
      addLight(int(li.GetNumberAsDouble()), world, nodeName);
      scene_.lights.back().animation = animationHere();
    }
    for (int child : node.children) visit(child, world, depth + 1);
    path_.pop_back();
  }

  // glTF animations: every channel that moves a node's translation, rotation or scale becomes
  // a track; all of the file's animations play at once from time 0, each looping on its own
  // length.
  void readAnimations() {
    auto tracks = std::make_shared<std::vector<KeyframeTrack>>();
    for (std::size_t ai = 0; ai < m_.animations.size(); ++ai) {
      const tinygltf::Animation& anim = m_.animations[ai];
      const std::string name =
          "animation '" + (anim.name.empty() ? std::to_string(ai) : anim.name) + "'";
      const std::size_t first = tracks->size();
      float period = 0.0f;
      for (const tinygltf::AnimationChannel& ch : anim.channels) {
        check(ch.sampler, anim.samplers.size(), "animation sampler");
        if (ch.target_node < 0) continue;  // glTF allows channels that target nothing
        check(ch.target_node, m_.nodes.size(), "node");
        KeyframeTrack k;
        if (ch.target_path == "translation") {
          k.property = KeyframeTrack::Property::Translation;
        } else if (ch.target_path == "rotation") {
          k.property = KeyframeTrack::Property::Rotation;
        } else if (ch.target_path == "scale") {
          k.property = KeyframeTrack::Property::Scale;
        } else {
          warnOnce(name + ": '" + ch.target_path + "' channels are not read (morph targets)");
          continue;
        }
        if (m_.nodes[std::size_t(ch.target_node)].matrix.size() == 16) {
          warnOnce(name + ": a channel moves node " + std::to_string(ch.target_node) +
                   ", which has a matrix (glTF forbids animating it); the channel is ignored");
          continue;
        }
        const tinygltf::AnimationSampler& sampler = anim.samplers[std::size_t(ch.sampler)];
        if (sampler.interpolation == "STEP") {
          k.interpolation = KeyframeTrack::Interpolation::Step;
        } else if (sampler.interpolation == "CUBICSPLINE") {
          k.interpolation = KeyframeTrack::Interpolation::CubicSpline;
        } else if (sampler.interpolation.empty() || sampler.interpolation == "LINEAR") {
          k.interpolation = KeyframeTrack::Interpolation::Linear;
        } else {
          throw GltfError{name + ": unknown interpolation '" + sampler.interpolation + "'"};
        }
        k.times = readFloats(sampler.input, 1, "animation input");
        for (std::size_t i = 0; i < k.times.size(); ++i)
          if (!std::isfinite(k.times[i]) || k.times[i] < 0.0f ||
              (i > 0 && !(k.times[i] > k.times[i - 1])))
            throw GltfError{name + ": key times must be finite, >= 0 and increasing (key " +
                            std::to_string(i) + " is " + std::to_string(k.times[i]) + ")"};
        const int comps = k.property == KeyframeTrack::Property::Rotation ? 4 : 3;
        const std::vector<float> v = readFloats(sampler.output, comps, "animation output");
        const std::size_t perKey =
            k.interpolation == KeyframeTrack::Interpolation::CubicSpline ? 3 : 1;
        if (k.times.empty() || v.size() != k.times.size() * perKey * std::size_t(comps))
          throw GltfError{name + ": a sampler has " + std::to_string(k.times.size()) +
                          " key times and " + std::to_string(v.size() / std::size_t(comps)) +
                          " values (expected " + std::to_string(perKey) + " per key)"};
        for (std::size_t i = 0; i < v.size(); i += std::size_t(comps)) {
          glm::vec4 value(v[i], v[i + 1], v[i + 2], comps == 4 ? v[i + 3] : 0.0f);
          if (!std::isfinite(value.x) || !std::isfinite(value.y) || !std::isfinite(value.z) ||
              !std::isfinite(value.w))
            throw GltfError{name + ": a key value is not finite"};
          k.values.push_back(value);
        }
        period = std::max(period, k.times.back());
        nodeTracks_[ch.target_node].push_back(int(tracks->size()));
        tracks->push_back(std::move(k));
      }
      for (std::size_t i = first; i < tracks->size(); ++i) (*tracks)[i].period = period;
    }
    if (!m_.skins.empty())
      scene_.warnings.push_back("the file's " + std::to_string(m_.skins.size()) +
                                " skin(s) are not read: skinned meshes stay in their bind pose");
    tracks_ = std::move(tracks);
  }

  // The animation that moves what the node being visited holds, when any node on the way
  // from its root is animated (the chain of path_), else -1.
  int chainAnimation() {
    bool moves = false;
    for (int n : path_) moves = moves || nodeTracks_.count(n) > 0;
    if (!moves) return -1;
    Animation a;
    a.kind = Animation::Kind::Keyframes;
    a.tracks = tracks_;
    for (int n : path_) {
      const tinygltf::Node& node = m_.nodes[std::size_t(n)];
      KeyframedNode k;
      if (node.matrix.size() == 16) {
        k.hasMatrix = true;
        k.matrix = localMatrix(node);
      }
      if (node.translation.size() == 3)
        k.translation = glm::vec3(node.translation[0], node.translation[1], node.translation[2]);
      if (node.rotation.size() == 4)
        k.rotation = glm::normalize(glm::quat(float(node.rotation[3]), float(node.rotation[0]),
                                              float(node.rotation[1]), float(node.rotation[2])));
      if (node.scale.size() == 3) k.scale = glm::vec3(node.scale[0], node.scale[1], node.scale[2]);
      if (auto it = nodeTracks_.find(n); it != nodeTracks_.end()) k.tracks = it->second;
      a.chain.push_back(std::move(k));
    }
    scene_.animations.push_back(std::move(a));
    return int(scene_.animations.size()) - 1;
  }

  void warnOnce(const std::string& message) {
    if (warned_.insert(message).second) scene_.warnings.push_back(message);
  }

  void addCamera(int index, const glm::mat4& world, const std::string& nodeName) {
    check(index, m_.cameras.size(), "camera");
    const tinygltf::Camera& c = m_.cameras[index];
    if (c.type != "perspective") return;  // orthographic views are not used by any renderer
    Camera cam;
    cam.name = c.name.empty() ? nodeName : c.name;
    cam.position = glm::vec3(world * glm::vec4(0, 0, 0, 1));
    cam.forward = glm::normalize(glm::vec3(world * glm::vec4(0, 0, -1, 0)));
    cam.up = glm::normalize(glm::vec3(world * glm::vec4(0, 1, 0, 0)));
    if (c.perspective.yfov > 0) {
      if (!(c.perspective.yfov < 3.14159265))
        throw GltfError{"camera '" + cam.name + "': yfov " + std::to_string(c.perspective.yfov) +
                        " radians is not below pi"};
      cam.yfov = float(c.perspective.yfov);
    }
    scene_.cameras.push_back(cam);
  }

  void addLight(int index, const glm::mat4& world, const std::string& nodeName) {
    check(index, m_.lights.size(), "light");
    const tinygltf::Light& l = m_.lights[index];
    Light light;
    light.name = l.name.empty() ? nodeName : l.name;
    if (l.type == "point") {
      light.type = LightType::Point;
    } else if (l.type == "spot") {
      light.type = LightType::Spot;
      light.innerConeAngle = float(l.spot.innerConeAngle);
      light.outerConeAngle = float(l.spot.outerConeAngle);
    } else if (l.type == "directional") {
      light.type = LightType::Directional;
    } else {
      throw GltfError{"light '" + light.name + "': unknown type '" + l.type + "'"};
    }
    // Intensity is taken as given (candela and lux read as W/sr and W/m^2): the sidecar's
    // exposure is where a scene is brought to a sensible brightness.
    if (l.color.size() == 3)
      light.color = glm::vec3(float(l.color[0]), float(l.color[1]), float(l.color[2]));
    light.intensity = float(l.intensity);
    // As the sidecar's lights are checked (docs/SCENES.md): values that would light nothing
    // sensible are errors, not silent nonsense.
    if (!std::isfinite(light.intensity) || light.intensity < 0.0f)
      throw GltfError{"light '" + light.name + "': intensity " + std::to_string(l.intensity) +
                      " is negative or not finite"};
    if (light.type == LightType::Spot &&
        !(light.innerConeAngle >= 0.0f && light.innerConeAngle <= light.outerConeAngle &&
          light.outerConeAngle <= 0.5f * 3.1415927f))
      throw GltfError{"light '" + light.name +
                      "': spot cones must be 0 <= inner <= outer <= pi/2 (inner " +
                      std::to_string(l.spot.innerConeAngle) + ", outer " +
                      std::to_string(l.spot.outerConeAngle) + ")"};
    light.range = float(l.range);
    light.position = glm::vec3(world * glm::vec4(0, 0, 0, 1));
    glm::vec3 dir = glm::vec3(world * glm::vec4(0, 0, -1, 0));  // lights shine along node -Z
    if (glm::length(dir) > 0.0f) light.direction = glm::normalize(dir);
    scene_.lights.push_back(light);
  }

  // pc meshes made from glTF mesh `index` (one per triangle primitive), built on first use.
  const std::vector<int>& meshesFor(int index) {
    auto it = meshCache_.find(index);
    if (it != meshCache_.end()) return it->second;
    std::vector<int> made;
    const tinygltf::Mesh& gm = m_.meshes[index];
    std::string base = gm.name.empty() ? "mesh" + std::to_string(index) : gm.name;
    for (std::size_t p = 0; p < gm.primitives.size(); ++p) {
      std::string name = gm.primitives.size() > 1 ? base + "/" + std::to_string(p) : base;
      Mesh mesh;
      mesh.name = name;
      try {
        if (!readPrimitive(gm.primitives[p], mesh)) continue;
      } catch (const GltfError& e) {
        throw GltfError{"mesh '" + name + "': " + e.message};
      }
      made.push_back(int(scene_.meshes.size()));
      scene_.meshes.push_back(std::move(mesh));
    }
    return meshCache_.emplace(index, std::move(made)).first->second;
  }

  // Reads accessor `index` as `comps` floats per element (integers normalised when flagged).
  std::vector<float> readFloats(int index, int comps, const char* what) {
    check(index, m_.accessors.size(), "accessor");
    const tinygltf::Accessor& a = m_.accessors[index];
    int have = tinygltf::GetNumComponentsInType(a.type);
    if (have != comps)
      throw GltfError{std::string(what) + " accessor " + std::to_string(index) + " has " +
                      std::to_string(have) + " components, expected " + std::to_string(comps)};
    if (a.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT &&
        a.componentType != TINYGLTF_COMPONENT_TYPE_BYTE &&
        a.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
        a.componentType != TINYGLTF_COMPONENT_TYPE_SHORT &&
        a.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT)
      throw GltfError{std::string(what) + " accessor " + std::to_string(index) +
                      " has component type " + std::to_string(a.componentType) +
                      " (glTF allows float, byte, short and their unsigned forms here)"};
    forEachElement(a, index,
                   [](const unsigned char*, std::size_t) {});  // checked before allocating
    std::vector<float> out(a.count * comps, 0.0f);
    forEachElement(a, index, [&](const unsigned char* src, std::size_t i) {
      for (int c = 0; c < comps; ++c) out[i * comps + c] = component(src, a, c);
    });
    return out;
  }

  std::vector<std::uint32_t> readIndices(int index) {
    check(index, m_.accessors.size(), "accessor");
    const tinygltf::Accessor& a = m_.accessors[index];
    if (tinygltf::GetNumComponentsInType(a.type) != 1)
      throw GltfError{"index accessor " + std::to_string(index) + " is not scalar"};
    forEachElement(a, index,
                   [](const unsigned char*, std::size_t) {});  // checked before allocating
    std::vector<std::uint32_t> out(a.count, 0);
    forEachElement(a, index, [&](const unsigned char* src, std::size_t i) {
      switch (a.componentType) {
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
          out[i] = src[0];
          break;
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
          std::uint16_t v;
          std::memcpy(&v, src, 2);
          out[i] = v;
          break;
        }
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
          std::memcpy(&out[i], src, 4);
          break;
        default:
          throw GltfError{"index accessor " + std::to_string(index) +
                          " has a non-integer component type"};
      }
    });
    return out;
  }

  static float component(const unsigned char* src, const tinygltf::Accessor& a, int c) {
    switch (a.componentType) {
      case TINYGLTF_COMPONENT_TYPE_FLOAT: {
        float v;
        std::memcpy(&v, src + 4 * c, 4);
        return v;
      }
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: {
        float v = float(src[c]);
        return a.normalized ? v / 255.0f : v;
      }
      case TINYGLTF_COMPONENT_TYPE_BYTE: {
        float v = float(std::int8_t(src[c]));
        return a.normalized ? std::max(v / 127.0f, -1.0f) : v;
      }
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
        std::uint16_t u;
        std::memcpy(&u, src + 2 * c, 2);
        return a.normalized ? float(u) / 65535.0f : float(u);
      }
      case TINYGLTF_COMPONENT_TYPE_SHORT: {
        std::int16_t s;
        std::memcpy(&s, src + 2 * c, 2);
        return a.normalized ? std::max(float(s) / 32767.0f, -1.0f) : float(s);
      }
      default:
        throw GltfError{"accessor has unsupported component type " +
                        std::to_string(a.componentType)};
    }
  }

  // The bytes of `count` elements of `elemSize`, `stride` apart, from `offset` in buffer view
  // `viewIndex`: checked to lie inside the view and its buffer (a truncated or lying file must
  // not make us read past the end), without overflow whatever the counts claim.
  const unsigned char* elements(int viewIndex, std::size_t offset, std::size_t count,
                                std::size_t elemSize, std::size_t stride, const std::string& what) {
    check(viewIndex, m_.bufferViews.size(), "bufferView");
    const tinygltf::BufferView& view = m_.bufferViews[viewIndex];
    check(view.buffer, m_.buffers.size(), "buffer");
    const tinygltf::Buffer& buf = m_.buffers[view.buffer];
    // The view first, so that no sum below can wrap around.
    if (view.byteOffset > buf.data.size() || view.byteLength > buf.data.size() - view.byteOffset)
      throw GltfError{"bufferView " + std::to_string(viewIndex) + " (offset " +
                      std::to_string(view.byteOffset) + ", length " +
                      std::to_string(view.byteLength) + ") lies past the end of buffer " +
                      std::to_string(view.buffer) + " (" + std::to_string(buf.data.size()) +
                      " bytes)"};
    const std::size_t limit = view.byteOffset + view.byteLength;
    bool fits = offset <= view.byteLength && elemSize <= view.byteLength - offset;
    if (fits && count > 1) {
      const std::size_t room = view.byteLength - offset - elemSize;  // for the other strides
      fits = stride == 0 || (count - 1) <= room / stride;
    }
    if (!fits) {
      const long double needs = (long double)view.byteOffset + (long double)offset +
                                (long double)stride * (long double)(count - 1) +
                                (long double)elemSize;
      throw GltfError{what + " reads past the end of buffer " + std::to_string(view.buffer) +
                      " (needs " +
                      std::to_string((unsigned long long)std::min<long double>(needs, 1.8e19L)) +
                      " bytes, has " + std::to_string(limit) + ")"};
    }
    return buf.data.data() + view.byteOffset + offset;
  }

  // Accessors without a buffer view are zeros (then sparse values): their counts cost memory
  // without bytes in the file to back them, so they are held to this many elements.
  static constexpr std::size_t kMaxUnbackedElements = std::size_t(1) << 26;

  // Checks accessor `index` whole (its elements and its sparse values lie inside their
  // buffers) and calls f(pointer to element i, i) for every element, then for every sparse
  // value with the index it replaces. Callers call it once with a no-op f before allocating
  // for a.count elements, so that a count no file backs is an error, not an allocation.
  template <typename F>
  void forEachElement(const tinygltf::Accessor& a, int index, F&& f) {
    const std::string what = "accessor " + std::to_string(index);
    const int compSize = tinygltf::GetComponentSizeInBytes(a.componentType);
    const int comps = tinygltf::GetNumComponentsInType(a.type);
    if (compSize <= 0 || comps <= 0)
      throw GltfError{what + " has an invalid component type " + std::to_string(a.componentType) +
                      " or type " + std::to_string(a.type)};
    const std::size_t elemSize = std::size_t(compSize) * std::size_t(comps);
    if (a.count == 0) return;
    if (a.bufferView >= 0) {
      check(a.bufferView, m_.bufferViews.size(), "bufferView");
      const std::size_t byteStride = m_.bufferViews[a.bufferView].byteStride;
      const std::size_t stride = byteStride ? byteStride : elemSize;
      const unsigned char* base =
          elements(a.bufferView, a.byteOffset, a.count, elemSize, stride, what);
      for (std::size_t i = 0; i < a.count; ++i) f(base + i * stride, i);
    } else if (a.count > kMaxUnbackedElements) {
      throw GltfError{what + " has " + std::to_string(a.count) +
                      " elements and no buffer view; at most " +
                      std::to_string(kMaxUnbackedElements) + " are read without one"};
    }
    if (!a.sparse.isSparse) return;
    // Sparse: `count` indices (strictly increasing, tightly packed) and as many values, each
    // replacing the element at its index.
    const std::string sw = what + " sparse";
    if (a.sparse.count <= 0 || std::size_t(a.sparse.count) > a.count)
      throw GltfError{sw + " count " + std::to_string(a.sparse.count) + " is not in 1.." +
                      std::to_string(a.count)};
    const std::size_t n = std::size_t(a.sparse.count);
    const int indexSize = tinygltf::GetComponentSizeInBytes(a.sparse.indices.componentType);
    if (a.sparse.indices.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
        a.sparse.indices.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
        a.sparse.indices.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)
      throw GltfError{sw + " indices have component type " +
                      std::to_string(a.sparse.indices.componentType) + ", not an unsigned integer"};
    if (a.sparse.indices.byteOffset < 0 || a.sparse.values.byteOffset < 0)
      throw GltfError{sw + " has a negative byte offset"};
    const unsigned char* indices =
        elements(a.sparse.indices.bufferView, std::size_t(a.sparse.indices.byteOffset), n,
                 std::size_t(indexSize), std::size_t(indexSize), sw + " indices");
    const unsigned char* values =
        elements(a.sparse.values.bufferView, std::size_t(a.sparse.values.byteOffset), n, elemSize,
                 elemSize, sw + " values");
    for (std::size_t k = 0; k < n; ++k) {
      const unsigned char* at = indices + k * std::size_t(indexSize);
      std::uint32_t i = 0;
      if (indexSize == 1) {
        i = at[0];
      } else if (indexSize == 2) {
        std::uint16_t v;
        std::memcpy(&v, at, 2);
        i = v;
      } else {
        std::memcpy(&i, at, 4);
      }
      if (i >= a.count)
        throw GltfError{sw + " index " + std::to_string(i) + " (at " + std::to_string(k) +
                        ") out of range (" + std::to_string(a.count) + " elements)"};
      f(values + k * elemSize, std::size_t(i));
    }
  }

  // Where a material's textures take their coordinates from: a TEXCOORD set and, with
  // KHR_texture_transform, an affine map (scale, then rotation about the origin, then offset,
  // as the extension specifies). Meshes keep one set of coordinates, so the map is applied on
  // load: the base colour texture's, else the emissive texture's, else the normal texture's;
  // a texture whose coordinates differ follows the first one's, with a warning.
  struct UvSource {
    int set = 0;
    glm::vec2 offset{0.0f}, scale{1.0f};
    float rotation = 0.0f;
    bool operator==(const UvSource&) const = default;
    glm::vec2 apply(glm::vec2 uv) const {
      const glm::vec2 s = uv * scale;
      const float c = std::cos(rotation), n = std::sin(rotation);
      return glm::vec2(c * s.x - n * s.y, n * s.x + c * s.y) + offset;
    }
  };

  static UvSource uvSourceOf(int texCoord, const tinygltf::ExtensionMap& extensions) {
    UvSource uv;
    uv.set = std::max(texCoord, 0);
    auto ext = extensions.find("KHR_texture_transform");
    if (ext == extensions.end() || !ext->second.IsObject()) return uv;
    const tinygltf::Value& t = ext->second;
    auto vec2 = [&](const char* key, glm::vec2& out) {
      if (!t.Has(key) || !t.Get(key).IsArray() || t.Get(key).ArrayLen() != 2) return;
      for (int i = 0; i < 2; ++i)
        if (t.Get(key).Get(i).IsNumber()) out[i] = float(t.Get(key).Get(i).GetNumberAsDouble());
    };
    vec2("offset", uv.offset);
    vec2("scale", uv.scale);
    if (t.Has("rotation") && t.Get("rotation").IsNumber())
      uv.rotation = float(t.Get("rotation").GetNumberAsDouble());
    if (t.Has("texCoord") && t.Get("texCoord").IsInt())
      uv.set = std::max(t.Get("texCoord").GetNumberAsInt(), 0);
    return uv;
  }

  UvSource uvSourceOf(int gltfMaterial) {
    if (gltfMaterial < 0 || std::size_t(gltfMaterial) >= m_.materials.size()) return {};
    const tinygltf::Material& gm = m_.materials[gltfMaterial];
    const tinygltf::TextureInfo& base = gm.pbrMetallicRoughness.baseColorTexture;
    const tinygltf::TextureInfo& emissive = gm.emissiveTexture;
    const tinygltf::NormalTextureInfo& normal = gm.normalTexture;
    const tinygltf::TextureInfo& metalRough = gm.pbrMetallicRoughness.metallicRoughnessTexture;
    struct Use {
      const char* what;
      int index;
      UvSource uv;
    };
    const Use uses[] = {
        {"base colour", base.index, uvSourceOf(base.texCoord, base.extensions)},
        {"emissive", emissive.index, uvSourceOf(emissive.texCoord, emissive.extensions)},
        {"normal", normal.index, uvSourceOf(normal.texCoord, normal.extensions)},
        {"metallic-roughness", metalRough.index,
         uvSourceOf(metalRough.texCoord, metalRough.extensions)}};
    const Use* first = nullptr;
    for (const Use& use : uses) {
      if (use.index < 0) continue;
      if (!first) {
        first = &use;
      } else if (!(use.uv == first->uv)) {
        warnOnce("material '" + gm.name + "': its " + use.what +
                 " texture's coordinates (set or KHR_texture_transform) differ from its " +
                 first->what + " texture's; the " + first->what + "'s are used for both");
      }
    }
    return first ? first->uv : UvSource{};
  }

  // Whether glTF material `gltfMaterial` has a normal map (its meshes keep their tangents).
  bool hasNormalMap(int gltfMaterial) const {
    return gltfMaterial >= 0 && std::size_t(gltfMaterial) < m_.materials.size() &&
           m_.materials[std::size_t(gltfMaterial)].normalTexture.index >= 0;
  }

  // False for primitives that hold no triangles (points, lines).
  bool readPrimitive(const tinygltf::Primitive& prim, Mesh& mesh) {
    int mode = prim.mode < 0 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
    if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP &&
        mode != TINYGLTF_MODE_TRIANGLE_FAN)
      return false;
    auto pos = prim.attributes.find("POSITION");
    if (pos == prim.attributes.end()) throw GltfError{"primitive has no POSITION"};
    // The triangle count from the accessor counts, before anything is allocated for them.
    const int cornersFrom = prim.indices >= 0 ? prim.indices : pos->second;
    check(cornersFrom, m_.accessors.size(), "accessor");
    const std::uint64_t corners = m_.accessors[std::size_t(cornersFrom)].count;
    storedTriangles_ += mode == TINYGLTF_MODE_TRIANGLES ? corners / 3
                        : corners > 2                   ? corners - 2
                                                        : 0;
    if (Status s =
            checkTriangleLimit("the triangles of the meshes so far", storedTriangles_, options_);
        !s)
      throw GltfError{s.error().message};
    std::vector<float> p = readFloats(pos->second, 3, "POSITION");
    std::size_t n = p.size() / 3;
    mesh.positions.resize(n);
    for (std::size_t i = 0; i < n; ++i) mesh.positions[i] = {p[3 * i], p[3 * i + 1], p[3 * i + 2]};
    if (auto it = prim.attributes.find("NORMAL"); it != prim.attributes.end()) {
      std::vector<float> v = readFloats(it->second, 3, "NORMAL");
      if (v.size() == p.size()) {
        mesh.normals.resize(n);
        for (std::size_t i = 0; i < n; ++i)
          mesh.normals[i] = {v[3 * i], v[3 * i + 1], v[3 * i + 2]};
      }
    }
    const UvSource uv = uvSourceOf(prim.material);
    const std::string uvName = "TEXCOORD_" + std::to_string(uv.set);
    if (auto it = prim.attributes.find(uvName); it != prim.attributes.end()) {
      std::vector<float> v = readFloats(it->second, 2, uvName.c_str());
      if (v.size() == 2 * n) {
        mesh.uvs.resize(n);
        for (std::size_t i = 0; i < n; ++i) mesh.uvs[i] = uv.apply({v[2 * i], v[2 * i + 1]});
      }
    }
    // Tangents only matter under a normal map; without one they would only cost memory.
    // Unusable ones (zero, not finite) are generated again on load (generateTangents).
    if (auto it = prim.attributes.find("TANGENT");
        it != prim.attributes.end() && hasNormalMap(prim.material)) {
      std::vector<float> v = readFloats(it->second, 4, "TANGENT");
      if (v.size() == 4 * n) {
        mesh.tangents.resize(n);
        for (std::size_t i = 0; i < n; ++i)
          mesh.tangents[i] = {v[4 * i], v[4 * i + 1], v[4 * i + 2], v[4 * i + 3]};
      }
    }
    std::vector<std::uint32_t> idx;
    if (prim.indices >= 0) {
      idx = readIndices(prim.indices);
    } else {
      idx.resize(n);
      for (std::size_t i = 0; i < n; ++i) idx[i] = std::uint32_t(i);
    }
    mesh.indices = toTriangleList(idx, mode);
    mesh.material = materialFor(prim.material);
    return true;
  }

  static std::vector<std::uint32_t> toTriangleList(const std::vector<std::uint32_t>& idx,
                                                   int mode) {
    if (mode == TINYGLTF_MODE_TRIANGLES) {
      std::vector<std::uint32_t> out = idx;
      out.resize(idx.size() / 3 * 3);  // a trailing partial triangle is dropped
      return out;
    }
    std::vector<std::uint32_t> out;
    for (std::size_t i = 2; i < idx.size(); ++i) {
      if (mode == TINYGLTF_MODE_TRIANGLE_FAN) {
        out.insert(out.end(), {idx[0], idx[i - 1], idx[i]});
      } else if (i % 2 == 0) {  // strips alternate winding to keep it consistent
        out.insert(out.end(), {idx[i - 2], idx[i - 1], idx[i]});
      } else {
        out.insert(out.end(), {idx[i - 1], idx[i - 2], idx[i]});
      }
    }
    return out;
  }

  int materialFor(int gltfMaterial) {
    if (gltfMaterial < 0) {
      if (defaultMaterial_ < 0) {
        defaultMaterial_ = int(scene_.materials.size());
        Material d;
        d.name = "default";
        scene_.materials.push_back(d);
      }
      return defaultMaterial_;
    }
    check(gltfMaterial, m_.materials.size(), "material");
    auto it = materialCache_.find(gltfMaterial);
    if (it != materialCache_.end()) return it->second;
    const tinygltf::Material& gm = m_.materials[gltfMaterial];
    Material mat;
    mat.name = gm.name.empty() ? "material" + std::to_string(gltfMaterial) : gm.name;
    const auto& bc = gm.pbrMetallicRoughness.baseColorFactor;
    if (bc.size() >= 3) mat.baseColor = glm::vec3(float(bc[0]), float(bc[1]), float(bc[2]));
    mat.baseColorTexture = textureFor(gm.pbrMetallicRoughness.baseColorTexture.index);
    readMetallicRoughness(gm.pbrMetallicRoughness, mat);
    const auto& ef = gm.emissiveFactor;
    if (ef.size() == 3) mat.emissive = glm::vec3(float(ef[0]), float(ef[1]), float(ef[2]));
    auto strength = gm.extensions.find("KHR_materials_emissive_strength");
    if (strength != gm.extensions.end() && strength->second.IsObject() &&
        strength->second.Has("emissiveStrength") &&
        strength->second.Get("emissiveStrength").IsNumber())
      mat.emissive *= float(strength->second.Get("emissiveStrength").GetNumberAsDouble());
    // An emissive texture without a factor means nothing in glTF (factor defaults to 0).
    if (mat.isEmissive()) mat.emissiveTexture = textureFor(gm.emissiveTexture.index);
    // The normal map holds directions, not colours: read as linear data. Its scale stretches
    // the map's x and y (glTF).
    if (const tinygltf::NormalTextureInfo& normal = gm.normalTexture; normal.index != -1) {
      if (normal.index < 0 || std::size_t(normal.index) >= m_.textures.size())
        throw GltfError{"material '" + mat.name + "': normalTexture index " +
                        std::to_string(normal.index) + " out of range (" +
                        std::to_string(m_.textures.size()) + " textures)"};
      if (!std::isfinite(normal.scale))
        throw GltfError{"material '" + mat.name + "': normalTexture scale is not finite"};
      mat.normalTexture = textureFor(normal.index, true);
      mat.normalScale = float(normal.scale);
    }
    // MASK: a cut-out at alphaCutoff. BLEND (partial transparency) is not modelled; it is
    // drawn as a cut-out at 0.5 (every tracer and renderer alike), which keeps mostly
    // transparent surfaces such as glass from blocking light, and said once per material.
    if (gm.alphaMode == "MASK" || gm.alphaMode == "BLEND") {
      const bool mask = gm.alphaMode == "MASK";
      mat.alphaCutoff = mask ? std::max(float(gm.alphaCutoff), 1e-6f) : 0.5f;
      mat.baseAlpha = bc.size() >= 4 ? float(bc[3]) : 1.0f;
      mat.alphaTexture = mat.baseColorTexture;
      mat.alphaChannel = 3;
      // Without a texture the test has one answer everywhere: opaque needs no test.
      if (mat.alphaTexture < 0 && mat.baseAlpha >= mat.alphaCutoff) mat.alphaCutoff = 0.0f;
      if (!mask)
        scene_.warnings.push_back("material '" + mat.name +
                                  "': alphaMode BLEND drawn as a cut-out at alpha 0.5");
    }
    int out = int(scene_.materials.size());
    scene_.materials.push_back(mat);
    materialCache_[gltfMaterial] = out;
    return out;
  }

  // glTF's metallic-roughness factors (defaults 1 and 1, as the specification gives them,
  // whether or not the file writes pbrMetallicRoughness) and texture (linear data: B metallic,
  // G roughness). Factors must be finite; they are clamped to [0, 1].
  void readMetallicRoughness(const tinygltf::PbrMetallicRoughness& pbr, Material& mat) {
    if (!std::isfinite(pbr.metallicFactor) || !std::isfinite(pbr.roughnessFactor))
      throw GltfError{"material '" + mat.name +
                      "': metallicFactor or roughnessFactor is not finite"};
    mat.metallic = std::clamp(float(pbr.metallicFactor), 0.0f, 1.0f);
    mat.roughness = std::clamp(float(pbr.roughnessFactor), 0.0f, 1.0f);
    if (const int index = pbr.metallicRoughnessTexture.index; index != -1) {
      if (index < 0 || std::size_t(index) >= m_.textures.size())
        throw GltfError{"material '" + mat.name + "': metallicRoughnessTexture index " +
                        std::to_string(index) + " out of range (" +
                        std::to_string(m_.textures.size()) + " textures)"};
      mat.metallicRoughnessTexture = textureFor(index, true);
    }
  }

  // Scene texture index for glTF texture `index`, or -1 (with a warning) if its image is
  // missing or could not be decoded. `linear`: the texels are data (normal maps), not sRGB.
  int textureFor(int index, bool linear = false) {
    if (index < 0) return -1;
    check(index, m_.textures.size(), "texture");
    int source = m_.textures[index].source;
    if (source < 0) return -1;
    check(source, m_.images.size(), "image");
    // The sampler's wrap modes (glTF's default: repeat); its filters are not read, as every
    // renderer filters the same way.
    TextureWrap wrapU = TextureWrap::Repeat, wrapV = TextureWrap::Repeat;
    if (int sampler = m_.textures[index].sampler; sampler >= 0) {
      check(sampler, m_.samplers.size(), "sampler");
      wrapU = wrapMode(m_.samplers[sampler].wrapS);
      wrapV = wrapMode(m_.samplers[sampler].wrapT);
    }
    const auto key = std::make_tuple(source, wrapU, wrapV, linear);
    auto it = imageCache_.find(key);
    if (it != imageCache_.end()) return it->second;
    const tinygltf::Image& img = m_.images[source];
    std::string label = img.uri.empty() ? "image " + std::to_string(source) : img.uri;
    int out = -1;
    std::size_t texels = img.width > 0 && img.height > 0 ? std::size_t(img.width) * img.height : 0;
    int bytesPerComp = img.bits == 16 ? 2 : 1;
    if (texels == 0 || img.component < 1 || img.component > 4 ||
        img.image.size() < texels * img.component * bytesPerComp) {
      scene_.warnings.push_back(label + ": image missing or not decodable; using white");
    } else {
      Texture tex;
      tex.name = img.name.empty() ? label : img.name;
      tex.width = img.width;
      tex.height = img.height;
      tex.wrapU = wrapU;
      tex.wrapV = wrapV;
      tex.linear = linear;
      tex.rgba.resize(texels * 4);
      for (std::size_t t = 0; t < texels; ++t) {
        std::uint8_t c[4] = {0, 0, 0, 255};
        for (int k = 0; k < img.component; ++k) {
          // 16-bit images keep their high byte (little-endian storage).
          std::size_t at = (t * img.component + k) * bytesPerComp + (bytesPerComp - 1);
          c[k] = img.image[at];
        }
        if (img.component == 1 || img.component == 2) {  // grey (+ alpha)
          std::uint8_t a = img.component == 2 ? c[1] : 255;
          c[1] = c[2] = c[0];
          c[3] = a;
        }
        std::memcpy(&tex.rgba[t * 4], c, 4);
      }
      out = int(scene_.textures.size());
      scene_.textures.push_back(std::move(tex));
    }
    imageCache_[key] = out;
    return out;
  }

  static TextureWrap wrapMode(int gltf) {
    switch (gltf) {
      case TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE:
        return TextureWrap::ClampToEdge;
      case TINYGLTF_TEXTURE_WRAP_MIRRORED_REPEAT:
        return TextureWrap::MirroredRepeat;
      default:
        return TextureWrap::Repeat;
    }
  }

  static constexpr std::uint64_t kMaxNodeVisits = std::uint64_t(1) << 22;

  const tinygltf::Model& m_;
  Scene& scene_;
  const SceneLoadOptions& options_;
  std::uint64_t nodeVisits_ = 0, storedTriangles_ = 0, drawnTriangles_ = 0;
  std::map<int, std::vector<int>> meshCache_;
  std::map<int, int> materialCache_;
  // Image, wrap modes and whether linear.
  std::map<std::tuple<int, TextureWrap, TextureWrap, bool>, int> imageCache_;
  int defaultMaterial_ = -1;
  std::vector<int> path_;                       // the nodes from a root to the one visited
  std::map<int, std::vector<int>> nodeTracks_;  // node -> its tracks in tracks_
  std::shared_ptr<const std::vector<KeyframeTrack>> tracks_;
  std::set<std::string> warned_;
};

std::string trimmed(std::string s) {
  while (!s.empty() && (s.back() == '\n' || s.back() == ' ')) s.pop_back();
  return s;
}

// What tinygltf's callbacks need of one load: the model (for image buffer views), the folder
// every file the scene names must stay in, the texture budget, and the first thing refused,
// which becomes the load's error whatever tinygltf makes of the callback's failure (for an
// image, only a warning).
struct LoadContext {
  LoadContext(const tinygltf::Model& m, const std::filesystem::path& file,
              const SceneLoadOptions& options)
      : model(m),
        sceneFile(file.string()),
        budget(options),
        allowOutside(options.allowOutsidePaths) {
    // tinygltf resolves a URI against the scene file's folder as written in its path.
    const std::size_t slash = sceneFile.find_last_of('/');
    folder = slash == std::string::npos ? std::string() : sceneFile.substr(0, slash);
  }
  const tinygltf::Model& model;
  std::string sceneFile, folder;
  TextureBudget budget;
  bool allowOutside;
  Status refused;

  void refuse(const std::string& message) {
    if (refused.ok()) refused = Error{message};
  }
};

// tinygltf hands an image's buffer view to its decoder without checking that the view lies
// within its buffer, and the decoder then reads past the buffer's end. This loader runs in its
// place: it checks the view (the model's buffers and views are parsed before its images), then
// the image's size from its header against the texture limits, and then decodes as tinygltf's
// own loader does.
bool loadImageInBounds(tinygltf::Image* image, const int index, std::string* err, std::string* warn,
                       int width, int height, const unsigned char* bytes, int size,
                       void* contextPointer) {
  auto* context = static_cast<LoadContext*>(contextPointer);
  const tinygltf::Model* model = &context->model;
  if (image->bufferView >= 0) {
    // tinygltf has checked the view's and its buffer's indices.
    const tinygltf::BufferView& view = model->bufferViews[std::size_t(image->bufferView)];
    const std::size_t bufferBytes = model->buffers[std::size_t(view.buffer)].data.size();
    if (view.byteOffset > bufferBytes || view.byteLength > bufferBytes - view.byteOffset ||
        view.byteLength > std::size_t(std::numeric_limits<int>::max())) {
      if (err)
        *err += "image " + std::to_string(index) + ": buffer view " +
                std::to_string(image->bufferView) + " (offset " + std::to_string(view.byteOffset) +
                ", " + std::to_string(view.byteLength) + " bytes) lies outside its buffer (" +
                std::to_string(bufferBytes) + " bytes)\n";
      return false;
    }
  }
  int w = 0, h = 0, comps = 0;
  if (size > 0 && stbi_info_from_memory(bytes, size, &w, &h, &comps)) {
    const std::string name = !image->uri.empty()    ? image->uri
                             : !image->name.empty() ? image->name
                                                    : "image " + std::to_string(index);
    if (Status s = context->budget.admit(name, w, h); !s) {
      context->refuse(s.error().message);
      if (err) *err += s.error().message + "\n";
      return false;
    }
  }
  return tinygltf::LoadImageData(image, index, err, warn, width, height, bytes, size, nullptr);
}

// A buffer or image URI may name any path. tinygltf's own reader sizes a file by seeking to its
// end, which for a directory gives 2^63 - 1 bytes and an allocation that throws, and its
// existence check opens the file, which blocks on a FIFO until something writes to it. These
// look without opening, and read regular files only.
bool pathExists(const std::string& path, void*) {
  std::error_code ec;
  return std::filesystem::exists(path, ec);
}

bool readRegularFile(std::vector<unsigned char>* out, std::string* err, const std::string& path,
                     void* contextPointer) {
  auto* context = static_cast<LoadContext*>(contextPointer);
  // Buffers and images must stay in the scene's folder (the scene file itself is read here
  // too, and may be a link to anywhere).
  if (path != context->sceneFile) {
    // The URI as the file wrote it: tinygltf joined it to the folder, or to "." when the
    // folder did not hold it.
    std::string uri = path;
    const std::string inFolder = context->folder + "/";
    if (!context->folder.empty() && uri.rfind(inFolder, 0) == 0)
      uri.erase(0, inFolder.size());
    else if (uri.rfind("./", 0) == 0)
      uri.erase(0, 2);
    const std::filesystem::path folder = context->folder.empty() ? "." : context->folder;
    if (Status s = checkInsideSceneFolder(path, uri, folder, context->allowOutside); !s) {
      context->refuse("buffer or image URI " + s.error().message);
      if (err) *err += s.error().message + "\n";
      return false;
    }
  }
  std::error_code ec;
  const std::filesystem::file_status status = std::filesystem::status(path, ec);
  if (ec || !std::filesystem::is_regular_file(status)) {
    if (err) *err += "'" + path + "' is not a regular file\n";
    return false;
  }
  const std::uintmax_t size = std::filesystem::file_size(path, ec);
  std::ifstream in(path, std::ios::binary);
  if (ec || !in) {
    if (err) *err += "cannot open '" + path + "'\n";
    return false;
  }
  out->resize(std::size_t(size));
  in.read(reinterpret_cast<char*>(out->data()), std::streamsize(size));
  if (in.gcount() != std::streamsize(size)) {
    if (err) *err += "cannot read '" + path + "'\n";
    return false;
  }
  return true;
}

// tinygltf says only "Invalid glTF binary" for a cut-off .glb; the header tells us more.
Status checkGlbLength(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  unsigned char h[12] = {};
  in.read(reinterpret_cast<char*>(h), 12);
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  if (ec) return Status::success();
  if (in.gcount() < 12)
    return Error{path.string() + ": truncated .glb: " + std::to_string(size) +
                 " bytes, shorter than the 12-byte header"};
  if (std::memcmp(h, "glTF", 4) != 0) return Status::success();  // tinygltf reports it
  std::uint32_t declared = std::uint32_t(h[8]) | std::uint32_t(h[9]) << 8 |
                           std::uint32_t(h[10]) << 16 | std::uint32_t(h[11]) << 24;
  if (declared > size)
    return Error{path.string() + ": truncated .glb: header declares " + std::to_string(declared) +
                 " bytes, file has " + std::to_string(size)};
  return Status::success();
}

}  // namespace

Result<Scene> loadGltf(const std::filesystem::path& path, const SceneLoadOptions& options) {
  const std::string file = path.string();
  tinygltf::Model model;
  tinygltf::TinyGLTF loader;
  std::string err, warn;
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  if (ext == ".glb")
    if (Status s = checkGlbLength(path); !s) return s.error();
  LoadContext context(model, path, options);
  loader.SetImageLoader(loadImageInBounds, &context);
  loader.SetFsCallbacks({&pathExists, &tinygltf::ExpandFilePath, &readRegularFile,
                         &tinygltf::WriteWholeFile, &context});
  bool ok = false;
  try {
    ok = ext == ".glb" ? loader.LoadBinaryFromFile(&model, &err, &warn, file)
                       : loader.LoadASCIIFromFile(&model, &err, &warn, file);
  } catch (const std::exception& e) {  // allocations sized by the file (std::bad_alloc)
    return Error{file + ": cannot parse glTF: " + e.what()};
  }
  if (!context.refused.ok()) return Error{file + ": " + context.refused.error().message};
  // Refuse what we cannot honour before anything else: tinygltf itself ignores the list.
  for (const std::string& req : model.extensionsRequired)
    if (!kSupportedExtensions.count(req))
      return Error{file + ": unsupported required glTF extension '" + req + "'"};
  if (!ok) {
    std::string why = trimmed(err.empty() ? warn : err);
    return Error{file + ": cannot parse glTF: " + (why.empty() ? "unknown error" : why)};
  }
  // glTF 1.0 files parse as JSON but hold nothing a 2.0 reader finds.
  if (model.asset.version.rfind("2.", 0) != 0)
    return Error{file + ": glTF version '" + model.asset.version + "' (only 2.x is read)"};

  Scene scene;
  if (!warn.empty()) scene.warnings.push_back(file + ": " + trimmed(warn));
  try {
    GltfReader reader(model, scene, options);
    reader.readScene();
  } catch (const GltfError& e) {
    return Error{file + ": " + e.message};
  }
  for (std::string& w : unusedGltfFeatures(model, kSupportedExtensions))
    scene.warnings.push_back(file + ": " + std::move(w));
  return scene;
}

}  // namespace pc::scene_detail
