// Windowed front end: GLFW window, swapchain (recreated on resize), fly camera (right mouse
// button drag to look, WASD/QE to move, shift for speed), overlay with frame time and field age.
// Stereo shows both eyes side by side, each half the window's width. With --connect the field
// streams from a server (NetClient on its own thread): the window follows the server's clock,
// sends the fly camera as the viewer, and rebuilds the renderer when the layout changes.
#define GLFW_INCLUDE_VULKAN
#include <GLFW/glfw3.h>

#include <cstdio>
#include <fstream>
#include <map>
#include <utility>

#include "camera.h"
#include "client_app.h"
#include "client_setup.h"
#include "common/log.h"
#include "net_app.h"
#include "renderer.h"
#include "swapchain.h"

namespace pc::client {
namespace {

// Owns glfwInit/glfwTerminate and the window.
struct Glfw {
  GLFWwindow* window = nullptr;
  bool initialized = false;
  ~Glfw() {
    if (window) glfwDestroyWindow(window);
    if (initialized) glfwTerminate();
  }
};

struct Surface {
  VkInstance instance = VK_NULL_HANDLE;
  VkSurfaceKHR surface = VK_NULL_HANDLE;
  ~Surface() {
    if (surface) vkDestroySurfaceKHR(instance, surface, nullptr);
  }
};

char* lineBuffer() {
  static char buffer[128];
  return buffer;
}

// Keys that act once per press, not on every frame they are held.
class KeyPresses {
 public:
  bool pressed(GLFWwindow* window, int key) {
    const bool down = glfwGetKey(window, key) == GLFW_PRESS;
    const bool was = std::exchange(down_[key], down);
    return down && !was;
  }

 private:
  std::map<int, bool> down_;
};

// The probe view's keys: P shows or hides it, M switches between irradiance and state
// colours (showing it), C cycles the cascade shown (all, 0, 1, ...), L the relocation lines.
void probeViewKeys(GLFWwindow* window, KeyPresses& keys, int cascadeCount, ProbeViewSettings& view,
                   ProbeViewMode& lastMode) {
  if (keys.pressed(window, GLFW_KEY_P)) {
    if (view.on()) lastMode = view.mode;
    view.mode = view.on() ? ProbeViewMode::Off : lastMode;
  }
  if (keys.pressed(window, GLFW_KEY_M)) {
    view.mode =
        view.mode == ProbeViewMode::State ? ProbeViewMode::Irradiance : ProbeViewMode::State;
    lastMode = view.mode;
  }
  if (keys.pressed(window, GLFW_KEY_C))
    view.cascade = nextProbeViewCascade(view.cascade, cascadeCount);
  if (keys.pressed(window, GLFW_KEY_L)) view.offsets = !view.offsets;
}

}  // namespace

// Changed bricks fade in over this long in the window (headless images stay exact).
constexpr double kFieldFadeSeconds = 0.15;

int runWindow(const ClientConfig& config, const NetRunConfig* net) {
  auto scene = loadClientScene(config);
  if (!scene) {
    logError(scene.error().message);
    return 1;
  }
  auto camera = clientCamera(*scene, config);
  if (!camera) {
    logError(camera.error().message);
    return 1;
  }
  FieldMirror mirror;
  if ((!net || !config.probes.empty()) && !loadFallbackField(*scene, config, mirror))
    return 1;  // logged
  std::optional<NetClient> client;
  if (net) {
    client.emplace(mirror, net->net);
    client->setViewer(camera->position,
                      glm::quatLookAt(glm::normalize(camera->forward), camera->up));
    client->start();
  }

  Glfw glfw;
  if (!glfwInit()) {
    logError("cannot open a window: GLFW could not initialize (no display? use headless mode)");
    return 1;
  }
  glfw.initialized = true;
  if (!glfwVulkanSupported()) {
    logError(
        "no Vulkan loader or driver for windows: install mesa-vulkan-drivers from "
        "bookworm-backports (lavapipe) or your GPU's Vulkan driver");
    return 2;
  }
  std::uint32_t extCount = 0;
  const char** exts = glfwGetRequiredInstanceExtensions(&extCount);
  std::vector<std::string> instanceExtensions(exts, exts + extCount);
  ClientConfig windowed = config;
  windowed.windowed = true;
  auto ctx = createClientContext(windowed, instanceExtensions);
  if (!ctx) {
    logError(ctx.error().message);
    return 2;
  }
  logInfo("Vulkan device: " + (*ctx)->deviceName());

  glfwWindowHint(GLFW_CLIENT_API, GLFW_NO_API);
  glfwWindowHint(GLFW_RESIZABLE, GLFW_TRUE);
  glfw.window = glfwCreateWindow(config.width, config.height, "probecast", nullptr, nullptr);
  if (!glfw.window) {
    logError("cannot create the window");
    return 1;
  }
  Surface surface{(*ctx)->instance()};
  if (glfwCreateWindowSurface((*ctx)->instance(), glfw.window, nullptr, &surface.surface) !=
      VK_SUCCESS) {
    logError("cannot create a Vulkan surface for the window");
    return 2;
  }

  int status = 0;
  {
    Swapchain swapchain(**ctx, surface.surface);
    Status s =
        swapchain.create({std::uint32_t(config.width), std::uint32_t(config.height)}, kFrameSlots);
    if (!s) {
      logError("swapchain: " + s.error().message);
      return 1;
    }
    // Stereo: both eyes side by side, each half the window's width.
    const int eyes = config.stereo ? 2 : 1;
    RendererOptions ro;
    ro.views = eyes;
    ro.sideBySide = config.stereo;
    ro.width = std::max(1, int(swapchain.extent().width) / eyes);
    ro.height = int(swapchain.extent().height);
    ro.msaa = config.msaa;
    ro.rasterizer = config.rasterizer;
    ro.textureMipmaps = config.textureMipmaps;
    ro.shadows = config.shadows;
    ro.sampleFlags = config.sampleFlags;
    ro.aoRadius = config.aoRadius;
    ro.foveaRadius = config.foveaRadius;
    ro.fieldFadeSeconds = kFieldFadeSeconds;
    auto renderer = Renderer::create(**ctx, *scene, mirror, ro);
    if (!renderer) {
      logError("renderer: " + renderer.error().message);
      return 1;
    }
    std::uint64_t generation = client ? client->layoutGeneration() : 0;
    const double start = secondsNow();

    FlyCamera fly(*camera);
    KeyPresses keys;
    ProbeViewSettings probeView = config.probeView;
    ProbeViewMode lastProbeMode = probeView.on() ? probeView.mode : ProbeViewMode::Irradiance;
    const float speed = 0.25f * std::max(glm::length(scene->boundsMax - scene->boundsMin), 1e-3f);
    double lastTime = secondsNow(), animationTime = config.startTime;
    double lastX = 0, lastY = 0;
    bool dragging = false, recreate = false;
    double cpuFrameMs = 0;
    for (int frame = 0;
         !glfwWindowShouldClose(glfw.window) && (config.frames <= 0 || frame < config.frames);
         ++frame) {
      glfwPollEvents();
      const double now = secondsNow();
      if (net && net->duration > 0 && now - start >= net->duration) break;
      const float dt = float(now - lastTime);
      cpuFrameMs = 0.9 * cpuFrameMs + 0.1 * dt * 1000.0;
      lastTime = now;
      animationTime += config.dt >= 0.0 ? config.dt : dt;
      if (client) {
        // The server's clock when synced: direct light then matches its indirect light.
        animationTime = client->animationTime().value_or(animationTime);
        client->setViewer(fly.camera().position,
                          glm::quatLookAt(glm::normalize(fly.camera().forward), fly.camera().up));
        if (client->layoutGeneration() != generation) {
          // The server's layout differs from the one the renderer was made for: rebuild it
          // around the mirror, at the window's current size.
          generation = client->layoutGeneration();
          (*renderer)->waitIdle();
          (*renderer).reset();
          ro.width = std::max(1, int(swapchain.extent().width) / eyes);
          ro.height = int(swapchain.extent().height);
          renderer = Renderer::create(**ctx, *scene, mirror, ro);
          if (!renderer) {
            logError("renderer: " + renderer.error().message);
            status = 1;
            break;
          }
        }
      }

      // ---- input ----
      if (glfwGetKey(glfw.window, GLFW_KEY_ESCAPE) == GLFW_PRESS)
        glfwSetWindowShouldClose(glfw.window, 1);
      double x, y;
      glfwGetCursorPos(glfw.window, &x, &y);
      const bool look = glfwGetMouseButton(glfw.window, GLFW_MOUSE_BUTTON_RIGHT) == GLFW_PRESS;
      if (look && dragging) fly.rotate(float(x - lastX), float(y - lastY));
      dragging = look;
      lastX = x;
      lastY = y;
      auto key = [&](int k) { return glfwGetKey(glfw.window, k) == GLFW_PRESS ? 1.0f : 0.0f; };
      const float step = speed * dt * (key(GLFW_KEY_LEFT_SHIFT) > 0 ? 4.0f : 1.0f);
      fly.move(step * (key(GLFW_KEY_W) - key(GLFW_KEY_S)),
               step * (key(GLFW_KEY_D) - key(GLFW_KEY_A)),
               step * (key(GLFW_KEY_E) - key(GLFW_KEY_Q)));
      const std::optional<gpu::FieldDesc> layout = mirror.desc();
      probeViewKeys(glfw.window, keys, layout ? layout->cascadeCount : 0, probeView, lastProbeMode);
      if (config.testResize && frame == 2) {
        glfwSetWindowSize(glfw.window, config.testResize->x, config.testResize->y);
      }

      // ---- swapchain follows the window ----
      int fbw = 0, fbh = 0;
      glfwGetFramebufferSize(glfw.window, &fbw, &fbh);
      if (fbw == 0 || fbh == 0) {  // minimized: nothing to draw
        glfwWaitEvents();
        continue;
      }
      if (recreate ||
          VkExtent2D{std::uint32_t(fbw), std::uint32_t(fbh)}.width != swapchain.extent().width ||
          std::uint32_t(fbh) != swapchain.extent().height) {
        (*renderer)->waitIdle();
        s = swapchain.create({std::uint32_t(fbw), std::uint32_t(fbh)}, kFrameSlots);
        if (!s) {
          logError("swapchain: " + s.error().message);
          status = 1;
          break;
        }
        s = (*renderer)->resize(std::max(1, int(swapchain.extent().width) / eyes),
                                int(swapchain.extent().height));
        if (!s) {
          logError("resize: " + s.error().message);
          status = 1;
          break;
        }
        recreate = false;
        logInfo("window now " + std::to_string(swapchain.extent().width) + "x" +
                std::to_string(swapchain.extent().height));
      }

      auto cmd = (*renderer)->beginFrame();
      if (!cmd) {
        logError(cmd.error().message);
        status = 1;
        break;
      }
      const int slot = (*renderer)->currentSlot();
      std::uint32_t imageIndex = 0;
      VkResult acquired =
          vkAcquireNextImageKHR((*ctx)->device(), swapchain.get(), UINT64_MAX,
                                swapchain.acquired(slot), VK_NULL_HANDLE, &imageIndex);
      while (acquired == VK_ERROR_OUT_OF_DATE_KHR) {
        // The begun command buffer is simply re-recorded below once an image is acquired.
        (*renderer)->waitIdle();
        glfwGetFramebufferSize(glfw.window, &fbw, &fbh);
        s = swapchain.create({std::uint32_t(std::max(fbw, 1)), std::uint32_t(std::max(fbh, 1))},
                             kFrameSlots);
        if (!s) break;
        s = (*renderer)->resize(std::max(1, int(swapchain.extent().width) / eyes),
                                int(swapchain.extent().height));
        if (!s) break;
        acquired = vkAcquireNextImageKHR((*ctx)->device(), swapchain.get(), UINT64_MAX,
                                         swapchain.acquired(slot), VK_NULL_HANDLE, &imageIndex);
      }
      if (acquired != VK_SUCCESS && acquired != VK_SUBOPTIMAL_KHR) {
        logError(std::string("acquiring a window image: ") + vk::resultName(acquired));
        status = 1;
        break;
      }

      FrameInput input;
      input.time = animationTime;
      input.probeView = probeView;
      if (client) input.edited = client->editedScene();
      if (config.stereo) {
        input.cameras[0] = offsetCamera(fly.camera(), -0.5f * config.ipd);
        input.cameras[1] = offsetCamera(fly.camera(), 0.5f * config.ipd);
      } else {
        input.cameras[0] = fly.camera();
      }
      if (config.overlay) {
        const FrameTimings& t = (*renderer)->lastTimings();
        const FieldAge age = mirror.age(secondsNow());
        std::snprintf(lineBuffer(), 128, "FRAME %.1f MS  GPU %.2f MS  PROBE %.2f MS", cpuFrameMs,
                      t.frameMs(), t.probeMs);
        input.overlay.push_back(lineBuffer());
        if (age.present) {
          std::snprintf(lineBuffer(), 128, "FIELD AGE %.1f S  V%llu  PENDING %d", age.newestSeconds,
                        static_cast<unsigned long long>(age.version), age.pendingBricks);
        } else {
          std::snprintf(lineBuffer(), 128, "NO FIELD: AMBIENT");
        }
        input.overlay.push_back(lineBuffer());
        std::snprintf(lineBuffer(), 128, "%ux%u  MSAA %dx%s", swapchain.extent().width,
                      swapchain.extent().height, config.msaa, config.stereo ? "  STEREO" : "");
        input.overlay.push_back(lineBuffer());
        if (client) {
          const NetClientStats ns = client->stats();
          std::snprintf(lineBuffer(), 128, "NET %s  BRICKS %d/%d  FADING %d",
                        ns.connected ? "CONNECTED" : "OFFLINE", ns.bricksHeld, ns.bricksTotal,
                        (*renderer)->lastStats().bricksFading);
          input.overlay.push_back(lineBuffer());
        }
        input.overlay.push_back(probeView.on() ? probeViewStatus(probeView)
                                               : "P PROBES  M COLOUR  C CASCADE  L LINES");
      }
      const OutputTarget target{swapchain.image(imageIndex), swapchain.view(imageIndex),
                                swapchain.format(), VK_IMAGE_LAYOUT_PRESENT_SRC_KHR};
      (*renderer)->recordFrame(*cmd, input, target);
      s = (*renderer)->endFrame(swapchain.acquired(slot), swapchain.rendered(imageIndex));
      if (!s) {
        logError(s.error().message);
        status = 1;
        break;
      }
      VkPresentInfoKHR pi{VK_STRUCTURE_TYPE_PRESENT_INFO_KHR};
      const VkSemaphore rendered = swapchain.rendered(imageIndex);
      const VkSwapchainKHR sc = swapchain.get();
      pi.waitSemaphoreCount = 1;
      pi.pWaitSemaphores = &rendered;
      pi.swapchainCount = 1;
      pi.pSwapchains = &sc;
      pi.pImageIndices = &imageIndex;
      const VkResult presented = vkQueuePresentKHR((*ctx)->queue(), &pi);
      if (presented == VK_ERROR_OUT_OF_DATE_KHR || presented == VK_SUBOPTIMAL_KHR) {
        recreate = true;
      } else if (presented != VK_SUCCESS) {
        logError(std::string("presenting: ") + vk::resultName(presented));
        status = 1;
        break;
      }
      if (!config.readyFile.empty() && frame == std::max(config.frames, 2) / 2) {
        (*renderer)->waitIdle();
        std::ofstream(config.readyFile) << "ready\n";
      }
    }
    if (renderer) (*renderer)->waitIdle();
  }
  if (client) client->stop();
  if ((*ctx)->validationErrorCount() > 0) {
    logError("validation errors: " + std::to_string((*ctx)->validationErrorCount()));
    return 3;
  }
  return status;
}

int runWindowed(const ClientConfig& config) { return runWindow(config, nullptr); }

int runNetWindowed(const ClientConfig& config, const NetRunConfig& run) {
  return runWindow(config, &run);
}

}  // namespace pc::client
