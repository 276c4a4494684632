// The client's lighting pass with glTF normal maps (tests/normal_map_scene.h: a quad lit by a
// directional light, its map leaning the normal one way): the map changes the client's image
// as it changes the reference's, a flat map changes nothing, and the client agrees with the
// CPU probe-lit render (the same surfaces traced, the same shared shading code) with the light
// direct and with the light coming from a probe field alone (lavapipe with validation).
#include <array>
#include <cstdio>

#include "cpu/probe_lit_render.h"
#include "normal_map_scene.h"
#include "test_client_support.h"

namespace pc::client::test {
namespace {

using pc::test::NormalMapCase;
using pc::test::NormalMapQuad;

constexpr int kSize = 64;

struct Renders {
  double client = 0.0;     // the client's mean linear radiance
  double reference = 0.0;  // the path tracer's, direct light only
  double agreement = 0.0;  // PSNR of the client's display image against the CPU probe-lit one
};

Renders renderAll(vk::Context& ctx, const Scene& scene, const Field* field, const char* name) {
  Renders r;
  auto camera = sceneCamera(scene, 0);
  EXPECT_TRUE(camera.ok());
  if (!camera) return r;
  const ClientFrame frame = renderClientFrame(ctx, scene, field, *camera, nullptr, kSize, kSize);
  EXPECT_EQ(frame.linear.size(), 1u);
  if (frame.linear.size() != 1) return r;
  r.client = pc::test::meanRadiance(frame.linear[0]);

  PathTraceOptions trace;
  trace.width = trace.height = 16;
  trace.spp = 2;
  trace.maxBounces = 0;
  auto reference = renderReference(scene, trace);
  EXPECT_TRUE(reference.ok());
  if (reference) r.reference = pc::test::meanRadiance(reference->image);

  ProbeLitOptions lit;
  lit.width = lit.height = kSize;
  lit.primarySamples = 4;
  const Field none;
  auto cpu = renderProbeLit(scene, field ? *field : none, lit);
  EXPECT_TRUE(cpu.ok());
  if (!cpu) return r;
  const Image8 cpu8 = tonemap(*cpu, scene.exposure);
  r.agreement = psnr8(frame.display[0], cpu8);
  const std::filesystem::path dir = testOutputDir("normal-maps");
  writePng(dir / (std::string(name) + "_client.png"), frame.display[0]);
  writePng(dir / (std::string(name) + "_cpu_probe_lit.png"), cpu8);
  return r;
}

TEST(ClientNormalMaps, MapShadesAsInTheReferenceAndTheCpuRender) {
  auto ctx = validatingContext();
  if (!ctx) GTEST_SKIP() << "no Vulkan device";
  const std::filesystem::path dir = testOutputDir("normal-maps") / "scenes";

  NormalMapQuad q;
  q.normalMap = false;
  auto plain = pc::test::loadNormalMapQuad(dir / "plain", q);
  ASSERT_TRUE(plain.ok()) << plain.error().message;
  const Renders base = renderAll(*ctx, *plain, nullptr, "plain");
  ASSERT_GT(base.reference, 0.0);

  const NormalMapCase cases[] = {{"flat", {128, 128, 255}, true},
                                 {"tangent", {204, 128, 230}, true},
                                 {"bitangent_generated", {128, 204, 230}, false}};
  for (const NormalMapCase& c : cases) {
    q.normalMap = true;
    q.texel = c.texel;
    q.tangents = c.tangents;
    auto scene = pc::test::loadNormalMapQuad(dir / c.name, q);
    ASSERT_TRUE(scene.ok()) << scene.error().message;
    const Renders r = renderAll(*ctx, *scene, nullptr, c.name);
    // The client adds the same ambient term to both images, which the difference cancels.
    const double clientChange = r.client - base.client;
    const double referenceChange = r.reference - base.reference;
    std::printf(
        "map %-20s mean change: client %+.4f, reference %+.4f (unmapped %.4f, %.4f); client vs "
        "CPU probe-lit %.2f dB\n",
        c.name, clientChange, referenceChange, base.client, base.reference, r.agreement);
    if (c.texel == std::array<std::uint8_t, 3>{128, 128, 255}) {
      // 128 decodes to 0.0039, not 0: a flat map leans the normal by 0.3 degrees, toward
      // this light (0.8% more light in the reference, test_normal_maps).
      EXPECT_NEAR(r.client, base.client, 0.01 * base.client) << c.name;
      EXPECT_NEAR(r.reference, base.reference, 0.01 * base.reference) << c.name;
    } else {
      EXPECT_GT(referenceChange, 0.2 * base.reference) << c.name;  // the map lights it more
      EXPECT_NEAR(clientChange, referenceChange, 0.05 * referenceChange) << c.name;
    }
    EXPECT_GT(r.agreement, 35.0) << c.name;
  }
}

TEST(ClientNormalMaps, ProbeFieldIsLookedUpWithTheMappedNormal) {
  // No light but a sky bright above and black below, through a baked field: a map leaning
  // the normal up (+Y) catches more of it, in the client and the CPU probe-lit render alike.
  auto ctx = validatingContext();
  if (!ctx) GTEST_SKIP() << "no Vulkan device";
  const std::filesystem::path dir = testOutputDir("normal-maps") / "scenes";
  double means[2] = {0.0, 0.0};
  for (int mapped = 0; mapped < 2; ++mapped) {
    NormalMapQuad q;
    q.normalMap = mapped == 1;
    q.texel = {128, 230, 204};
    auto scene = pc::test::loadNormalMapQuad(dir / (mapped ? "sky_mapped" : "sky_plain"), q);
    ASSERT_TRUE(scene.ok()) << scene.error().message;
    scene->lights.clear();
    scene->sky.zenith = glm::vec3(2.0f);
    scene->sky.horizon = glm::vec3(0.5f);
    scene->sky.ground = glm::vec3(0.0f);
    ProbeVolume volume;
    volume.origin = glm::vec3(-1.5f, -1.5f, -0.5f);
    volume.spacing = 1.0f;
    volume.counts = glm::ivec3(4, 4, 3);
    scene->volumes = {volume};
    const Field field = bakeQuickly(*scene, 8);
    const Renders r = renderAll(*ctx, *scene, &field, mapped ? "sky_mapped" : "sky_plain");
    std::printf("sky through the field, %s: client mean %.4f; client vs CPU probe-lit %.2f dB\n",
                mapped ? "mapped up" : "unmapped", r.client, r.agreement);
    means[mapped] = r.client;
    EXPECT_GT(r.agreement, 35.0);
  }
  EXPECT_GT(means[1], 1.1 * means[0]);
}

// glTF's metallic-roughness texture (linear: B metallic, G roughness) scales the factors in the
// client as in the CPU renders. A rough metal (factors 1, 1) becomes a dielectric at roughness
// 0.25 through a texture whose B is 0 and G 64: its direct light changes in the client as in the
// reference, and the client agrees with the CPU probe-lit render with and without it.
TEST(ClientNormalMaps, MetallicRoughnessTextureScalesTheFactorsAsOnTheCpu) {
  auto ctx = validatingContext();
  if (!ctx) GTEST_SKIP() << "no Vulkan device";
  const std::filesystem::path dir = testOutputDir("normal-maps") / "scenes";
  Renders r[2];
  for (int textured = 0; textured < 2; ++textured) {
    NormalMapQuad q;
    q.normalMap = false;
    auto scene = pc::test::loadNormalMapQuad(dir / (textured ? "mr_textured" : "mr_plain"), q);
    ASSERT_TRUE(scene.ok()) << scene.error().message;
    ASSERT_FALSE(scene->materials.empty());
    Material& m = scene->materials[0];
    m.metallic = 1.0f;
    m.roughness = 1.0f;
    if (textured) {
      Texture t;
      t.name = "metallic-roughness";
      t.width = t.height = 2;
      t.linear = true;
      for (int i = 0; i < 4; ++i)
        t.rgba.insert(t.rgba.end(),
                      {std::uint8_t(255), std::uint8_t(64), std::uint8_t(0), std::uint8_t(255)});
      scene->textures.push_back(t);
      m.metallicRoughnessTexture = int(scene->textures.size()) - 1;
    }
    r[textured] = renderAll(*ctx, *scene, nullptr, textured ? "mr_textured" : "mr_plain");
    std::printf("%s: client mean %.4f, reference %.4f, client vs CPU probe-lit %.2f dB\n",
                textured ? "textured (dielectric, roughness 0.25)" : "factors (rough metal)",
                r[textured].client, r[textured].reference, r[textured].agreement);
    EXPECT_GT(r[textured].agreement, 35.0);
  }
  const double clientChange = r[1].client - r[0].client;
  const double referenceChange = r[1].reference - r[0].reference;
  EXPECT_GT(std::abs(referenceChange), 0.1 * r[0].reference) << "the texture changes the quad";
  // Within 15%: the client's ambient term (absent from the reference) goes through the BRDF too.
  EXPECT_NEAR(clientChange, referenceChange, 0.15 * std::abs(referenceChange));
  EXPECT_EQ(ctx->validationErrorCount(), 0u);
}

}  // namespace
}  // namespace pc::client::test
