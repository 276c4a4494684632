// probecast-client's two front ends over the renderer: headless (offscreen, writes a
// tone-mapped PNG and a linear EXR per frame and view) and windowed (GLFW, fly camera,
// overlay). Both load the scene, the baked fallback field and the Vulkan context the same way.
#pragma once

#include <glm/glm.hpp>
#include <optional>
#include <string>

#include "common/scene.h"
#include "light_pack.h"
#include "renderer.h"

namespace pc::client {

struct ClientConfig {
  std::string scene;             // scene file, or "builtin"
  std::string sidecar;           // optional scene.json
  SceneLoadOptions sceneLoad;    // what the scene file may read and allocate
  std::string probes;            // baked .probes file; empty: none (ambient)
  std::string outDir = ".";      // headless output folder
  std::string prefix = "frame";  // headless file names: <prefix>_<frame>[_left|_right].png/.exr
  int width = 640, height = 360;
  int frames = 1;          // headless: frames written; windowed: 0 runs until closed
  double startTime = 0.0;  // animation time of the first frame
  double dt = 1.0 / 30.0;  // seconds per frame; windowed: < 0 follows the wall clock
  int camera = 0;          // sidecar camera index
  std::optional<glm::vec3> position, direction, target;  // override the sidecar camera
  std::optional<float> fovDegrees;
  bool stereo = false;
  float ipd = 0.064f;  // interpupillary distance, scene units
  bool windowed = false;
  bool validation = false;  // Khronos validation layer; errors make the run fail
  bool overlay = true;
  int msaa = 4;
  Rasterizer rasterizer = Rasterizer::Auto;  // RendererOptions::rasterizer
  bool textureMipmaps = true;                // RendererOptions::textureMipmaps
  ShadowSettings shadows;
  int sampleFlags = 0;
  float aoRadius = gpu::PC_AO_DEFAULT_RADIUS;  // RendererOptions::aoRadius
  float foveaRadius = 0.0f;                    // RendererOptions::foveaRadius
  // The probe debug view the run starts with (windowed: keys P, M, C and L change it).
  ProbeViewSettings probeView;
  std::string readyFile;  // windowed: written after half the frames (tests take a screenshot)
  std::optional<glm::ivec2> testResize;  // windowed: resize the window to this after 2 frames
  bool writeExr = true;
};

// Both return the process exit code: 0 success, 1 bad input, 2 no usable Vulkan device,
// 3 validation errors.
int runHeadless(const ClientConfig& config);
int runWindowed(const ClientConfig& config);

}  // namespace pc::client
