// sdf: what the SDF backend's distance field costs to build and to keep current. For every
// shared scene and a generated height field (2,000,000 triangles by default), the whole build
// on the GPU, then the update after one instance moved: a crate added to the scene for the
// purpose (a box an eightieth of the scene's size), moved by half its side each time, so every
// scene is measured with the same kind of change. An update refills only the bricks the crate
// left and reached (server/vulkan_tracer_sdf.cpp).
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <glm/gtc/matrix_transform.hpp>

#include "bench.h"
#include "bench_common.h"
#include "server/vulkan_tracer.h"

namespace pc::bench {

namespace {

struct SdfBenchSetup {
  std::vector<std::string> scenes;  // empty: the shared scenes
  int cells = 1000;                 // height field quads a side (2 triangles each); 0: none
  float size = 1000.0f;             // height field side, m
  int voxels = 128;                 // VulkanTracerOptions::sdfVoxels
  int updates = 8;                  // crate moves timed (after one untimed)
  std::string device;
  bool gpuOnly = false;
};

// A box of side `side` centred on the origin: 12 triangles, outward normals.
Mesh crateMesh(float side) {
  Mesh m;
  m.name = "crate";
  const float h = 0.5f * side;
  for (int axis = 0; axis < 3; ++axis) {
    for (float sign : {-1.0f, 1.0f}) {
      glm::vec3 n(0.0f);
      n[axis] = sign;
      const glm::vec3 u = axis == 0 ? glm::vec3(0, 1, 0) : glm::vec3(1, 0, 0);
      const glm::vec3 v = glm::cross(n, u);
      const std::uint32_t base = std::uint32_t(m.positions.size());
      for (glm::vec2 c : {glm::vec2(-1, -1), glm::vec2(1, -1), glm::vec2(1, 1), glm::vec2(-1, 1)}) {
        m.positions.push_back(h * (n + c.x * u + c.y * v));
        m.normals.push_back(n);
      }
      for (std::uint32_t i : {0u, 1u, 2u, 0u, 2u, 3u}) m.indices.push_back(base + i);
    }
  }
  return m;
}

// The ground of `flight` (groundHeight), `cells` quads a side.
Scene heightField(int cells, float size) {
  Scene scene;
  scene.name = "height field " + std::to_string(2 * cells * cells) + " triangles";
  scene.materials.push_back(
      Material{.name = "ground", .baseColor = glm::vec3(0.45f, 0.42f, 0.36f)});
  Mesh m;
  m.name = "ground";
  const int n = cells;
  m.positions.reserve(std::size_t(n + 1) * std::size_t(n + 1));
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      const float x = (float(i) / float(n) - 0.5f) * size, z = (float(j) / float(n) - 0.5f) * size;
      m.positions.emplace_back(x, groundHeight(x, z), z);
      m.normals.push_back(groundNormal(x, z));
    }
  m.indices.reserve(std::size_t(n) * std::size_t(n) * 6);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const std::uint32_t a = std::uint32_t(j * (n + 1) + i), b = a + 1,
                          c = a + std::uint32_t(n + 1);
      for (std::uint32_t k : {a, c, b, b, c, c + 1}) m.indices.push_back(k);
    }
  scene.boundsMin = glm::vec3(-0.5f * size, -12.0f, -0.5f * size);
  scene.boundsMax = glm::vec3(0.5f * size, 12.0f, 0.5f * size);
  scene.meshes.push_back(std::move(m));
  scene.instances.push_back(Instance{.name = "ground", .mesh = 0});
  return scene;
}

// Adds the crate at the middle of the scene's bounds; returns its instance index.
int addCrate(Scene& scene) {
  const glm::vec3 extent = scene.boundsMax - scene.boundsMin;
  const float side = std::max(0.05f, glm::length(extent) / 80.0f);
  scene.materials.push_back(Material{.name = "crate", .baseColor = glm::vec3(0.5f)});
  Mesh crate = crateMesh(side);
  crate.material = int(scene.materials.size()) - 1;
  scene.meshes.push_back(std::move(crate));
  const glm::vec3 centre = 0.5f * (scene.boundsMin + scene.boundsMax);
  // Animated, so that the tracers keep it out of their static geometry; the benchmark sets its
  // transforms itself.
  Animation path;
  path.points = {centre, centre + glm::vec3(0.5f * side, 0, 0)};
  scene.animations.push_back(path);
  Instance inst{.name = "crate", .mesh = int(scene.meshes.size()) - 1};
  inst.transform = glm::translate(glm::mat4(1.0f), centre);
  inst.animation = int(scene.animations.size()) - 1;
  scene.instances.push_back(inst);
  return int(scene.instances.size()) - 1;
}

struct SdfTimes {
  SdfBuildStats build;   // the timed whole build
  double updateMs = 0;   // median over the timed moves that were updates
  int updateBricks = 0;  // bricks the median update filled
  int regrown = 0;       // timed moves that grew the field and built it whole
};

Result<SdfTimes> measure(const Scene& scene, int crate, const SdfBenchSetup& o) {
  VulkanTracerOptions vo;
  vo.tracing = VulkanTracing::DistanceField;
  vo.sdfVoxels = o.voxels;
  vo.allowCpuDevice = !o.gpuOnly;
  vo.deviceNameFilter = o.device;
  SdfTimes t;
  // Two tracers: the first build warms the device (clocks, caches), the second is timed.
  for (int pass = 0; pass < 2; ++pass) {
    auto tracer = VulkanTracer::create(scene, TracerOptions{}, vo);
    if (!tracer) return tracer.error();
    if (auto copy = (*tracer)->readSdf(); !copy) return copy.error();
    if (pass == 0) continue;
    t.build = (*tracer)->sdfBuildStats();
    SceneState state = evaluateScene(scene, 0.0);
    const float side = glm::length(scene.boundsMax - scene.boundsMin) / 80.0f;
    std::vector<std::pair<double, int>> updates;
    for (int i = 0; i <= o.updates; ++i) {
      // Back and forth along x by half a side: each move leaves bricks and reaches new ones.
      const float dx = (i % 2 == 0 ? 0.5f : -0.5f) * side;
      glm::mat4& m = state.instanceTransforms[std::size_t(crate)];
      m = glm::translate(glm::mat4(1.0f), glm::vec3(dx, 0, 0)) * m;
      if (Status s = (*tracer)->setState(state); !s) return s.error();
      if (auto copy = (*tracer)->readSdf(); !copy) return copy.error();
      const SdfBuildStats& u = (*tracer)->sdfBuildStats();
      // A move that needs more bricks than the field holds grows it and builds it whole
      // (server/vulkan_tracer_sdf.cpp); counted apart, not in the updates' median.
      if (i == 0) continue;
      if (u.update)
        updates.emplace_back(u.gpuMs, u.bricksBuilt);
      else
        ++t.regrown;
    }
    if (updates.empty())
      return Error{"every timed move of the crate rebuilt the whole distance field"};
    std::sort(updates.begin(), updates.end());
    t.updateMs = updates[updates.size() / 2].first;
    t.updateBricks = updates[updates.size() / 2].second;
  }
  return t;
}

}  // namespace

Benchmark addSdf(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "sdf",
      "SDF backend: distance field build and update times, shared scenes and a height field");
  static SdfBenchSetup o;
  cmd->add_option("--scene", o.scenes, "scene files (default: the shared scenes)");
  addSceneLoadOptions(*cmd, sceneLoadOptions());
  cmd->add_option("--cells", o.cells, "height field quads a side, 2 triangles each; 0: none")
      ->capture_default_str();
  cmd->add_option("--size", o.size, "height field side, m")->capture_default_str();
  cmd->add_option("--sdf-voxels", o.voxels, "voxels along the grid's longest side")
      ->capture_default_str();
  cmd->add_option("--updates", o.updates, "timed crate moves (after one untimed)")
      ->capture_default_str();
  cmd->add_option("--device", o.device, "Vulkan device name substring");
  cmd->add_flag("--gpu-only", o.gpuOnly, "refuse CPU Vulkan implementations (lavapipe)");
  return {cmd, [] {
            std::vector<std::string> files = o.scenes.empty() ? sharedSceneFiles() : o.scenes;
            if (files.empty() && o.scenes.empty())
              std::printf("sdf: the shared scenes folder %s is absent: height field only\n",
                          PC_SCENES_DIR);
            std::vector<std::pair<std::string, Scene>> scenes;
            for (const std::string& f : files) {
              auto scene = loadBenchScene(f, "");
              if (!scene) {
                std::fprintf(stderr, "sdf: %s\n", scene.error().message.c_str());
                return 1;
              }
              scenes.emplace_back(sceneSlug(*scene), std::move(scene).value());
            }
            if (o.cells > 0) scenes.emplace_back("height_field", heightField(o.cells, o.size));
            std::printf("host: %s\n", machineDescription().c_str());
            std::printf("%-28s %10s %8s %8s %9s %10s %10s %9s %8s\n", "scene", "triangles",
                        "bricks", "MiB", "voxel m", "build ms", "update ms", "refilled", "regrown");
            for (auto& [slug, scene] : scenes) {
              const int crate = addCrate(scene);
              auto t = measure(scene, crate, o);
              if (!t) {
                std::fprintf(stderr, "sdf: %s: %s\n", slug.c_str(), t.error().message.c_str());
                return 1;
              }
              std::printf("%-28s %10d %8d %8.1f %9.4g %10.2f %10.3f %9d %8d\n", slug.c_str(),
                          t->build.triangles, t->build.bricksBuilt,
                          double(t->build.bytes) / double(1 << 20), double(t->build.voxel),
                          t->build.gpuMs, t->updateMs, t->updateBricks, t->regrown);
              figure("sdf_build_ms." + slug, t->build.gpuMs, "ms");
              figure("sdf_update_ms." + slug, t->updateMs, "ms");
            }
            return 0;
          }};
}

}  // namespace pc::bench
