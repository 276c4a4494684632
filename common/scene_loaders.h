// Internal to scene loading: the format readers and the steps loadScene runs after them.
// Not part of pc_common's interface.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "common/scene.h"

namespace pc::scene_detail {

// Format readers. They fill meshes, materials, textures, instances, lights and cameras in the
// file's own units and axes; normals may be left empty (generated later).
Result<Scene> loadGltf(const std::filesystem::path& path, const SceneLoadOptions& options);
Result<Scene> loadObj(const std::filesystem::path& path, const SceneLoadOptions& options);

// ---- what a scene file may read and allocate (scene_limits.cpp) ----

// Checks that `file`, which the scene file names as `reference`, lies inside `sceneFolder` once
// both are made absolute and every symbolic link in them is resolved (unless allowOutside).
// The error names the reference, where it leads and the folder.
Status checkInsideSceneFolder(const std::filesystem::path& file, const std::string& reference,
                              const std::filesystem::path& sceneFolder, bool allowOutside);

// The texture limits of the load options, applied to each image's size as its header gives
// it, before any texel is decoded.
class TextureBudget {
 public:
  explicit TextureBudget(const SceneLoadOptions& options) : options_(options) {}
  // Admits a width x height texture called `name` and counts it against the scene's total.
  Status admit(const std::string& name, int width, int height);
  // Whether admit refused a texture: a scene over its limits fails to load, where a texture
  // that is missing or undecodable only costs a warning.
  bool exceeded() const { return exceeded_; }

 private:
  SceneLoadOptions options_;
  std::uint64_t texels_ = 0;
  bool exceeded_ = false;
};

// An error when `triangles` (what `what` holds or brings the scene to) is over the limit.
Status checkTriangleLimit(const std::string& what, std::uint64_t triangles,
                          const SceneLoadOptions& options);

// Decodes an image file (PNG, JPEG, ...) to 8-bit RGBA once `budget` admits its size.
Status loadImageFile(const std::filesystem::path& path, Texture& out, TextureBudget& budget);

// Folders of the sidecars written for known scenes, in the order they are searched: sidecars/
// in each data folder (common/data_folders.h: beside the running executable, as the build
// tree and scripts/bundle lay them out; the install's share/probecast/sidecars;
// $PROBECAST_DATA/sidecars).
std::vector<std::filesystem::path> sidecarFolders();
// Whether `name` ("rtxgi-cornell.json") is one of the sidecars probecast ships (data/sidecars).
bool isShippedSidecar(std::string_view name);
// The sidecar that applies to `scene`: the explicit one, else <scene dir>/scene.json, else
// <scene stem>.json or <scene dir name>.json in the first of sidecarFolders() holding one;
// empty when there is none; an Error when that name is one probecast ships (the scene needs
// it: its lights and volumes are there) and no folder holds it.
Result<std::filesystem::path> findSidecar(const std::filesystem::path& scene,
                                          const std::filesystem::path& explicitSidecar);
// Reads the sidecar and applies it: unit scale and up axis to what the file gave, then the
// sidecar's own lights, cameras, sky, volumes and animations (already in world units).
Status applySidecar(Scene& scene, const std::filesystem::path& sidecar);

// Area-weighted normals, shared only between faces less than ~60 degrees apart; vertices on
// sharper edges are split. Replaces positions/uvs/indices with the split ones.
void generateNormals(Mesh& mesh);

// Whether the mesh's tangents (Mesh::tangents) are one per vertex, finite and not zero; makes
// those it keeps unit length with a handedness of exactly +1 or -1.
bool tangentsUsable(Mesh& mesh);

// Tangents from the texture coordinates, for a normal map (scene_tangents.cpp): per triangle
// the directions of increasing u and of decreasing v (the map's +y, glTF's convention),
// weighted by the corner's angle and summed per vertex, then made perpendicular to the
// vertex normal, with the handedness the two directions give; one pass over the triangles.
// Vertices whose triangles all have degenerate coordinates get a tangent perpendicular to
// their normal. An error naming the mesh, tangents left empty, where the mesh has no
// coordinates or every triangle's are degenerate: its normal map cannot be applied.
Status generateTangents(Mesh& mesh);

// Index ranges, finite positions, attribute sizes. The message names the mesh.
Status validateMesh(const Mesh& mesh);

// World bounds of the referenced vertices; an error names an instance whose transform puts a
// vertex at a non-finite position.
Status computeBounds(Scene& scene);
std::uint64_t hashScene(const Scene& scene);

// The sRGB decoding curve, as in shaders/interop/tonemap.h (pcSrgbDecode).
float srgbToLinear(float v);

}  // namespace pc::scene_detail
