// The Vulkan context and its helpers on whatever device is present (lavapipe in CI), with the
// validation layer on: any validation error fails the test.
#include <gtest/gtest.h>

#include <cstring>

#include "common/vulkan/context.h"

namespace {

using namespace pc::vk;
using pc::Status;

std::unique_ptr<Context> makeContext(bool rayTracing,
                                     std::uint32_t apiVersion = VK_API_VERSION_1_3) {
  ContextOptions o;
  o.apiVersion = apiVersion;
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

// A buffer copied, timed and barriered, and an image uploaded, on `ctx`; no validation error.
void roundTrip(const Context& ctx_) {
  const Context* ctx = &ctx_;
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
    memoryBarrier(cmd, VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT,
                  VK_PIPELINE_STAGE_2_HOST_BIT, VK_ACCESS_2_HOST_READ_BIT);
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

TEST(VulkanContext, CreatesDeviceAndRoundTripsABuffer) {
  auto ctx = makeContext(false);
  if (!ctx)
    GTEST_SKIP() << "no Vulkan device (install mesa-vulkan-drivers from bookworm-backports)";
  roundTrip(*ctx);
}

// The server's tracers ask for Vulkan 1.2: the shared helpers then use no 1.3 command (the
// validation layer reports any 1.3 command recorded on a device created for 1.2).
TEST(VulkanContext, AVulkan12ContextRunsTheSharedHelpers) {
  auto ctx = makeContext(false, VK_API_VERSION_1_2);
  if (!ctx) GTEST_SKIP() << "no Vulkan device";
  roundTrip(*ctx);
}

TEST(VulkanContext, VersionsOlderThan12AreRefusedByName) {
  ContextOptions o;
  o.allowCpuDevice = true;
  o.apiVersion = VK_API_VERSION_1_1;
  auto ctx = Context::create(o);
  ASSERT_FALSE(ctx);
  EXPECT_NE(ctx.error().message.find("Vulkan 1.1 asked for"), std::string::npos)
      << ctx.error().message;
}

// synchronization2's masks recorded with 1.0's barrier: every bit lands on a 1.0 flag that
// covers it, and an empty mask on the stage 1.0 asks for.
TEST(VulkanContext, LegacyMasksCoverEverySynchronization2Bit) {
  EXPECT_EQ(legacyStages(VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, true),
            VkPipelineStageFlags(VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT));
  EXPECT_EQ(legacyStages(VK_PIPELINE_STAGE_2_COPY_BIT | VK_PIPELINE_STAGE_2_CLEAR_BIT, true),
            VkPipelineStageFlags(VK_PIPELINE_STAGE_TRANSFER_BIT));
  EXPECT_EQ(legacyStages(VK_PIPELINE_STAGE_2_INDEX_INPUT_BIT, false),
            VkPipelineStageFlags(VK_PIPELINE_STAGE_VERTEX_INPUT_BIT));
  EXPECT_EQ(legacyStages(VK_PIPELINE_STAGE_2_RAY_TRACING_SHADER_BIT_KHR |
                             VK_PIPELINE_STAGE_2_ACCELERATION_STRUCTURE_BUILD_BIT_KHR,
                         true),
            VkPipelineStageFlags(VK_PIPELINE_STAGE_RAY_TRACING_SHADER_BIT_KHR |
                                 VK_PIPELINE_STAGE_ACCELERATION_STRUCTURE_BUILD_BIT_KHR));
  EXPECT_EQ(legacyStages(VK_PIPELINE_STAGE_2_NONE, true),
            VkPipelineStageFlags(VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT));
  EXPECT_EQ(legacyStages(VK_PIPELINE_STAGE_2_NONE, false),
            VkPipelineStageFlags(VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT));
  EXPECT_EQ(legacyAccess(VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_SAMPLED_READ_BIT),
            VkAccessFlags(VK_ACCESS_SHADER_READ_BIT));
  EXPECT_EQ(legacyAccess(VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT | VK_ACCESS_2_TRANSFER_WRITE_BIT),
            VkAccessFlags(VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT));
  EXPECT_EQ(legacyAccess(VK_ACCESS_2_NONE), VkAccessFlags(0));
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
