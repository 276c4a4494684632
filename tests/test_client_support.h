// Shared steps of the client tests: a validating lavapipe context, a quickly baked field and
// one rendered frame. The scenes come from PC_SCENES_DIR; tests skip where it is absent.
#pragma once

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include "client/camera.h"
#include "client/field_mirror.h"
#include "client/renderer.h"
#include "common/vulkan/context.h"
#include "cpu/path_tracer.h"
#include "server/bake.h"
#include "server/tracer.h"
#include "test_tracer_support.h"

namespace pc::client::test {

inline std::filesystem::path scenePath(const std::string& relative) {
  return std::filesystem::path(PC_SCENES_DIR) / relative;
}

// build/test-client/<name>, created: where a test leaves its images for inspection.
inline std::filesystem::path testOutputDir(const std::string& name) {
  const std::filesystem::path dir = std::filesystem::path(PC_BUILD_DIR) / "test-client" / name;
  std::filesystem::create_directories(dir);
  return dir;
}

// A context with the validation layer on; null (and a message) without a Vulkan device.
inline std::unique_ptr<vk::Context> validatingContext() {
  vk::ContextOptions o;
  o.validation = true;
  o.allowCpuDevice = true;
  o.multiview = true;
  auto ctx = vk::Context::create(o);
  if (!ctx) {
    std::printf("no Vulkan device: %s\n", ctx.error().message.c_str());
    return nullptr;
  }
  return std::move(ctx).value();
}

inline Field bakeQuickly(const Scene& scene, int updates) {
  std::vector<ProbeVolume> volumes = scene.volumes.empty() ? defaultVolumes(scene) : scene.volumes;
  Field field = Field::create(volumes, FieldSettings{});
  field.sceneHash = scene.hash;
  auto tracer = makeEmbreeTracer(scene);
  EXPECT_TRUE(tracer.ok());
  if (!tracer) return field;
  BakeOptions options;
  options.updates = updates;
  bakeOrFail(field, **tracer, options);
  return field;
}

struct ClientFrame {
  std::vector<Image> linear;
  std::vector<Image8> display;
};

// Renders one frame (both eyes with cameras[1] set) and checks the validation layer stayed quiet.
inline ClientFrame renderClientFrame(vk::Context& ctx, const Scene& scene, const Field* field,
                                     const Camera& left, const Camera* right, int width, int height,
                                     ShadowSettings shadows = {},
                                     Rasterizer rasterizer = Rasterizer::Auto,
                                     bool textureMipmaps = true,
                                     float aoRadius = gpu::PC_AO_DEFAULT_RADIUS) {
  FieldMirror mirror;
  if (field) mirror.reset(*field, 0.0);
  RendererOptions ro;
  ro.width = width;
  ro.height = height;
  ro.views = right ? 2 : 1;
  ro.shadows = shadows;
  ro.rasterizer = rasterizer;
  ro.textureMipmaps = textureMipmaps;
  ro.aoRadius = aoRadius;
  auto renderer = Renderer::create(ctx, scene, mirror, ro);
  EXPECT_TRUE(renderer.ok()) << (renderer ? "" : renderer.error().message);
  if (!renderer) return {};
  FrameInput input;
  input.cameras[0] = left;
  if (right) input.cameras[1] = *right;
  auto frame = (*renderer)->renderOffscreen(input);
  EXPECT_TRUE(frame.ok()) << (frame ? "" : frame.error().message);
  (*renderer).reset();
  EXPECT_EQ(ctx.validationErrorCount(), 0u);
  if (!frame) return {};
  return {std::move(frame->linear), std::move(frame->display)};
}

}  // namespace pc::client::test
