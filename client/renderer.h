// The client's frame: field uploads, shadow maps, the main pass (a multisampled visibility
// buffer: which triangle covers each sample), the lighting pass (rebuilds each distinct surface
// of a pixel; emission, direct light with shadow maps and indirect light from the field's
// cascades, in compute, the field's light darkened at contacts by screen-space occlusion over
// the surfaces a pass before it writes) and tone mapping with the overlay, in one command
// buffer per frame. Frames rotate through kFrameSlots slots, each with its own command
// buffer, uniforms and staging, so the CPU prepares frame N+1 while the GPU draws frame N.
// Stereo renders both eyes in every pass with VK_KHR_multiview (2-layer targets).
#pragma once

#include <array>
#include <glm/glm.hpp>
#include <initializer_list>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "common/emissive_lights.h"
#include "common/image.h"
#include "common/result.h"
#include "common/scene.h"
#include "common/vulkan/context.h"
#include "field_gpu.h"
#include "field_mirror.h"
#include "gpu_scene.h"
#include "light_pack.h"
#include "probe_view.h"
#include "protocol/session_messages.h"
#include "renderer_shadow_cache.h"
#include "shaders/interop/screen_ao.h"

namespace pc::client {

inline constexpr int kFrameSlots = 2;

enum class Rasterizer { Auto, FixedFunction, Compute };
// "auto", "fixed" or "compute" (command lines).
std::optional<Rasterizer> parseRasterizer(std::string_view name);
const char* rasterizerName(Rasterizer r);

struct RendererOptions {
  int width = 640, height = 360;
  int views = 1;  // 2: stereo (multiview)
  // Stereo only: tone mapping writes both eyes side by side into one 2*width x height image
  // (a window), instead of one layer per eye.
  bool sideBySide = false;
  int msaa = 4;  // samples per pixel: 2, 4 or 8
  ShadowSettings shadows;
  int sampleFlags = 0;      // PC_SAMPLE_* for the field
  int bricksPerFrame = 32;  // field upload budget per frame
  // A changed brick fades in over this long (the window uses 0.15 s); 0: at once, so that
  // headless images show exactly the field the mirror holds.
  double fieldFadeSeconds = 0.0;
  std::optional<glm::vec3> ambient;  // irradiance where no field covers; default from the sky
  // Depth-only pass first, then the visibility pass with an EQUAL depth test: each sample's id
  // is written once, whatever the draw order. Even with a fragment stage this cheap it pays
  // where fragments are dear (H100, sauer-pandora 1080p 4x: main pass 3.42 ms with it, 3.94
  // without).
  bool depthPrepass = true;
  // false: the lighting pass skips the field and uses the ambient term (the bench times the
  // probe sampling as the difference).
  bool sampleField = true;
  // Who draws the visibility buffer: compute shaders (client_raster*.comp) or the
  // fixed-function pipeline (with VK_KHR_multiview for stereo). Auto takes compute where the
  // device has 64-bit buffer atomics: it was faster everywhere it was measured (H100 1080p
  // 4x: 0.37 against 2.80 ms on sauer-pandora; lavapipe too), most where graphics units are
  // few next to compute. The depth pre-pass applies to the fixed-function path only.
  Rasterizer rasterizer = Rasterizer::Auto;
  // Textures with mip chains, each lookup filtered over its pixel's footprint (trilinear,
  // anisotropic where the device has it). false: one bilinear tap of level 0 per sample, as
  // the CPU renders take per ray (minified textures alias).
  bool textureMipmaps = true;
  // Screen-space ambient occlusion (GTAO, shaders/interop/screen_ao.h) of the field's indirect
  // light, radius in probe spacings: contacts the probes are too coarse to see. 0: off (the
  // surface pass before lighting is skipped too).
  float aoRadius = gpu::PC_AO_DEFAULT_RADIUS;
  // Glossy surfaces: the field's split-sum specular (shaders/interop/specular_probe.h) besides
  // its irradiance. false: the indirect light stays diffuse (the comparison without it).
  bool indirectSpecular = true;
  // Foveated field sampling: outside this radius (a fraction of the view's half width and
  // height, an ellipse about its centre, where a headset's lens is sharpest) the lighting pass
  // samples the field at one pixel of each 2x2 quad and shares it with the quad's pixels on the
  // same surface (client_indirect.comp). 0: every pixel samples the field.
  float foveaRadius = 0.0f;
};

struct FrameInput {
  double time = 0.0;                 // animation time (lights and instances move)
  std::array<Camera, 2> cameras;     // [0] mono or left eye, [1] right eye
  std::vector<std::string> overlay;  // text lines; empty: no overlay
  // Seconds on the clock that paces field fades; unset: a steady clock (wall time).
  std::optional<double> clock;
  // The probe debug view over the lit frame (client_probe_view.comp); off by default.
  ProbeViewSettings probeView;
  // The server's scene state while runtime edits are in force (NetClient::editedScene): its
  // lights, instance transforms and emission replace the animation's at `time`, so direct
  // light and the field describe the same scene. Added lights past the renderer's light
  // count (fixed at creation) are left out.
  std::optional<SceneStateMsg> edited;
};

// Where tone mapping writes: an 8-bit UNORM color image with one layer per view (side by
// side: one layer twice the render width).
struct OutputTarget {
  VkImage image = VK_NULL_HANDLE;
  VkImageView view = VK_NULL_HANDLE;  // 2D_ARRAY view for multiview targets, else 2D
  VkFormat format = VK_FORMAT_R8G8B8A8_UNORM;
  VkImageLayout finalLayout = VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL;
};

// GPU milliseconds of one finished frame (timestamp queries).
struct FrameTimings {
  bool valid = false;
  double uploadMs = 0, shadowMs = 0, mainMs = 0, probeMs = 0, tonemapMs = 0;
  // Compute rasterizer: triangles not drawn because its work lists were full (0 normally).
  std::uint32_t rasterDropped = 0;
  double frameMs() const { return uploadMs + shadowMs + mainMs + probeMs + tonemapMs; }
};

// What the last recorded frame drew (for benchmarks and tests).
struct FrameStats {
  int bricksUploaded = 0;       // field bricks staged this frame
  int bricksFading = 0;         // field bricks still fading in
  int drawCalls = 0;            // all passes
  std::uint64_t triangles = 0;  // all passes, per view
  int lights = 0;               // lights every main-pass fragment loops over
  int shadowViews = 0;          // shadow map layers the lights use
  int shadowViewsDrawn = 0;     // of those, redrawn this frame (the rest kept from before)
  int msaa = 0;                 // samples per pixel of the main pass
};

class Renderer {
 public:
  static Result<std::unique_ptr<Renderer>> create(const vk::Context& ctx, const Scene& scene,
                                                  FieldMirror& mirror,
                                                  const RendererOptions& options);
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  const RendererOptions& options() const { return options_; }
  int areaLightCount() const { return areaLights_; }
  // New render size; waits for the GPU (resizes are rare).
  Status resize(int width, int height);

  // Waits for the next slot's previous frame (normally finished long ago), collects its
  // timings and returns the slot's command buffer, begun.
  Result<VkCommandBuffer> beginFrame();
  // Records the whole frame into the command buffer from beginFrame.
  void recordFrame(VkCommandBuffer cmd, const FrameInput& input, const OutputTarget& target);
  // Ends and submits it; `wait` semaphores gate the tone-mapping output, `signal` (optional)
  // fires when it is done.
  Status endFrame(VkSemaphore wait = VK_NULL_HANDLE, VkSemaphore signal = VK_NULL_HANDLE);
  // Timings of the most recently completed frame.
  const FrameTimings& lastTimings() const { return timings_; }
  // The field's GPU copy (tests read its atlases back).
  const FieldGpu& fieldGpu() const { return *field_; }
  // Counts of the most recently recorded frame.
  const FrameStats& lastStats() const { return stats_; }
  // The frame slot beginFrame chose (for per-slot objects of the caller, like semaphores).
  int currentSlot() const { return current_; }
  // Context::waitIdle: a lost device's error, returned.
  VkResult waitIdle() const;

  // Headless: renders one frame into an offscreen target and reads back the linear and the
  // tone-mapped image of every view (waits for the frame).
  struct Readback {
    std::vector<Image> linear;    // per view
    std::vector<Image8> display;  // per view
  };
  Result<Readback> renderOffscreen(const FrameInput& input);
  // Headless, pipelined: records and submits one frame into the offscreen target and returns
  // without waiting or reading back (frames overlap CPU and GPU work as in a window; timings
  // arrive through lastTimings() once the slot comes round again).
  Status renderFrame(const FrameInput& input);

 private:
  Renderer() = default;
  bool sideBySide() const { return options_.views == 2 && options_.sideBySide; }
  bool computeRaster() const { return options_.rasterizer == Rasterizer::Compute; }
  struct Slot;
  // create's steps, in order.
  void chooseViewDefaults();  // near plane and ambient term from the scene
  Status createSceneBuffers();
  Status createField();
  void countLights();   // light, matrix and shadow layer counts (fixed by the scene)
  void measureDraws();  // drawBounds_
  Status createSamplers();
  Status createShadowArrays();
  Status createShadowArray(int array, int size, bool large);
  Status createTargets();
  Status createPipelines();
  Status createFrameSlot();
  Status createDescriptorSets();
  Status writeDescriptors();
  Result<VkPipeline> tonemapPipeline(VkFormat format);
  void updateFrameData(Slot& slot, const FrameInput& input);
  // The probe view's uniforms; writes the slot's brick flashes when the view is on.
  gpu::ProbeViewParams probeViewParams(Slot& slot, const FrameInput& input);
  // recordFrame's passes, in order.
  void recordFieldUploads(VkCommandBuffer cmd, const FrameInput& input);
  void recordShadowMaps(VkCommandBuffer cmd, const Slot& slot);
  void recordShadowBarriers(VkCommandBuffer cmd, const Slot& slot, bool toAttachment);
  void recordVisibility(VkCommandBuffer cmd, Slot& slot);
  void recordFixedFunctionRaster(VkCommandBuffer cmd, const Slot& slot);
  void recordLighting(VkCommandBuffer cmd, const Slot& slot);
  void recordProbeView(VkCommandBuffer cmd);
  void recordTonemap(VkCommandBuffer cmd, const OutputTarget& target);
  void drawScene(VkCommandBuffer cmd, const Slot& slot, std::initializer_list<glm::mat4> views);
  void collectTimings(Slot& slot);

  const vk::Context* ctx_ = nullptr;
  const Scene* scene_ = nullptr;
  std::optional<EmissiveSurfaces> emissive_;  // found once; each frame only places them
  FieldMirror* mirror_ = nullptr;
  RendererOptions options_;
  std::optional<GpuScene> gpuScene_;
  std::optional<FieldGpu> field_;
  int areaLights_ = 0;
  int shadowLayers_[kShadowArrays] = {0, 0, 0};
  int lightCount_ = 0, matrixCount_ = 0;
  float nearPlane_ = 0.01f;
  glm::vec3 ambient_{0.0f};

  // Render targets (shared by the slots: the queue runs frames in order).
  struct Target {
    vk::Image image;
    vk::UniqueImageView arrayView;
  };
  Target visibility_, depth_, hdr_, offscreen_;
  struct ShadowArray {
    vk::Image image;
    vk::UniqueImageView view;                     // all layers, sampled
    std::vector<vk::UniqueImageView> layerViews;  // one per layer, rendered to
    int size = 0;                                 // texels per side
    bool large = true;                            // D32 (else D16)
  };
  ShadowArray shadowArrays_[kShadowArrays];

  vk::UniqueSampler linearSampler_, nearestSampler_, shadowSampler_;
  vk::UniqueDescriptorSetLayout setLayout_;
  vk::UniquePipelineLayout pipelineLayout_;
  vk::UniqueDescriptorPool descriptorPool_;
  vk::UniquePipeline scenePipeline_, prepassPipeline_, largeShadowPipeline_, smallShadowPipeline_,
      indirectPipeline_, aoSurfacesPipeline_, rasterPipeline_, rasterArgsPipeline_,
      rasterTilesPipeline_, probeViewPipeline_;
  // Compute rasterizer: per-sample depth and id, its work lists and counters (minimal buffers
  // when it is off, so that every descriptor stays valid).
  vk::Buffer visSamples_, rasterTriangles_, rasterJobs_, rasterCounters_;
  // The surfaces under the pixel centres, for the ambient occlusion (PC_CLIENT_BIND_AO_SURFACES).
  vk::Buffer aoSurfaces_;
  std::uint32_t rasterTriangleCapacity_ = 0, rasterJobCapacity_ = 0;
  bool rasterDropWarned_ = false;
  void recordComputeRaster(VkCommandBuffer cmd, Slot& slot);
  std::map<VkFormat, vk::UniquePipeline> tonemapPipelines_;

  std::optional<vk::CommandPool> commandPool_;
  std::vector<std::unique_ptr<Slot>> slots_;
  int current_ = -1;
  FrameTimings timings_;
  FrameStats stats_;
  ShadowCache shadowCache_;
  std::vector<LocalBounds> drawBounds_;  // per draw, object space
  BrickFlash brickFlash_;                // the probe view's flashes of changed bricks
  std::size_t brickCount_ = 0;           // bricks of all cascades (the flash buffers' size)
  vk::Buffer readback_;
};

}  // namespace pc::client
