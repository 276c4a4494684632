// The screen-space ambient occlusion of the indirect light (shaders/interop/screen_ao.h) on
// the CPU: open surfaces stay unoccluded, a contact darkens and only near the contact, and
// the concave-edge measure: the probe-lit render's error in a band along a block's contact
// with the floor, against the path tracer, without and with the occlusion.
#include <gtest/gtest.h>

#include <cstdio>

#include "common/scene_contact.h"
#include "cpu/camera.h"
#include "cpu/contact_band.h"
#include "cpu/path_tracer.h"
#include "cpu/probe_lit_render.h"
#include "cpu/render_setup.h"
#include "server/bake.h"
#include "server/embree_tracer.h"
#include "test_meshes.h"

namespace pc {
namespace {

constexpr int kWidth = 160, kHeight = 120;

Field contactField(const Scene& scene, int updates) {
  Field field = Field::create(scene.volumes, FieldSettings{});
  field.sceneHash = scene.hash;
  auto tracer = makeEmbreeTracer(scene);
  EXPECT_TRUE(tracer.ok());
  if (!tracer) return field;
  BakeOptions options;
  options.updates = updates;
  EXPECT_TRUE(bakeField(field, **tracer, options).ok());
  return field;
}

struct View {
  CpuRenderSetup setup;
  ViewSurfaces surfaces;
};

View viewOf(const Scene& scene) {
  auto setup = prepareCpuRender(scene, kWidth, kHeight, std::nullopt, 0, 0.0);
  EXPECT_TRUE(setup.ok());
  View v{std::move(setup).value(), {}};
  const PinholeCamera pinhole(v.setup.camera, kWidth, kHeight);
  v.surfaces = traceViewSurfaces(*v.setup.embree, pinhole, kWidth, kHeight);
  return v;
}

// Mean of `values` where `mask` is set.
double meanWhere(const std::vector<float>& values, const std::vector<bool>& mask) {
  double sum = 0;
  int n = 0;
  for (std::size_t i = 0; i < values.size(); ++i)
    if (mask[i]) sum += values[i], ++n;
  return n ? sum / n : 0.0;
}

TEST(ScreenAo, AnOpenFloorIsUnoccluded) {
  Scene scene;
  scene.name = "floor";
  scene.materials = {{.name = "white", .baseColor = glm::vec3(0.7f)}};
  Mesh floor{.name = "floor", .material = 0};
  testmesh::addQuad(floor, {-20, 0, 20}, {20, 0, 20}, {20, 0, -20}, {-20, 0, -20});
  scene.meshes = {floor};
  scene.instances = {{.name = "floor", .mesh = 0}};
  scene.cameras = {{.name = "c",
                    .position = {0, 1.5f, 2},
                    .forward = glm::normalize(glm::vec3(0, -1, -1.5f)),
                    .up = {0, 1, 0},
                    .yfov = glm::radians(60.0f)}};
  scene.volumes = {{.origin = glm::vec3(-2, 0.25f, -2), .spacing = 0.5f, .counts = glm::ivec3(9)}};
  const View v = viewOf(scene);
  const Field field = Field::create(scene.volumes, FieldSettings{});
  const std::vector<float> ao = screenAmbientOcclusion(
      v.surfaces, PinholeCamera(v.setup.camera, kWidth, kHeight), field, gpu::PC_AO_DEFAULT_RADIUS);
  int floorPixels = 0;
  float lowest = 1.0f;
  for (std::size_t i = 0; i < ao.size(); ++i) {
    if (v.surfaces.position[i].w <= 0.0f) continue;
    ++floorPixels;
    lowest = std::min(lowest, ao[i]);
  }
  EXPECT_GT(floorPixels, kWidth * kHeight / 2);
  // A plane occludes nothing of its own hemisphere.
  EXPECT_GT(lowest, 0.99f);
}

TEST(ScreenAo, ContactDarkensOnlyNearTheContact) {
  const Scene scene = contactScene();
  const View v = viewOf(scene);
  const Field field = Field::create(scene.volumes, FieldSettings{});
  const std::vector<float> ao = screenAmbientOcclusion(
      v.surfaces, PinholeCamera(v.setup.camera, kWidth, kHeight), field, gpu::PC_AO_DEFAULT_RADIUS);
  const std::vector<bool> contact = contactBandMask(v.surfaces, contactSceneEdges(), 0.05f);
  // The floor well away from the block and the walls: within 1 m of the block's contact but
  // not within 0.4, and not near a wall.
  std::vector<bool> near = contactBandMask(v.surfaces, contactSceneEdges(), 1.0f);
  const std::vector<bool> inner = contactBandMask(v.surfaces, contactSceneEdges(), 0.4f);
  for (std::size_t i = 0; i < near.size(); ++i) {
    const glm::vec3 p = v.surfaces.eye + glm::vec3(v.surfaces.position[i]);
    near[i] = near[i] && !inner[i] && p.y < 0.01f;
  }
  const double atContact = meanWhere(ao, contact), away = meanWhere(ao, near);
  std::printf("visibility at the contact %.3f, on the open floor %.3f\n", atContact, away);
  EXPECT_LT(atContact, 0.85);
  EXPECT_GT(away, 0.99);
}

TEST(ScreenAo, MultiBounceLeavesOpenSurfacesAndGivesBackLightOnBrightOnes) {
  const glm::vec3 open = gpu::pcAoMultiBounce(1.0f, glm::vec3(0.2f, 0.5f, 0.9f));
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(open[c], 1.0f, 0.002f);
  const glm::vec3 half = gpu::pcAoMultiBounce(0.5f, glm::vec3(0.1f, 0.5f, 0.9f));
  EXPECT_GE(half.x, 0.5f);
  EXPECT_GT(half.y, half.x);
  EXPECT_GT(half.z, half.y);
  EXPECT_LT(half.z, 1.0f);
}

// The concave-edge measure (probecast-bench contact measures the same at full size).
TEST(ScreenAo, ContactBandErrorDropsWithTheOcclusion) {
  const Scene scene = contactScene();
  const Field field = contactField(scene, 64);
  View v = viewOf(scene);
  PathTraceOptions pt;
  pt.width = kWidth;
  pt.height = kHeight;
  pt.spp = 768;
  auto reference = renderReference(scene, pt);
  ASSERT_TRUE(reference.ok());
  const Image8 ref = tonemap(reference->image, scene.exposure);
  const std::vector<bool> band = contactBandMask(v.surfaces, contactSceneEdges(), 0.08f);
  BandError e[2];
  for (int on = 0; on < 2; ++on) {
    ProbeLitOptions lit;
    lit.width = kWidth;
    lit.height = kHeight;
    lit.primarySamples = 4;
    lit.aoRadius = on ? gpu::PC_AO_DEFAULT_RADIUS : 0.0f;
    const Image image = renderProbeLit(*v.setup.embree, v.setup.state, v.setup.emissive, field,
                                       v.setup.camera, lit);
    e[on] = bandError(tonemap(image, scene.exposure), ref, band);
  }
  std::printf(
      "contact band (%d pixels): mean error %+.2f levels without occlusion, %+.2f with it "
      "(mean |error| %.2f, %.2f)\n",
      e[0].pixels, e[0].meanSigned, e[1].meanSigned, e[0].meanAbs, e[1].meanAbs);
  EXPECT_GT(e[0].pixels, 200);
  // Without it the contact is too bright: the probes do not see it.
  EXPECT_GT(e[0].meanSigned, 2.0);
  // With it, at most half that error remains.
  EXPECT_LT(std::abs(e[1].meanSigned), 0.5 * e[0].meanSigned);
}

}  // namespace
}  // namespace pc
