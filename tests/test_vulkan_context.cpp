// The Vulkan context and its helpers on whatever device is present (lavapipe in CI), with the
// validation layer on: any validation error fails the test.
#include <gtest/gtest.h>

#include <cstring>

#include "common/vulkan/context.h"

namespace {

using namespace pc::vk;
using pc::Status;

std::unique_ptr<Context> makeContext(bool rayTracing) {
  ContextOptions o;
  o.validation = true;
  o.allowCpuDevice = true;
  o.rayTracing = rayTracing;
  auto ctx = Context::create(o);
  if (!ctx) {
    std::printf("no Vulkan device: %s\n", ctx.error().message.c_str());
    return nullptr;
  }
  return std::move(ctx).value();
}

TEST(VulkanContext, CreatesDeviceAndRoundTripsABuffer) {
  auto ctx = makeContext(false);
  if (!ctx)
    GTEST_SKIP() << "no Vulkan device (install mesa-vulkan-drivers from bookworm-backports)";
  EXPECT_FALSE(ctx->deviceName().empty());
  auto src = Buffer::create(*ctx, 1024, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, MemoryUsage::Upload);
  auto dst = Buffer::create(*ctx, 1024, VK_BUFFER_USAGE_TRANSFER_DST_BIT, MemoryUsage::Readback);
  ASSERT_TRUE(src) << src.error().message;
  ASSERT_TRUE(dst) << dst.error().message;
  std::vector<std::uint32_t> data(256);
  for (std::uint32_t i = 0; i < 256; ++i) data[i] = i * 7u;
  src->write(data.data(), 1024);
  auto timer = GpuTimer::create(*ctx);
  ASSERT_TRUE(timer) << timer.error().message;
  Status s = ctx->submitAndWait([&](VkCommandBuffer cmd) {
    timer->reset(cmd);
    timer->begin(cmd, "copy");
    VkBufferCopy copy{0, 0, 1024};
    vkCmdCopyBuffer(cmd, src->get(), dst->get(), 1, &copy);
    timer->end(cmd);
  });
  ASSERT_TRUE(s) << s.error().message;
  ASSERT_EQ(dst->invalidate(), VK_SUCCESS);
  EXPECT_EQ(std::memcmp(dst->mapped(), data.data(), 1024), 0);
  auto times = timer->results();
  if (timer->supported()) {
    ASSERT_EQ(times.size(), 1u);
    EXPECT_EQ(times[0].first, "copy");
    EXPECT_GE(times[0].second, 0.0);
  }

  auto image = Image::create(*ctx, ImageDesc{VK_FORMAT_R8G8B8A8_SRGB, 4, 4, 2});
  ASSERT_TRUE(image) << image.error().message;
  std::vector<std::uint8_t> texels(4 * 4 * 4 * 2, 128);
  Status up = image->upload(texels.data(), texels.size());
  EXPECT_TRUE(up) << (up ? "" : up.error().message);
  EXPECT_EQ(image->layout(), VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL);
  EXPECT_EQ(ctx->validationErrorCount(), 0u);
}

TEST(VulkanContext, RayTracingDeviceOrClearError) {
  ContextOptions o;
  o.allowCpuDevice = true;
  o.rayTracing = true;
  auto ctx = Context::create(o);
  if (!ctx) {
    // The message must say what is missing.
    EXPECT_NE(ctx.error().message.find("Vulkan"), std::string::npos) << ctx.error().message;
    GTEST_SKIP() << ctx.error().message;
  }
  EXPECT_NE((*ctx)->rt().cmdTraceRays, nullptr);
  EXPECT_GT((*ctx)->rayTracingProperties().shaderGroupHandleSize, 0u);
}

TEST(VulkanContext, ShaderPathIsBesideTheExecutable) {
  const auto p = shaderPath("x.comp.spv");
  EXPECT_EQ(p.filename(), "x.comp.spv");
  EXPECT_EQ(p.parent_path().filename(), "shaders");
}

TEST(VulkanContext, MissingShaderIsAnError) {
  auto ctx = makeContext(false);
  if (!ctx) GTEST_SKIP() << "no Vulkan device";
  auto m = loadShader(*ctx, "does_not_exist.comp.spv");
  ASSERT_FALSE(m);
  EXPECT_NE(m.error().message.find("does_not_exist"), std::string::npos);
}

}  // namespace
