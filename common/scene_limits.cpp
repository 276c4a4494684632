// What a scene file may read and make us allocate (SceneLoadOptions): the folder its references
// must stay in, texture sizes and the triangle count. A hostile file otherwise reads any file
// the user can (a URI of ../../etc/...) or asks for gigabytes with a few bytes of header.
#include <stb_image.h>  // declarations only; the implementation is in scene_model.cpp

#include "common/scene_loaders.h"

namespace pc::scene_detail {

namespace fs = std::filesystem;

namespace {

// Absolute, with every symbolic link of the part that exists resolved and "." and ".." folded.
fs::path resolved(const fs::path& p) {
  std::error_code ec;
  fs::path abs = fs::absolute(p.empty() ? fs::path(".") : p, ec);
  if (ec) return p.lexically_normal();
  fs::path out = fs::weakly_canonical(abs, ec);
  return ec ? abs.lexically_normal() : out;
}

}  // namespace

Status checkInsideSceneFolder(const fs::path& file, const std::string& reference,
                              const fs::path& sceneFolder, bool allowOutside) {
  if (allowOutside) return Status::success();
  const fs::path folder = resolved(sceneFolder), target = resolved(file);
  const fs::path rel = target.lexically_relative(folder);
  const bool inside = !rel.empty() && rel != "." && *rel.begin() != "..";
  if (inside) return Status::success();
  return Error{"'" + reference + "' leads to " + target.string() + ", outside the scene's folder " +
               folder.string() +
               " (a scene may only read files inside its folder; --allow-outside-paths, "
               "SceneLoadOptions::allowOutsidePaths, permits others)"};
}

Status TextureBudget::admit(const std::string& name, int width, int height) {
  const std::string size = std::to_string(width) + "x" + std::to_string(height);
  const int limit = options_.maxTextureSize;
  if (width > limit || height > limit) {
    exceeded_ = true;
    return Error{"texture '" + name + "' is " + size + ", over the limit of " +
                 std::to_string(limit) + " texels per side (--max-texture-size raises it)"};
  }
  const std::uint64_t texels =
      std::uint64_t(std::max(width, 0)) * std::uint64_t(std::max(height, 0));
  if (texels > options_.maxSceneTexels - texels_) {  // texels_ never exceeds the limit
    exceeded_ = true;
    return Error{"texture '" + name + "' (" + size + ") brings the scene's textures to " +
                 std::to_string(texels_ + texels) + " texels, over the limit of " +
                 std::to_string(options_.maxSceneTexels) + " (--max-scene-texels raises it)"};
  }
  texels_ += texels;
  return Status::success();
}

Status checkTriangleLimit(const std::string& what, std::uint64_t triangles,
                          const SceneLoadOptions& options) {
  if (triangles <= options.maxTriangles) return Status::success();
  return Error{what + ": " + std::to_string(triangles) + " triangles, over the limit of " +
               std::to_string(options.maxTriangles) + " (--max-triangles raises it)"};
}

Status loadImageFile(const fs::path& path, Texture& out, TextureBudget& budget) {
  // A FIFO would block the load until something wrote to it; a directory is no image.
  std::error_code ec;
  if (!fs::is_regular_file(path, ec))
    return Error{path.string() + ": cannot read image: not a regular file"};
  int w = 0, h = 0, comps = 0;
  // The header alone first: the size is checked before the texels are allocated.
  if (!stbi_info(path.string().c_str(), &w, &h, &comps)) {
    const char* why = stbi_failure_reason();
    return Error{path.string() + ": cannot read image: " + (why ? why : "unknown error")};
  }
  if (Status s = budget.admit(path.filename().string(), w, h); !s)
    return Error{path.string() + ": " + s.error().message};
  const int admittedW = w, admittedH = h;
  stbi_uc* data = stbi_load(path.string().c_str(), &w, &h, &comps, 4);
  if (!data) {
    const char* why = stbi_failure_reason();
    return Error{path.string() + ": cannot read image: " + (why ? why : "unknown error")};
  }
  if (w != admittedW || h != admittedH) {  // the file changed between the two reads
    stbi_image_free(data);
    return Error{path.string() + ": cannot read image: its size changed while it was read"};
  }
  out.width = w;
  out.height = h;
  out.rgba.assign(data, data + std::size_t(w) * h * 4);
  out.name = path.filename().string();
  stbi_image_free(data);
  return Status::success();
}

}  // namespace pc::scene_detail
