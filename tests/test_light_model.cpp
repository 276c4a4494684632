// The shared light model (shaders/interop/light_model.h) as C++ against known values, and as
// GLSL on the Vulkan device (lavapipe in CI, validation on) against the same header compiled
// as C++: every light type, inside and outside its cone and range, behind the surface, and the
// emitter geometry and ray offsets the tracers share, and the BRDF (shaders/interop/brdf.h)
// that weighs each light sample. The C++ side is what the Embree tracer
// and the CPU renders evaluate; the GLSL side what probe_shade.comp and the client evaluate.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include "common/light_pack.h"
#include "common/vulkan/check.h"
#include "common/vulkan/context.h"
#include "tests/glsl/light_model_check.h"

namespace {

using namespace pc;
using gpu::GpuLight;
using gpu::LightCheckCase;

struct NamedCase {
  std::string name;
  LightCheckCase c;
};

// Materials the cases cycle through (base colour, metallic; roughness): diffuse, a glossy
// dielectric, rough and near-mirror metals and a blend.
struct CheckMaterial {
  glm::vec4 material;
  float roughness;
};
constexpr CheckMaterial kCheckMaterials[] = {{{0.8f, 0.8f, 0.8f, 0.0f}, 1.0f},
                                             {{0.7f, 0.2f, 0.1f, 0.0f}, 0.4f},
                                             {{1.0f, 0.78f, 0.34f, 1.0f}, 0.6f},
                                             {{0.9f, 0.9f, 0.9f, 1.0f}, 0.05f},
                                             {{0.5f, 0.6f, 0.7f, 0.5f}, 0.25f}};

LightCheckCase makeCase(const Light& light, glm::vec3 P, glm::vec3 N) {
  LightCheckCase c{};
  c.light = packLight(light);
  c.position = glm::vec4(P, 0.0f);
  c.normal = glm::vec4(glm::normalize(N), 0.0f);
  return c;
}

// Gives case `index` a view a little off its normal (oblique enough for Fresnel and masking
// to act) and one of kCheckMaterials.
void addViewAndMaterial(LightCheckCase& c, std::size_t index) {
  const CheckMaterial& m = kCheckMaterials[index % std::size(kCheckMaterials)];
  const glm::vec3 V = glm::normalize(glm::vec3(c.normal) + glm::vec3(0.7f, 0.1f, -0.2f));
  c.view = glm::vec4(V, m.roughness);
  c.material = m.material;
}
Light pointLight(glm::vec3 position, float intensity, float range = 0.0f) {
  Light l;
  l.type = LightType::Point;
  l.position = position;
  l.intensity = intensity;
  l.range = range;
  return l;
}

Light spotLight(glm::vec3 position, glm::vec3 direction, float inner, float outer) {
  Light l;
  l.type = LightType::Spot;
  l.position = position;
  l.direction = direction;
  l.intensity = 8.0f;
  l.innerConeAngle = inner;
  l.outerConeAngle = outer;
  return l;
}

Light sun(glm::vec3 direction, float intensity) {
  Light l;
  l.type = LightType::Directional;
  l.direction = direction;
  l.intensity = intensity;
  return l;
}

// A client virtual point light for a patch of emitter facing `normal`, of area `patch`.
LightCheckCase areaCase(glm::vec3 position, glm::vec3 normal, float patch, glm::vec3 P,
                        glm::vec3 N) {
  LightCheckCase c{};
  c.light.type = gpu::PC_LIGHT_AREA;
  c.light.position = position;
  c.light.direction = glm::normalize(normal);
  c.light.power = glm::vec3(2.0f, 1.0f, 0.5f);
  c.light.range = patch;
  c.light.shadowLayer = -1;
  c.position = glm::vec4(P, 0.0f);
  c.normal = glm::vec4(glm::normalize(N), 0.0f);
  return c;
}

std::vector<NamedCase> cases() {
  const glm::vec3 up(0, 1, 0), origin(0.0f);
  const float cone = 0.5f;  // outer half-angle of the spots (rad)
  std::vector<NamedCase> v;
  v.push_back({"point above", makeCase(pointLight({0, 2, 0}, 4), origin, up)});
  v.push_back({"point oblique", makeCase(pointLight({1.5f, 2, -0.5f}, 3), origin, up)});
  v.push_back({"point behind the surface", makeCase(pointLight({0, -2, 0}, 4), origin, up)});
  v.push_back({"point in its plane", makeCase(pointLight({2, 0, 0}, 4), origin, up)});
  v.push_back({"point at the surface point", makeCase(pointLight(origin, 4), origin, up)});
  v.push_back({"point inside its range", makeCase(pointLight({0, 2, 0}, 4, 3.0f), origin, up)});
  v.push_back({"point past its range", makeCase(pointLight({0, 2, 0}, 4, 1.5f), origin, up)});
  v.push_back({"spot inside the inner cone",
               makeCase(spotLight({0, 2, 0}, {0, -1, 0}, 0.2f, cone), origin, up)});
  // Seen from P at 0.35 rad off the axis: between the inner (0.2) and outer (0.5) cones.
  const glm::vec3 between(2.0f * std::tan(0.35f), 0, 0);
  v.push_back({"spot between the cones",
               makeCase(spotLight({0, 2, 0}, {0, -1, 0}, 0.2f, cone), between, up)});
  const glm::vec3 outside(2.0f * std::tan(0.7f), 0, 0);
  v.push_back({"spot outside the outer cone",
               makeCase(spotLight({0, 2, 0}, {0, -1, 0}, 0.2f, cone), outside, up)});
  v.push_back({"spot with a hard edge, inside",
               makeCase(spotLight({0, 2, 0}, {0, -1, 0}, cone, cone), between, up)});
  v.push_back({"spot with a hard edge, outside",
               makeCase(spotLight({0, 2, 0}, {0, -1, 0}, cone, cone), outside, up)});
  v.push_back({"spot behind the surface",
               makeCase(spotLight({0, -2, 0}, {0, 1, 0}, 0.2f, cone), origin, up)});
  v.push_back({"sun overhead", makeCase(sun({0, -1, 0}, 3), origin, up)});
  v.push_back({"sun oblique", makeCase(sun({1, -1, 0.5f}, 3), origin, up)});
  v.push_back({"sun below the horizon", makeCase(sun({0, 1, 0}, 3), origin, up)});
  v.push_back({"area facing the surface", areaCase({0, 2, 0}, {0, -1, 0}, 0.01f, origin, up)});
  v.push_back({"area facing away", areaCase({0, 2, 0}, {0, 1, 0}, 0.01f, origin, up)});
  v.push_back(
      {"area closer than its own size", areaCase({0, 0.05f, 0}, {0, -1, 0}, 0.04f, origin, up)});
  v.push_back({"area behind the surface", areaCase({0, -2, 0}, {0, 1, 0}, 0.01f, origin, up)});
  // Far from the world's origin, where the ray offset counts float steps, and near it, where
  // it is an absolute step.
  v.push_back({"point far from the origin",
               makeCase(pointLight({1e4f, 3, -2e4f}, 9), {1e4f, 0, -2e4f}, {0.3f, 1, 0.1f})});
  v.push_back(
      {"point near the origin, tilted normal",
       makeCase(pointLight({0.5f, 1, 0.25f}, 2), {0.01f, -0.02f, 0.005f}, {-0.4f, 1, 0.2f})});
  for (std::size_t i = 0; i < v.size(); ++i) addViewAndMaterial(v[i].c, i);
  return v;
}

struct Evaluated {
  glm::vec4 r[gpu::PC_LIGHT_CHECK_RESULTS];
};

Evaluated evaluateCpu(const LightCheckCase& c) {
  const glm::vec3 P(c.position), N(c.normal);
  glm::vec3 wi(0.0f);
  float distance = 0.0f;
  const glm::vec3 E = gpu::pcLightIrradiance(c.light, P, N, wi, distance);
  const float geometry = gpu::pcEmitterGeometry(c.light.position, c.light.direction, P, N);
  const glm::vec3 offset = gpu::pcOffsetRayOrigin(P, N);
  const float window = gpu::pcRangeWindow(glm::length(c.light.position - P), c.light.range);
  return {{glm::vec4(E, distance), glm::vec4(wi, geometry), glm::vec4(offset, window),
           gpu::pcBrdfCheck(c, wi, E), gpu::pcSpecularCheck(c, E)}};
}

TEST(LightModel, KnownValues) {
  const std::vector<NamedCase> all = cases();
  auto get = [&](const std::string& name) {
    for (const NamedCase& nc : all)
      if (nc.name == name) return evaluateCpu(nc.c);
    ADD_FAILURE() << "no case " << name;
    return Evaluated{};
  };
  // A 4 W/sr point light 2 above: E = I / d^2 = 1, from straight above.
  Evaluated above = get("point above");
  EXPECT_FLOAT_EQ(above.r[0].y, 1.0f);
  EXPECT_FLOAT_EQ(above.r[0].w, 2.0f);
  EXPECT_FLOAT_EQ(above.r[1].y, 1.0f);
  // Oblique: I cos(theta) / d^2.
  {
    const glm::vec3 L(1.5f, 2, -0.5f);
    const float d = glm::length(L);
    EXPECT_NEAR(get("point oblique").r[0].x, 3.0f * (L.y / d) / (d * d), 1e-6f);
  }
  for (const char* dark :
       {"point behind the surface", "point in its plane", "point at the surface point",
        "point past its range", "spot outside the outer cone", "spot with a hard edge, outside",
        "spot behind the surface", "sun below the horizon", "area facing away",
        "area behind the surface"}) {
    const Evaluated e = get(dark);
    EXPECT_EQ(e.r[0], glm::vec4(0.0f)) << dark;  // no light and no distance
    EXPECT_EQ(glm::vec3(e.r[1]), glm::vec3(0.0f)) << dark;
  }
  // The range window (1 - (d/r)^4)^2 at d = 2, r = 3.
  {
    const float w = std::pow(1.0f - std::pow(2.0f / 3.0f, 4.0f), 2.0f);
    EXPECT_NEAR(get("point inside its range").r[0].y, 1.0f * w, 1e-6f);
  }
  // Inside the inner cone the spot is a point light; between the cones smoothstep of cosines.
  EXPECT_FLOAT_EQ(get("spot inside the inner cone").r[0].y, 8.0f / 4.0f);
  {
    const float cosIn = std::cos(0.2f), cosOut = std::cos(0.5f), cosA = std::cos(0.35f);
    const float t = (cosA - cosOut) / (cosIn - cosOut);
    const float d2 = 4.0f / (cosA * cosA);
    EXPECT_NEAR(get("spot between the cones").r[0].y, 8.0f * cosA / d2 * t * t * (3 - 2 * t),
                1e-5f);
    EXPECT_NEAR(get("spot with a hard edge, inside").r[0].y, 8.0f * cosA / d2, 1e-5f);
  }
  // The sun: E = intensity x cos, at an unbounded distance.
  EXPECT_FLOAT_EQ(get("sun overhead").r[0].y, 3.0f);
  EXPECT_EQ(get("sun overhead").r[0].w, gpu::PC_LIGHT_UNBOUNDED);
  EXPECT_NEAR(get("sun oblique").r[0].x, 3.0f / std::sqrt(2.25f), 1e-6f);
  // An area patch facing the point: power x cos x cos / d^2; closer than its size, / size.
  EXPECT_FLOAT_EQ(get("area facing the surface").r[0].x, 2.0f / 4.0f);
  EXPECT_FLOAT_EQ(get("area closer than its own size").r[0].x, 2.0f / 0.04f);
  // The emitter geometry of a sample 2 above, facing down: cos x cos / d^2 = 1/4; one facing
  // away contributes nothing.
  EXPECT_FLOAT_EQ(get("area facing the surface").r[1].w, 0.25f);
  EXPECT_EQ(get("area facing away").r[1].w, 0.0f);
  // The reflected light: the BRDF for the light's direction times the irradiance, and black
  // where no light arrives.
  {
    const NamedCase* oblique = nullptr;
    for (const NamedCase& nc : all)
      if (nc.name == "point oblique") oblique = &nc;
    ASSERT_NE(oblique, nullptr);
    const Evaluated e = evaluateCpu(oblique->c);
    const glm::vec3 N(oblique->c.normal), V(oblique->c.view), base(oblique->c.material);
    const glm::vec3 f = gpu::pcMaterialBrdf(N, V, glm::vec3(e.r[1]), base, oblique->c.material.w,
                                            oblique->c.view.w);
    EXPECT_NEAR(e.r[3].x, f.x * e.r[0].x, 1e-6f * f.x * e.r[0].x);
    EXPECT_GT(e.r[3].x, 0.0f);
    EXPECT_EQ(glm::vec3(get("point behind the surface").r[3]), glm::vec3(0.0f));
  }
  // The ray offset: 256 float steps along a unit axis far out, an absolute 1/65536 near zero.
  {
    const Evaluated far = get("point far from the origin");
    EXPECT_GT(far.r[2].x, 1e4f);
    EXPECT_LT(far.r[2].z, -2e4f + 1.0f);
    EXPECT_GT(far.r[2].z, -2e4f);
    const Evaluated near = get("point near the origin, tilted normal");
    const glm::vec3 N = glm::normalize(glm::vec3(-0.4f, 1, 0.2f));
    EXPECT_FLOAT_EQ(near.r[2].y, -0.02f + N.y / 65536.0f);
  }
}

// The same cases through light_model_check.comp.
class LightModelGlsl : public ::testing::Test {
 protected:
  void SetUp() override {
    vk::ContextOptions o;
    o.validation = true;
    o.allowCpuDevice = true;
    auto ctx = vk::Context::create(o);
    if (!ctx) GTEST_SKIP() << "no Vulkan device: " << ctx.error().message;
    ctx_ = std::move(ctx).value();
  }
  std::unique_ptr<vk::Context> ctx_;
};

TEST_F(LightModelGlsl, AgreesWithTheCppEvaluationToFloatPrecision) {
  const std::vector<NamedCase> all = cases();
  std::vector<LightCheckCase> input;
  for (const NamedCase& nc : all) input.push_back(nc.c);
  const std::size_t inBytes = input.size() * sizeof(LightCheckCase);
  const std::size_t outBytes = input.size() * sizeof(Evaluated);
  auto in = vk::Buffer::create(*ctx_, inBytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                               vk::MemoryUsage::Upload);
  auto out = vk::Buffer::create(*ctx_, outBytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                                vk::MemoryUsage::Readback);
  ASSERT_TRUE(in) << in.error().message;
  ASSERT_TRUE(out) << out.error().message;
  in->write(input.data(), inBytes);

  const VkDevice device = ctx_->device();
  VkDescriptorSetLayoutBinding bindings[2] = {};
  for (std::uint32_t b = 0; b < 2; ++b) {
    bindings[b].binding = b;
    bindings[b].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
    bindings[b].descriptorCount = 1;
    bindings[b].stageFlags = VK_SHADER_STAGE_COMPUTE_BIT;
  }
  auto setLayout = vk::createDescriptorSetLayout(*ctx_, bindings);
  ASSERT_TRUE(setLayout) << setLayout.error().message;
  auto layout =
      vk::createPipelineLayout(*ctx_, setLayout->get(), VK_SHADER_STAGE_COMPUTE_BIT, sizeof(int));
  ASSERT_TRUE(layout) << layout.error().message;
  auto shader = vk::loadShader(*ctx_, "light_model_check.comp.spv");
  ASSERT_TRUE(shader) << shader.error().message;

  VkComputePipelineCreateInfo ci{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
  ci.stage = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
  ci.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
  ci.stage.module = shader->get();
  ci.stage.pName = "main";
  ci.layout = layout->get();
  VkPipeline rawPipeline = VK_NULL_HANDLE;
  ASSERT_EQ(vkCreateComputePipelines(device, VK_NULL_HANDLE, 1, &ci, nullptr, &rawPipeline),
            VK_SUCCESS);
  vk::UniquePipeline pipeline(device, rawPipeline);

  VkDescriptorPoolSize poolSize{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 2};
  VkDescriptorPoolCreateInfo pci{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  pci.maxSets = 1;
  pci.poolSizeCount = 1;
  pci.pPoolSizes = &poolSize;
  VkDescriptorPool rawPool = VK_NULL_HANDLE;
  ASSERT_EQ(vkCreateDescriptorPool(device, &pci, nullptr, &rawPool), VK_SUCCESS);
  vk::UniqueDescriptorPool pool(device, rawPool);
  VkDescriptorSetLayout setLayoutHandle = setLayout->get();
  VkDescriptorSetAllocateInfo ai{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
  ai.descriptorPool = pool.get();
  ai.descriptorSetCount = 1;
  ai.pSetLayouts = &setLayoutHandle;
  VkDescriptorSet set = VK_NULL_HANDLE;
  ASSERT_EQ(vkAllocateDescriptorSets(device, &ai, &set), VK_SUCCESS);
  VkDescriptorBufferInfo infos[2] = {{in->get(), 0, VK_WHOLE_SIZE}, {out->get(), 0, VK_WHOLE_SIZE}};
  VkWriteDescriptorSet writes[2] = {};
  for (std::uint32_t b = 0; b < 2; ++b) {
    writes[b] = {VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
    writes[b].dstSet = set;
    writes[b].dstBinding = b;
    writes[b].descriptorCount = 1;
    writes[b].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
    writes[b].pBufferInfo = &infos[b];
  }
  vkUpdateDescriptorSets(device, 2, writes, 0, nullptr);

  const int count = int(input.size());
  Status s = ctx_->submitAndWait([&](VkCommandBuffer cmd) {
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline.get());
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, layout->get(), 0, 1, &set, 0,
                            nullptr);
    vkCmdPushConstants(cmd, layout->get(), VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(int), &count);
    vkCmdDispatch(cmd, std::uint32_t(count + 63) / 64, 1, 1);
  });
  ASSERT_TRUE(s) << s.error().message;
  ASSERT_EQ(out->invalidate(), VK_SUCCESS);
  std::vector<Evaluated> gpuResults(input.size());
  std::memcpy(gpuResults.data(), out->mapped(), outBytes);

  // Float precision: a few units in the last place of the larger magnitude (the device may
  // fuse a multiply and an add where the compiler did not).
  auto close = [](float a, float b) {
    return a == b || std::fabs(a - b) <= 4e-7f * std::max({std::fabs(a), std::fabs(b), 1e-6f});
  };
  // The BRDF row chains more divisions and square roots, each within a few ulps on the device
  // (GLSL's precision rules), and near-mirror lobes are steep: a looser bound there.
  auto closeBrdf = [](float a, float b) {
    return a == b || std::fabs(a - b) <= 2e-5f * std::max({std::fabs(a), std::fabs(b), 1e-6f});
  };
  // The split-sum row adds the lobe fit's cosines, whose terms cancel down to a tenth of
  // their size (pcGgxSpecularZh): a device cosine's last-place error weighs ten times more.
  auto closeSpecular = [](float a, float b) {
    return a == b || std::fabs(a - b) <= 1e-4f * std::max({std::fabs(a), std::fabs(b), 1e-3f});
  };
  int lit = 0, glossy = 0;
  for (std::size_t i = 0; i < all.size(); ++i) {
    const Evaluated cpu = evaluateCpu(input[i]);
    if (cpu.r[0].w > 0.0f) ++lit;
    if (cpu.r[0].w > 0.0f && gpu::pcHasSpecularLobe(input[i].material.w, input[i].view.w)) ++glossy;
    for (int r = 0; r < gpu::PC_LIGHT_CHECK_RESULTS; ++r) {
      for (int k = 0; k < 4; ++k) {
        const float g = gpuResults[i].r[r][k], c = cpu.r[r][k];
        EXPECT_TRUE(r == 4   ? closeSpecular(g, c)
                    : r == 3 ? closeBrdf(g, c)
                             : close(g, c))
            << all[i].name << ": result " << r << "[" << k << "] GLSL " << gpuResults[i].r[r][k]
            << " C++ " << cpu.r[r][k];
      }
    }
  }
  EXPECT_GE(lit, 10);    // the table exercises lit cases, not only dark ones
  EXPECT_GE(glossy, 6);  // and lights on glossy materials
  EXPECT_EQ(ctx_->validationErrorCount(), 0u);
}

}  // namespace
