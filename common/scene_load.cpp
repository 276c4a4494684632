// loadScene: picks the reader by extension, then runs the steps every format shares:
// validation, normal generation, the sidecar, bounds and the scene hash.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <unordered_map>

#include "common/scene_loaders.h"

namespace pc {

namespace scene_detail {

Status validateMesh(const Mesh& mesh) {
  const std::string where = "mesh '" + mesh.name + "': ";
  if (mesh.indices.size() % 3 != 0)
    return Error{where + "index count " + std::to_string(mesh.indices.size()) +
                 " is not a multiple of 3"};
  for (std::size_t i = 0; i < mesh.indices.size(); ++i)
    if (mesh.indices[i] >= mesh.positions.size())
      return Error{where + "index " + std::to_string(mesh.indices[i]) + " (at " +
                   std::to_string(i) + ") out of range (" + std::to_string(mesh.positions.size()) +
                   " vertices)"};
  for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
    const glm::vec3& p = mesh.positions[i];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      return Error{where + "vertex " + std::to_string(i) + " has a non-finite position (" +
                   std::to_string(p.x) + ", " + std::to_string(p.y) + ", " + std::to_string(p.z) +
                   ")"};
  }
  if (!mesh.normals.empty() && mesh.normals.size() != mesh.positions.size())
    return Error{where + "normal count differs from vertex count"};
  if (!mesh.uvs.empty() && mesh.uvs.size() != mesh.positions.size())
    return Error{where + "uv count differs from vertex count"};
  if (!mesh.tangents.empty() && mesh.tangents.size() != mesh.positions.size())
    return Error{where + "tangent count differs from vertex count"};
  return Status::success();
}

namespace {

// A corner takes the faces around its vertex that are within 60 degrees of its own face, so
// curved surfaces shade smoothly and boxes keep hard edges.
constexpr float kCosSmooth = 0.5f;
// Up to this many faces around a vertex, each corner's faces are tested one by one (every
// ordinary mesh). Around busier vertices (a fan of 250,000 triangles, made to stall the
// loader: testing every pair took minutes) the faces are summed into direction bins first.
constexpr std::uint32_t kExactFaces = 64;
constexpr int kBinsPerSide = 16;  // octahedral map of directions: 256 bins of ~11 degrees

int directionBin(glm::vec3 n) {
  const float s = std::abs(n.x) + std::abs(n.y) + std::abs(n.z);
  float u = n.x / s, v = n.y / s;
  if (n.z < 0.0f) {  // the lower half folds over the diamond's corners
    const float fu = (1.0f - std::abs(v)) * (u >= 0.0f ? 1.0f : -1.0f);
    v = (1.0f - std::abs(u)) * (v >= 0.0f ? 1.0f : -1.0f);
    u = fu;
  }
  auto cell = [](float x) {
    return std::clamp(int((x * 0.5f + 0.5f) * float(kBinsPerSide)), 0, kBinsPerSide - 1);
  };
  return cell(u) * kBinsPerSide + cell(v);
}

// The faces around one busy vertex, their area-weighted normals summed per direction bin. A
// corner's sum is that of the bins whose mean direction lies within 60 degrees of its own
// face's bin: worked out once per bin, so a vertex costs its face count plus at most 256^2
// tests, and gives at most 256 distinct normals.
class BinnedFaces {
 public:
  BinnedFaces(const std::uint32_t* faces, std::size_t count, const std::vector<glm::vec3>& faceN,
              const std::vector<glm::vec3>& faceUnit) {
    slot_.fill(-1);
    for (std::size_t i = 0; i < count; ++i) {
      const std::uint32_t f = faces[i];
      if (faceUnit[f] == glm::vec3(0.0f)) continue;  // degenerate: adds nothing
      int& slot = slot_[std::size_t(directionBin(faceUnit[f]))];
      if (slot < 0) {
        slot = int(bins_.size());
        bins_.push_back({});
      }
      bins_[std::size_t(slot)].sum += faceN[f];
    }
    for (Bin& b : bins_) b.direction = glm::normalize(b.sum);
  }

  // The sum for a corner whose face has unit normal `unit` (not zero: one of the faces here).
  glm::vec3 sumFor(glm::vec3 unit) {
    Bin& own = bins_[std::size_t(slot_[std::size_t(directionBin(unit))])];
    if (!own.summed) {
      for (const Bin& b : bins_)
        if (glm::dot(b.direction, own.direction) >= kCosSmooth) own.smoothSum += b.sum;
      own.summed = true;
    }
    return own.smoothSum;
  }

 private:
  struct Bin {
    glm::vec3 sum{0.0f}, direction{0.0f}, smoothSum{0.0f};
    bool summed = false;
  };
  std::array<int, kBinsPerSide * kBinsPerSide> slot_;
  std::vector<Bin> bins_;
};

}  // namespace

void generateNormals(Mesh& mesh) {
  const std::size_t nv = mesh.positions.size(), nt = mesh.triangleCount();
  // Face normals, length = twice the area: summing them weights by area.
  std::vector<glm::vec3> faceN(nt), faceUnit(nt);
  for (std::size_t t = 0; t < nt; ++t) {
    const glm::vec3& a = mesh.positions[mesh.indices[3 * t]];
    const glm::vec3& b = mesh.positions[mesh.indices[3 * t + 1]];
    const glm::vec3& c = mesh.positions[mesh.indices[3 * t + 2]];
    faceN[t] = glm::cross(b - a, c - a);
    float len = glm::length(faceN[t]);
    faceUnit[t] = len > 0.0f ? faceN[t] / len : glm::vec3(0.0f);
  }
  // Faces around each vertex, as offsets into one array (compact and cache-friendly).
  std::vector<std::uint32_t> start(nv + 1, 0), faces(mesh.indices.size());
  for (std::uint32_t i : mesh.indices) ++start[i + 1];
  for (std::size_t v = 0; v < nv; ++v) start[v + 1] += start[v];
  std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
  for (std::size_t k = 0; k < mesh.indices.size(); ++k)
    faces[fill[mesh.indices[k]]++] = std::uint32_t(k / 3);
  std::unordered_map<std::uint32_t, BinnedFaces> busy;  // built at a busy vertex's first corner

  std::vector<glm::vec3> positions, normals;
  std::vector<glm::vec2> uvs;
  std::vector<glm::vec4> tangents;
  std::vector<std::uint32_t> indices(mesh.indices.size());
  // Per original vertex, the split copies made so far: (normal, new index).
  std::vector<std::vector<std::pair<glm::vec3, std::uint32_t>>> copies(nv);
  positions.reserve(nv);
  normals.reserve(nv);
  for (std::size_t k = 0; k < mesh.indices.size(); ++k) {
    std::uint32_t v = mesh.indices[k];
    std::size_t t = k / 3;
    glm::vec3 sum(0.0f);
    if (start[v + 1] - start[v] <= kExactFaces) {
      for (std::uint32_t j = start[v]; j < start[v + 1]; ++j) {
        std::uint32_t f = faces[j];
        if (glm::dot(faceUnit[f], faceUnit[t]) >= kCosSmooth) sum += faceN[f];
      }
    } else if (faceUnit[t] != glm::vec3(0.0f)) {
      auto it = busy.find(v);
      if (it == busy.end())
        it =
            busy.emplace(v, BinnedFaces(&faces[start[v]], start[v + 1] - start[v], faceN, faceUnit))
                .first;
      sum = it->second.sumFor(faceUnit[t]);
    }
    float len = glm::length(sum);
    glm::vec3 n = len > 0.0f ? sum / len : faceUnit[t];
    if (n == glm::vec3(0.0f)) n = glm::vec3(0.0f, 1.0f, 0.0f);  // degenerate triangle
    std::uint32_t out = 0;
    bool found = false;
    for (const auto& [cn, ci] : copies[v])
      if (glm::dot(cn, n) > 0.9999f) {
        out = ci;
        found = true;
        break;
      }
    if (!found) {
      out = std::uint32_t(positions.size());
      positions.push_back(mesh.positions[v]);
      normals.push_back(n);
      if (!mesh.uvs.empty()) uvs.push_back(mesh.uvs[v]);
      if (!mesh.tangents.empty()) tangents.push_back(mesh.tangents[v]);
      copies[v].emplace_back(n, out);
    }
    indices[k] = out;
  }
  mesh.positions = std::move(positions);
  mesh.normals = std::move(normals);
  mesh.uvs = std::move(uvs);
  mesh.tangents = std::move(tangents);
  mesh.indices = std::move(indices);
}

// Normals present but unusable (zero, NaN) are regenerated for the whole mesh: mixing file and
// generated normals on one surface would show seams.
static bool normalsUsable(Mesh& mesh) {
  if (mesh.normals.size() != mesh.positions.size()) return false;
  for (glm::vec3& n : mesh.normals) {
    float len = glm::length(n);
    if (!std::isfinite(len) || len < 1e-8f) return false;
    n /= len;
  }
  return true;
}

Status computeBounds(Scene& scene) {
  glm::vec3 lo(INFINITY), hi(-INFINITY);
  for (const Instance& inst : scene.instances) {
    if (inst.mesh < 0 || std::size_t(inst.mesh) >= scene.meshes.size()) continue;
    const Mesh& mesh = scene.meshes[inst.mesh];
    for (std::uint32_t i : mesh.indices) {  // only referenced vertices count
      glm::vec3 p = glm::vec3(inst.transform * glm::vec4(mesh.positions[i], 1.0f));
      // Finite file positions can still overflow under a node's scale or the sidecar's
      // unit_scale: such a vertex would put infinities into every acceleration structure and
      // probe volume built from the scene.
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
        return Error{"instance '" + inst.name + "' (mesh '" + mesh.name + "'): vertex " +
                     std::to_string(i) + " lands at a non-finite world position (" +
                     std::to_string(p.x) + ", " + std::to_string(p.y) + ", " + std::to_string(p.z) +
                     ") under its transform"};
      lo = glm::min(lo, p);
      hi = glm::max(hi, p);
    }
  }
  if (lo.x > hi.x) lo = hi = glm::vec3(0.0f);
  scene.boundsMin = lo;
  scene.boundsMax = hi;
  return Status::success();
}

namespace {

// 64-bit FNV-1a over explicit little-endian bytes, so the hash is the same on every machine.
class Hasher {
 public:
  void bytes(const void* data, std::size_t n) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < n; ++i) {
      h_ ^= p[i];
      h_ *= 0x100000001b3ull;
    }
  }
  void u64(std::uint64_t v) {
    unsigned char b[8];
    for (int i = 0; i < 8; ++i) b[i] = static_cast<unsigned char>(v >> (8 * i));
    bytes(b, 8);
  }
  void i32(int v) { u64(std::uint64_t(std::int64_t(v))); }
  void f32(float v) {
    if (v == 0.0f) v = 0.0f;  // -0 and +0 are the same scene
    std::uint32_t u;
    std::memcpy(&u, &v, 4);
    u64(u);
  }
  void vec(glm::vec2 v) {
    f32(v.x);
    f32(v.y);
  }
  void vec(glm::vec3 v) {
    f32(v.x);
    f32(v.y);
    f32(v.z);
  }
  void str(const std::string& s) {
    u64(s.size());
    bytes(s.data(), s.size());
  }
  std::uint64_t value() const { return h_; }

 private:
  std::uint64_t h_ = 0xcbf29ce484222325ull;
};

}  // namespace

std::uint64_t hashScene(const Scene& scene) {
  Hasher h;
  h.u64(scene.meshes.size());
  for (const Mesh& m : scene.meshes) {
    h.u64(m.positions.size());
    for (const auto& p : m.positions) h.vec(p);
    h.u64(m.uvs.size());
    for (const auto& uv : m.uvs) h.vec(uv);
    h.u64(m.indices.size());
    for (std::uint32_t i : m.indices) h.u64(i);
    h.i32(m.material);
  }
  h.u64(scene.materials.size());
  for (const Material& m : scene.materials) {
    h.vec(m.baseColor);
    h.i32(m.baseColorTexture);
    h.vec(m.emissive);
    h.i32(m.emissiveTexture);
    // Only cut-outs add these, so opaque scenes keep the hashes baked files were made with.
    if (m.isCutOut()) {
      h.f32(m.alphaCutoff);
      h.f32(m.baseAlpha);
      h.i32(m.alphaTexture);
      h.i32(m.alphaChannel);
    }
    // Likewise only normal maps add theirs (and their meshes' tangents, below).
    if (m.normalTexture >= 0) {
      h.i32(m.normalTexture);
      h.f32(m.normalScale);
    }
    // And only glossy materials their metallic-roughness terms.
    if (!m.isDiffuseOnly()) {
      h.f32(m.metallic);
      h.f32(m.roughness);
      h.i32(m.metallicRoughnessTexture);
    }
  }
  for (const Mesh& m : scene.meshes) {
    if (m.tangents.empty()) continue;
    h.u64(m.tangents.size());
    for (const glm::vec4& t : m.tangents) {
      h.vec(glm::vec3(t));
      h.f32(t.w);
    }
  }
  h.u64(scene.textures.size());
  for (const Texture& t : scene.textures) {
    h.i32(t.width);
    h.i32(t.height);
    h.bytes(t.rgba.data(), t.rgba.size());
    // Only other wrap modes add these, so repeating textures keep the hashes baked files
    // were made with.
    if (t.wrapU != TextureWrap::Repeat || t.wrapV != TextureWrap::Repeat) {
      h.i32(int(t.wrapU));
      h.i32(int(t.wrapV));
    }
    if (t.linear) h.i32(1);
  }
  h.u64(scene.instances.size());
  for (const Instance& inst : scene.instances) {
    h.i32(inst.mesh);
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r) h.f32(inst.transform[c][r]);
    h.i32(inst.animation);
  }
  h.u64(scene.lights.size());
  for (const Light& l : scene.lights) {
    h.i32(int(l.type));
    h.vec(l.position);
    h.vec(l.direction);
    h.vec(l.color);
    h.f32(l.intensity);
    h.f32(l.range);
    h.f32(l.innerConeAngle);
    h.f32(l.outerConeAngle);
    h.i32(l.animation);
  }
  // Animation and sky change the field as much as geometry does.
  h.u64(scene.animations.size());
  for (const Animation& a : scene.animations) {
    h.i32(int(a.kind));
    h.u64(a.points.size());
    for (const auto& p : a.points) h.vec(p);
    h.f32(a.period);
    h.vec(a.axis);
    h.vec(a.pivot);
    h.f32(a.radiansPerSecond);
    h.u64(a.chain.size());
    for (const KeyframedNode& n : a.chain) {
      h.vec(n.translation);
      h.vec(glm::vec3(n.rotation.x, n.rotation.y, n.rotation.z));
      h.f32(n.rotation.w);
      h.vec(n.scale);
      for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 4; ++r) h.f32(n.hasMatrix ? n.matrix[c][r] : 0.0f);
      h.u64(n.tracks.size());
      for (int t : n.tracks) {
        const KeyframeTrack& k = (*a.tracks)[std::size_t(t)];
        h.i32(int(k.property));
        h.i32(int(k.interpolation));
        h.f32(k.period);
        h.u64(k.times.size());
        for (float time : k.times) h.f32(time);
        for (const glm::vec4& v : k.values) {
          h.vec(glm::vec3(v));
          h.f32(v.w);
        }
      }
    }
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r) h.f32(a.base[c][r]);
  }
  h.vec(scene.sky.zenith);
  h.vec(scene.sky.horizon);
  h.vec(scene.sky.ground);
  h.i32(int(scene.emissiveMode));
  return h.value();
}

}  // namespace scene_detail

using namespace scene_detail;

Result<Scene> loadScene(const std::filesystem::path& path, const std::filesystem::path& sidecar,
                        const SceneLoadOptions& options) {
  const std::string file = path.string();
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return Error{file + ": file not found"};
  if (!std::filesystem::is_regular_file(path, ec)) return Error{file + ": not a regular file"};
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });

  Result<Scene> loaded = Error{""};
  if (ext == ".gltf" || ext == ".glb") {
    loaded = loadGltf(path, options);
  } else if (ext == ".obj") {
    loaded = loadObj(path, options);
  } else {
    return Error{file + ": unsupported scene format '" + ext + "' (expected .gltf, .glb or .obj)"};
  }
  if (!loaded) return loaded.error();
  Scene scene = std::move(loaded).value();
  scene.name = path.stem().string();
  scene.source = path;

  for (Mesh& mesh : scene.meshes) {
    if (Status s = validateMesh(mesh); !s) return Error{file + ": " + s.error().message};
    if (!normalsUsable(mesh)) generateNormals(mesh);
    // Tangents serve the normal map alone; a mesh that has one and lacks usable tangents gets
    // them generated, and one where that fails (no texture coordinates to read the map with,
    // or only degenerate ones) is drawn without its map, said once here.
    const bool normalMapped = mesh.material >= 0 &&
                              std::size_t(mesh.material) < scene.materials.size() &&
                              scene.materials[std::size_t(mesh.material)].normalTexture >= 0;
    if (!normalMapped) {
      mesh.tangents.clear();
    } else if (mesh.uvs.size() != mesh.positions.size() || !tangentsUsable(mesh)) {
      if (Status s = generateTangents(mesh); !s)
        scene.warnings.push_back(file + ": " + s.error().message);
    }
  }
  if (scene.triangleCount() == 0) return Error{file + ": no triangles"};

  Result<std::filesystem::path> found = findSidecar(path, sidecar);
  if (!found) return found.error();
  if (!found.value().empty()) {
    if (Status s = applySidecar(scene, found.value()); !s) return s.error();
    scene.sidecar = found.value();
  }

  if (Status s = computeBounds(scene); !s) return Error{file + ": " + s.error().message};
  scene.hash = hashScene(scene);
  // Nothing lights such a scene: every image of it is black. Said once here rather than left
  // to look like a failure of the renderers.
  if (!scene.hasLights() && scene.sky.isBlack())
    scene.warnings.push_back(file +
                             ": no lights, no emissive materials and a black sky: nothing lights "
                             "the scene (a sidecar adds lights and a sky, docs/SCENES.md)");
  return scene;
}

}  // namespace pc
