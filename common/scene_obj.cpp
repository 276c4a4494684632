// Wavefront OBJ + MTL through tinyobjloader: one mesh per (group, material), diffuse colour and
// texture (map_Kd), emission (Ke), metallic and roughness (Pm, Pr). Missing textures are warnings:
// such scenes still light.
#include <tiny_obj_loader.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <unordered_map>

#include "common/scene_loaders.h"

namespace pc::scene_detail {

namespace {

// Grey for materials whose only colour was a texture that is missing: mid albedo keeps the
// scene's light balance plausible.
constexpr float kMissingTextureAlbedo = 0.6f;

struct CornerKey {
  int v, vt, vn;
  bool operator==(const CornerKey& o) const { return v == o.v && vt == o.vt && vn == o.vn; }
};
struct CornerHash {
  std::size_t operator()(const CornerKey& k) const {
    std::uint64_t h = std::uint64_t(std::uint32_t(k.v)) * 0x9E3779B97F4A7C15ull;
    h ^= std::uint64_t(std::uint32_t(k.vt)) * 0xC2B2AE3D27D4EB4Full + (h >> 29);
    h ^= std::uint64_t(std::uint32_t(k.vn)) * 0x165667B19E3779F9ull + (h >> 31);
    return std::size_t(h);
  }
};

class ObjBuilder {
 public:
  ObjBuilder(const std::filesystem::path& path, const tinyobj::attrib_t& attrib, Scene& scene,
             const SceneLoadOptions& options)
      : path_(path), attrib_(attrib), scene_(scene), options_(options), budget_(options) {}

  // Fails where a texture map lies outside the scene's folder or over the texture limits.
  Status addMaterials(const std::vector<tinyobj::material_t>& mats) {
    for (const auto& m : mats) {
      Material mat;
      mat.name = m.name;
      mat.baseColor = glm::vec3(m.diffuse[0], m.diffuse[1], m.diffuse[2]);
      mat.emissive = glm::vec3(m.emission[0], m.emission[1], m.emission[2]);
      // The PBR extension's Pm (metallic) and Pr (roughness), where the file gives either;
      // tinyobj reports both as 0 when absent, so a material naming neither (or both 0, which
      // would be a perfect dielectric mirror) stays diffuse. Phong's Ks and Ns are not mapped:
      // exporters write them for diffuse surfaces too, and they name no roughness.
      if ((m.metallic > 0.0f || m.roughness > 0.0f) && std::isfinite(m.metallic) &&
          std::isfinite(m.roughness)) {
        mat.metallic = std::clamp(float(m.metallic), 0.0f, 1.0f);
        mat.roughness = std::clamp(float(m.roughness), 0.0f, 1.0f);
      }
      if (!m.diffuse_texname.empty()) {
        // MTL files often give map_Kd without Kd (tinyobj then reports Kd = 0): the texture
        // is the colour.
        bool noKd = mat.baseColor == glm::vec3(0.0f);
        mat.baseColorTexture = texture(m.diffuse_texname, m.diffuse_texopt.clamp);
        if (noKd)
          mat.baseColor = glm::vec3(mat.baseColorTexture >= 0 ? 1.0f : kMissingTextureAlbedo);
      }
      // map_d: a cut-out where the map is below one half: its alpha where the image has
      // one (often map_d names the colour texture itself), else its first channel (masks
      // are grey images). A map that cannot be read leaves the surface opaque (texture()
      // warns).
      if (!m.alpha_texname.empty()) {
        const int alpha = texture(m.alpha_texname, m.alpha_texopt.clamp);
        if (alpha >= 0) {
          const std::vector<std::uint8_t>& rgba = scene_.textures[alpha].rgba;
          bool hasAlpha = false;
          for (std::size_t i = 3; i < rgba.size() && !hasAlpha; i += 4) hasAlpha = rgba[i] < 255;
          mat.alphaCutoff = 0.5f;
          mat.alphaTexture = alpha;
          mat.alphaChannel = hasAlpha ? 3 : 0;
        }
      }
      if (!refused_.ok()) return refused_;
      scene_.materials.push_back(mat);
    }
    return Status::success();
  }

  // Face corners of shape `shapeIndex`, split by material into meshes. Fails on an index
  // outside the file's vertex, texcoord or normal lists.
  Status addShape(const tinyobj::shape_t& shape, std::size_t shapeIndex) {
    const auto& mesh = shape.mesh;
    std::size_t nv = attrib_.vertices.size() / 3, nt = attrib_.texcoords.size() / 2,
                nn = attrib_.normals.size() / 3;
    // Faces grouped by material, in file order within each group.
    std::map<int, std::vector<std::size_t>> byMaterial;
    for (std::size_t f = 0; f < mesh.num_face_vertices.size(); ++f) {
      if (mesh.num_face_vertices[f] != 3) continue;  // lines/points left after triangulation
      int mat = f < mesh.material_ids.size() ? mesh.material_ids[f] : -1;
      if (mat < 0 || std::size_t(mat) >= scene_.materials.size()) mat = -1;
      byMaterial[mat].push_back(f);
    }
    // tinyobj keeps faces as a flat corner list; face f starts at 3 * f once triangulated.
    std::string base = shape.name.empty() ? "shape" + std::to_string(shapeIndex) : shape.name;
    for (auto& [mat, faces] : byMaterial) {
      Mesh out;
      int material = mat >= 0 ? mat : defaultMaterial();
      out.name = byMaterial.size() > 1 ? base + "/" + scene_.materials[material].name : base;
      out.material = material;
      bool haveNormals = true, haveUvs = false;
      std::unordered_map<CornerKey, std::uint32_t, CornerHash> corners;
      for (std::size_t f : faces) {
        for (int c = 0; c < 3; ++c) {
          const tinyobj::index_t& idx = mesh.indices[3 * f + c];
          // (A negative index here was a relative one reaching before the first vertex.)
          if (idx.vertex_index < 0 || std::size_t(idx.vertex_index) >= nv)
            return Error{
                path_.string() + ": face " + std::to_string(f + 1) + " of '" + base + "': " +
                (idx.vertex_index < 0 ? std::string("relative vertex index reaches before vertex 1")
                                      : "vertex index " + std::to_string(idx.vertex_index + 1) +
                                            " out of range (" + std::to_string(nv) + " vertices)")};
          if (idx.texcoord_index >= 0 && std::size_t(idx.texcoord_index) >= nt)
            return Error{path_.string() + ": face " + std::to_string(f + 1) + " of '" + base +
                         "': texcoord index " + std::to_string(idx.texcoord_index + 1) +
                         " out of range (" + std::to_string(nt) + " texcoords)"};
          if (idx.normal_index >= 0 && std::size_t(idx.normal_index) >= nn)
            return Error{path_.string() + ": face " + std::to_string(f + 1) + " of '" + base +
                         "': normal index " + std::to_string(idx.normal_index + 1) +
                         " out of range (" + std::to_string(nn) + " normals)"};
          if (idx.normal_index < 0) haveNormals = false;
          if (idx.texcoord_index >= 0) haveUvs = true;
          CornerKey key{idx.vertex_index, idx.texcoord_index, idx.normal_index};
          auto [it, inserted] = corners.emplace(key, std::uint32_t(out.positions.size()));
          if (inserted) pushVertex(out, key);
          out.indices.push_back(it->second);
        }
      }
      if (out.indices.empty()) continue;
      if (!haveNormals) out.normals.clear();  // generated later, with hard edges kept
      if (!haveUvs) out.uvs.clear();
      Instance inst;
      inst.name = out.name;
      inst.mesh = int(scene_.meshes.size());
      scene_.instances.push_back(inst);
      scene_.meshes.push_back(std::move(out));
    }
    return Status::success();
  }

 private:
  void pushVertex(Mesh& out, const CornerKey& k) {
    const auto& v = attrib_.vertices;
    out.positions.emplace_back(v[3 * k.v], v[3 * k.v + 1], v[3 * k.v + 2]);
    if (k.vn >= 0) {
      const auto& n = attrib_.normals;
      out.normals.emplace_back(n[3 * k.vn], n[3 * k.vn + 1], n[3 * k.vn + 2]);
    } else {
      out.normals.emplace_back(0.0f);
    }
    if (k.vt >= 0) {
      const auto& t = attrib_.texcoords;
      out.uvs.emplace_back(t[2 * k.vt], 1.0f - t[2 * k.vt + 1]);  // OBJ v points up
    } else {
      out.uvs.emplace_back(0.0f, 1.0f);
    }
  }

  // The texture map `name` (relative to the OBJ's folder); -1 where it cannot be used.
  // `clamp`: the MTL's "-clamp on" (texture coordinates clamped to the edge texels).
  int texture(const std::string& name, bool clamp = false) {
    const std::filesystem::path file = path_.parent_path() / name;
    const std::string key = file.string() + (clamp ? "#clamp" : "");
    auto it = textureCache_.find(key);
    if (it != textureCache_.end()) return it->second;
    Texture tex;
    int index = -1;
    if (Status inside =
            checkInsideSceneFolder(file, name, path_.parent_path(), options_.allowOutsidePaths);
        !inside) {
      refused_ = Error{path_.string() + ": texture map " + inside.error().message};
    } else if (Status s = loadImageFile(file, tex, budget_); s) {
      if (clamp) tex.wrapU = tex.wrapV = TextureWrap::ClampToEdge;
      index = int(scene_.textures.size());
      scene_.textures.push_back(std::move(tex));
    } else if (budget_.exceeded()) {
      refused_ = s.error();
    } else {
      scene_.warnings.push_back(s.error().message);
    }
    textureCache_[key] = index;
    return index;
  }

  int defaultMaterial() {
    if (defaultMaterial_ < 0) {
      defaultMaterial_ = int(scene_.materials.size());
      Material d;
      d.name = "default";
      scene_.materials.push_back(d);
    }
    return defaultMaterial_;
  }

  const std::filesystem::path& path_;
  const tinyobj::attrib_t& attrib_;
  Scene& scene_;
  const SceneLoadOptions& options_;
  TextureBudget budget_;
  Status refused_;  // the first texture the options refuse: fails the load
  std::map<std::string, int> textureCache_;
  int defaultMaterial_ = -1;
};

// What scanObjText finds before tinyobj parses the file.
struct ObjText {
  std::vector<std::string> mtllibs;  // each mtllib line's whole argument, for MtlReader
  std::uint64_t triangles = 0;       // the face lines' triangles once triangulated
};

// Triangles a face line makes once triangulated as a fan: one per corner past the second.
std::uint64_t faceTriangles(const std::string& line, std::size_t from) {
  std::uint64_t corners = 0;
  bool inToken = false;
  for (std::size_t i = from; i < line.size(); ++i) {
    const bool space = line[i] == ' ' || line[i] == '\t' || line[i] == '\r';
    if (!space && !inToken) ++corners;
    inToken = !space;
  }
  return corners > 2 ? corners - 2 : 0;
}

// tinyobj reads "nan", "inf", words and missing coordinates as 0, so vertex lines are checked
// in the text itself (the file is read once more; cheap next to parsing). The same pass keeps each
// mtllib line's whole argument for MtlReader, and counts the triangles the faces will make, so
// that the triangle limit is applied before tinyobj allocates for them.
Status scanObjText(const std::filesystem::path& path, ObjText& out) {
  std::vector<std::string>& mtllibs = out.mtllibs;
  std::ifstream in(path, std::ios::binary);
  std::string line;
  std::size_t lineNo = 0, vertex = 0;
  while (std::getline(in, line)) {
    ++lineNo;
    std::size_t i = line.find_first_not_of(" \t");
    if (i != std::string::npos && line[i] == 'f' && i + 1 < line.size() &&
        (line[i + 1] == ' ' || line[i + 1] == '\t')) {
      out.triangles += faceTriangles(line, i + 2);
      continue;
    }
    if (i != std::string::npos && line.compare(i, 7, "mtllib ") == 0) {
      std::string name = line.substr(i + 7);
      while (!name.empty() && (name.back() == '\r' || name.back() == ' ' || name.back() == '\t'))
        name.pop_back();
      name.erase(0, name.find_first_not_of(" \t"));
      if (!name.empty()) mtllibs.push_back(name);
      continue;
    }
    if (i == std::string::npos || line[i] != 'v' || i + 1 >= line.size() ||
        (line[i + 1] != ' ' && line[i + 1] != '\t'))
      continue;
    ++vertex;
    std::istringstream tokens(line.substr(i + 2));
    std::string tok;
    const std::string where =
        path.string() + ":" + std::to_string(lineNo) + ": vertex " + std::to_string(vertex);
    int k = 0;
    for (; k < 3 && tokens >> tok; ++k) {
      char* end = nullptr;
      double v = std::strtod(tok.c_str(), &end);
      if (end == tok.c_str() || *end != '\0')
        return Error{where + " has a coordinate '" + tok + "' that is not a number"};
      if (!std::isfinite(v)) return Error{where + " has a non-finite coordinate '" + tok + "'"};
    }
    // tinyobj would read the missing coordinates as 0 and place the vertex silently.
    if (k < 3)
      return Error{where + " has " + std::to_string(k) + " coordinate" + (k == 1 ? "" : "s") +
                   " where a position needs 3"};
  }
  return Status::success();
}

// Reads the .mtl files an OBJ names, from the OBJ's folder. mtllib lists file names separated
// by spaces, and tinyobj asks for them one at a time, stopping at the first that loads. So the
// first request from an mtllib line reads the whole line's files here: its whole argument where
// that is one file ("my materials.mtl": exporters write names with spaces), else every name on
// it that is a file.
class MtlReader : public tinyobj::MaterialReader {
 public:
  MtlReader(std::filesystem::path dir, std::vector<std::string> lines, bool allowOutside)
      : dir_(std::move(dir)), lines_(std::move(lines)), allowOutside_(allowOutside) {}

  // The first material file the load options refuse (outside the scene's folder).
  const Status& refused() const { return refused_; }

  bool operator()(const std::string& name, std::vector<tinyobj::material_t>* materials,
                  std::map<std::string, int>* materialMap, std::string* warn,
                  std::string* err) override {
    std::vector<std::string> files;
    for (const std::string& line : lines_) {
      const std::vector<std::string> tokens = split(line);
      if (std::find(tokens.begin(), tokens.end(), name) == tokens.end()) continue;
      if (isFile(line)) {
        files = {line};
      } else {
        for (const std::string& t : tokens)
          if (isFile(t)) files.push_back(t);
      }
      break;
    }
    if (files.empty() && isFile(name)) files = {name};
    if (files.empty()) {
      if (warn) *warn += "material file '" + name + "' not found in " + dir_.string() + "\n";
      return false;
    }
    for (const std::string& f : files) {
      if (!read_.insert(f).second) continue;  // read for an earlier line
      if (Status inside = checkInsideSceneFolder(dir_ / f, f, dir_, allowOutside_); !inside) {
        if (refused_.ok()) refused_ = Error{"material library " + inside.error().message};
        continue;
      }
      std::ifstream in(dir_ / f, std::ios::binary);
      tinyobj::LoadMtl(materialMap, materials, &in, warn, err);
    }
    return true;
  }

 private:
  static std::vector<std::string> split(const std::string& line) {
    std::istringstream in(line);
    std::vector<std::string> out;
    for (std::string t; in >> t;) out.push_back(t);
    return out;
  }
  bool isFile(const std::string& name) const {
    std::error_code ec;
    return std::filesystem::is_regular_file(dir_ / name, ec);
  }

  std::filesystem::path dir_;
  std::vector<std::string> lines_;
  bool allowOutside_;
  std::set<std::string> read_;
  Status refused_;
};

}  // namespace

Result<Scene> loadObj(const std::filesystem::path& path, const SceneLoadOptions& options) {
  ObjText text;
  if (Status s = scanObjText(path, text); !s) return s.error();
  if (Status s = checkTriangleLimit(path.string(), text.triangles, options); !s) return s.error();
  std::ifstream objText(path, std::ios::binary);
  if (!objText) return Error{path.string() + ": cannot open"};
  tinyobj::attrib_t attrib;
  std::vector<tinyobj::shape_t> shapes;
  std::vector<tinyobj::material_t> materials;
  std::string warning, why;
  MtlReader mtl(path.parent_path(), text.mtllibs, options.allowOutsidePaths);
  if (!tinyobj::LoadObj(&attrib, &shapes, &materials, &warning, &why, &objText, &mtl,
                        /*triangulate=*/true, /*default_vcols_fallback=*/false)) {
    while (!why.empty() && why.back() == '\n') why.pop_back();
    return Error{path.string() + ": cannot parse OBJ: " + (why.empty() ? "unknown error" : why)};
  }
  if (!mtl.refused().ok()) return Error{path.string() + ": " + mtl.refused().error().message};
  Scene scene;
  // A missing .mtl only costs colours; tinyobj reports it as a warning.
  if (!warning.empty()) {
    while (!warning.empty() && warning.back() == '\n') warning.pop_back();
    scene.warnings.push_back(path.string() + ": " + warning);
  }
  // Non-finite coordinates would poison bounds and acceleration structures: refuse them here,
  // numbering vertices from 1 as the file's face lines do.
  for (std::size_t i = 0; i < attrib.vertices.size(); ++i)
    if (!std::isfinite(attrib.vertices[i]))
      return Error{path.string() + ": vertex " + std::to_string(i / 3 + 1) +
                   " has a non-finite position"};
  ObjBuilder builder(path, attrib, scene, options);
  if (Status s = builder.addMaterials(materials); !s) return s.error();
  for (std::size_t s = 0; s < shapes.size(); ++s)
    if (Status st = builder.addShape(shapes[s], s); !st) return st.error();
  return scene;
}

}  // namespace pc::scene_detail
