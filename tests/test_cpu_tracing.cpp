// The Embree scene, direct lighting, the reference path tracer and the probe-lit render on
// small scenes built in code, checked against analytic values.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <vector>

#include "common/field.h"
#include "common/image.h"
#include "common/scene.h"
#include "cpu/camera.h"
#include "cpu/embree_scene.h"
#include "cpu/lighting.h"
#include "cpu/path_tracer.h"
#include "cpu/probe_lit_render.h"
#include "test_meshes.h"

namespace pc {
namespace {

constexpr float kPi = std::numbers::pi_v<float>;

using testmesh::addQuad;
using testmesh::boxMesh;

// Square in the plane y = `height`, centred on (cx, cz), facing up or down.
Mesh squareMesh(float cx, float cz, float half, float height, bool facingUp) {
  Mesh mesh;
  const glm::vec3 a(cx - half, height, cz - half), b(cx + half, height, cz - half),
      c(cx + half, height, cz + half), d(cx - half, height, cz + half);
  if (facingUp) {
    addQuad(mesh, a, d, c, b);
  } else {
    addQuad(mesh, a, b, c, d);
  }
  return mesh;
}

int addObject(Scene& scene, Mesh mesh, Material material) {
  mesh.material = static_cast<int>(scene.materials.size());
  scene.materials.push_back(std::move(material));
  scene.meshes.push_back(std::move(mesh));
  Instance inst;
  inst.mesh = static_cast<int>(scene.meshes.size()) - 1;
  scene.instances.push_back(inst);
  return static_cast<int>(scene.instances.size()) - 1;
}

Material diffuse(float albedo, float emission = 0.0f) {
  Material m;
  m.baseColor = glm::vec3(albedo);
  m.emissive = glm::vec3(emission);
  return m;
}

SceneState staticState(const Scene& scene) {
  SceneState state;
  state.lights = scene.lights;
  for (const Instance& inst : scene.instances) state.instanceTransforms.push_back(inst.transform);
  return state;
}

std::unique_ptr<EmbreeScene> build(const Scene& scene) {
  auto created = EmbreeScene::create(scene);
  EXPECT_TRUE(created.ok()) << (created.ok() ? "" : created.error().message);
  return std::move(created.value());
}

glm::vec3 meanPixel(const Image& image) {
  glm::dvec3 sum(0.0);
  for (const glm::vec3& p : image.pixels) sum += glm::dvec3(p);
  return glm::vec3(sum / double(image.pixels.size()));
}

// The probe-lit render's primary samples: one in each cell of the pixel's grid first, so that
// an edge through the pixel is integrated far better than by uniform samples.
TEST(PixelSamples, StratifiedOnePerCellAndFewerEdgeErrors) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0f, 0.99999f);
  const int strata = 4, n = strata * strata;
  std::vector<int> hits(n, 0);
  for (int s = 0; s < n; ++s) {
    const glm::vec2 j = pc::stratifiedPixelOffset(s, strata, u(rng), u(rng));
    ASSERT_GE(j.x, 0.0f);
    ASSERT_LT(j.x, 1.0f);
    ASSERT_GE(j.y, 0.0f);
    ASSERT_LT(j.y, 1.0f);
    ++hits[int(j.y * strata) * strata + int(j.x * strata)];
  }
  for (int h : hits) EXPECT_EQ(h, 1);
  // Coverage of pixels cut by edges of random angle and offset, estimated with 16 samples.
  double stratifiedError = 0, uniformError = 0;
  for (int pixel = 0; pixel < 2000; ++pixel) {
    const float angle = u(rng) * 6.2831853f, offset = u(rng) - 0.5f;
    const glm::vec2 normal(std::cos(angle), std::sin(angle));
    auto inside = [&](glm::vec2 p) { return glm::dot(p - glm::vec2(0.5f), normal) < offset; };
    // The exact coverage, from a fine grid.
    int fine = 0;
    for (int y = 0; y < 200; ++y)
      for (int x = 0; x < 200; ++x) fine += inside({(x + 0.5f) / 200, (y + 0.5f) / 200});
    const double exact = fine / 40000.0;
    int stratified = 0, uniform = 0;
    for (int s = 0; s < n; ++s) {
      stratified += inside(pc::stratifiedPixelOffset(s, strata, u(rng), u(rng)));
      uniform += inside({u(rng), u(rng)});
    }
    stratifiedError += std::pow(stratified / double(n) - exact, 2);
    uniformError += std::pow(uniform / double(n) - exact, 2);
  }
  EXPECT_LT(stratifiedError, 0.35 * uniformError);
  // Past the grid's samples, the rest are uniform in the whole pixel.
  EXPECT_EQ(pc::stratifiedPixelOffset(n, strata, 0.25f, 0.75f), glm::vec2(0.25f, 0.75f));
}

TEST(EmbreeScene, CounterClockwiseIsFrontFace) {
  Scene scene;
  Mesh tri;
  tri.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};  // counter-clockwise seen from +z
  tri.normals = {{0, 0, 1}, {0, 0, 1}, {0, 0, 1}};
  tri.indices = {0, 1, 2};
  addObject(scene, tri, diffuse(0.5f, 2.0f));
  auto embree = build(scene);

  Hit hit;
  const glm::vec3 down(0, 0, -1);
  ASSERT_TRUE(embree->intersect({0.2f, 0.2f, 1.0f}, down, 0.0f, INFINITY, hit));
  EXPECT_NEAR(hit.t, 1.0f, 1e-5f);
  EXPECT_EQ(hit.instance, 0u);
  // Embree 3's own Ng points out of the counter-clockwise side too, as its documentation
  // says; surface() derives the front from the world winding anyway, which also covers
  // mirrored instances.
  EXPECT_GT(glm::normalize(hit.geometricNormal).z, 0.99f);
  SurfacePoint front = embree->surface(hit, {0.2f, 0.2f, 1.0f}, down);
  EXPECT_FALSE(front.backface);
  EXPECT_NEAR(front.geometricNormal.z, 1.0f, 1e-6f);
  EXPECT_NEAR(front.normal.z, 1.0f, 1e-6f);
  EXPECT_NEAR(front.position.x, 0.2f, 1e-6f);
  EXPECT_FLOAT_EQ(front.emission.x, 2.0f);
  EXPECT_FLOAT_EQ(front.albedo.y, 0.5f);

  const glm::vec3 up(0, 0, 1);
  ASSERT_TRUE(embree->intersect({0.2f, 0.2f, -1.0f}, up, 0.0f, INFINITY, hit));
  SurfacePoint back = embree->surface(hit, {0.2f, 0.2f, -1.0f}, up);
  EXPECT_TRUE(back.backface);
  EXPECT_NEAR(back.geometricNormal.z, -1.0f, 1e-6f);  // flipped to face the ray
  EXPECT_NEAR(back.normal.z, -1.0f, 1e-6f);
  EXPECT_EQ(back.emission, glm::vec3(0.0f));  // emitters are one-sided
}

TEST(EmbreeScene, MirroredInstanceKeepsItsFrontFace) {
  Scene scene;
  Mesh tri;
  tri.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  tri.normals = {{0, 0, 1}, {0, 0, 1}, {0, 0, 1}};
  tri.indices = {0, 1, 2};
  addObject(scene, tri, diffuse(0.5f));
  // Mirrored in x: the front still faces +z in world space.
  scene.instances[0].transform = glm::mat4(glm::vec4(-1, 0, 0, 0), glm::vec4(0, 1, 0, 0),
                                           glm::vec4(0, 0, 1, 0), glm::vec4(0, 0, 0, 1));
  auto embree = build(scene);
  Hit hit;
  ASSERT_TRUE(embree->intersect({-0.2f, 0.2f, 1.0f}, {0, 0, -1}, 0.0f, INFINITY, hit));
  SurfacePoint sp = embree->surface(hit, {-0.2f, 0.2f, 1.0f}, {0, 0, -1});
  EXPECT_FALSE(sp.backface);
  EXPECT_NEAR(sp.normal.z, 1.0f, 1e-6f);
}

// A unit quad in z = 0 (uv = xy) whose material is cut out where a 2x1 texture's left texel
// (alpha 255) gives way to its right one (alpha 0): covered for u < 0.5 with bilinear
// filtering and wrapping, open beyond. Behind it, at z = -1, an opaque floor.
Scene cutOutQuadScene(bool mirrored) {
  Scene scene;
  Texture mask;
  mask.width = 2;
  mask.height = 1;
  mask.rgba = {255, 255, 255, 255, 255, 255, 255, 0};
  scene.textures.push_back(mask);
  Mesh quad;
  addQuad(quad, {0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0});
  for (glm::vec3 p : quad.positions) quad.uvs.push_back({p.x, p.y});
  Material cut = diffuse(0.5f);
  cut.alphaCutoff = 0.5f;
  cut.alphaTexture = 0;
  addObject(scene, quad, cut);
  if (mirrored)  // x -> 1 - x: the open half moves to the left, winding swapped inside
    scene.instances[0].transform = glm::mat4(glm::vec4(-1, 0, 0, 0), glm::vec4(0, 1, 0, 0),
                                             glm::vec4(0, 0, 1, 0), glm::vec4(1, 0, 0, 1));
  Mesh floor;
  addQuad(floor, {-1, -1, -1}, {2, -1, -1}, {2, 2, -1}, {-1, 2, -1});
  addObject(scene, floor, diffuse(0.5f));
  return scene;
}

TEST(EmbreeScene, CutOutMaterialsLetRaysThroughTheirOpenTexels) {
  for (bool mirrored : {false, true}) {
    const Scene scene = cutOutQuadScene(mirrored);
    auto embree = build(scene);
    const glm::vec3 down(0, 0, -1);
    // u = 0.25 is the left texel's centre (alpha 1), u = 0.75 the right one's (alpha 0).
    const float covered = mirrored ? 0.75f : 0.25f, open = mirrored ? 0.25f : 0.75f;
    Hit hit;
    ASSERT_TRUE(embree->intersect({covered, 0.5f, 1.0f}, down, 0.0f, INFINITY, hit));
    EXPECT_EQ(hit.instance, 0u) << "mirrored " << mirrored;
    EXPECT_NEAR(hit.t, 1.0f, 1e-5f);
    ASSERT_TRUE(embree->intersect({open, 0.5f, 1.0f}, down, 0.0f, INFINITY, hit));
    EXPECT_EQ(hit.instance, 1u) << "the ray should pass the open half to the floor";
    EXPECT_NEAR(hit.t, 2.0f, 1e-5f);
    // Shadow rays: blocked by the covered half, not by the open one (the floor is past tfar).
    EXPECT_TRUE(embree->occluded({covered, 0.5f, 1.0f}, down, 0.0f, 1.5f));
    EXPECT_FALSE(embree->occluded({open, 0.5f, 1.0f}, down, 0.0f, 1.5f));
    EXPECT_TRUE(coveredAt(scene.materials[0], scene.textures, {0.25f, 0.5f}));
    EXPECT_FALSE(coveredAt(scene.materials[0], scene.textures, {0.75f, 0.5f}));
  }
}

TEST(EmbreeScene, IntersectsABox) {
  Scene scene;
  addObject(scene, boxMesh(glm::vec3(-0.5f), glm::vec3(0.5f), false), diffuse(0.5f));
  auto embree = build(scene);
  Hit hit;
  ASSERT_TRUE(embree->intersect({0.1f, 0.2f, 5.0f}, {0, 0, -1}, 0.0f, INFINITY, hit));
  EXPECT_NEAR(hit.t, 4.5f, 1e-5f);
  SurfacePoint sp = embree->surface(hit, {0.1f, 0.2f, 5.0f}, {0, 0, -1});
  EXPECT_FALSE(sp.backface);
  EXPECT_NEAR(sp.normal.z, 1.0f, 1e-6f);
  // From the side, along x.
  ASSERT_TRUE(embree->intersect({-3.0f, 0.0f, 0.1f}, {1, 0, 0}, 0.0f, INFINITY, hit));
  EXPECT_NEAR(hit.t, 2.5f, 1e-5f);
  EXPECT_NEAR(embree->surface(hit, {-3.0f, 0.0f, 0.1f}, {1, 0, 0}).normal.x, -1.0f, 1e-6f);
  // Inside: the far wall's back face.
  ASSERT_TRUE(embree->intersect({0, 0, 0}, {0, 1, 0}, 0.0f, INFINITY, hit));
  EXPECT_NEAR(hit.t, 0.5f, 1e-5f);
  EXPECT_TRUE(embree->surface(hit, {0, 0, 0}, {0, 1, 0}).backface);

  EXPECT_FALSE(embree->intersect({2.0f, 0.0f, 5.0f}, {0, 0, -1}, 0.0f, INFINITY, hit));
  EXPECT_FALSE(embree->intersect({0.0f, 0.0f, 5.0f}, {0, 0, -1}, 0.0f, 4.0f, hit));
  EXPECT_TRUE(embree->occluded({0.0f, 0.0f, 5.0f}, {0, 0, -1}, 0.0f, 5.0f));
  EXPECT_FALSE(embree->occluded({0.0f, 0.0f, 5.0f}, {0, 0, -1}, 0.0f, 4.0f));

  RTCRayHit rays[2] = {};
  for (int i = 0; i < 2; ++i) {
    rays[i].ray.org_x = i == 0 ? 0.0f : 3.0f;
    rays[i].ray.org_z = 5.0f;
    rays[i].ray.dir_z = -1.0f;
    rays[i].ray.tfar = INFINITY;
    rays[i].ray.mask = 0xFFFFFFFFu;
    rays[i].hit.geomID = RTC_INVALID_GEOMETRY_ID;
  }
  embree->intersect1M(rays, 2);
  EXPECT_EQ(rays[0].hit.geomID, 0u);
  EXPECT_NEAR(rays[0].ray.tfar, 4.5f, 1e-5f);
  EXPECT_EQ(rays[1].hit.geomID, RTC_INVALID_GEOMETRY_ID);
}

TEST(EmbreeScene, AnimatedInstanceUpdateMovesTheHit) {
  Scene scene;
  addObject(scene, boxMesh(glm::vec3(-0.5f), glm::vec3(0.5f), false), diffuse(0.5f));
  addObject(scene, squareMesh(0, 0, 10, -2, true), diffuse(0.5f));  // static floor
  Animation spin;
  spin.kind = Animation::Kind::Rotate;
  scene.animations.push_back(spin);
  scene.instances[0].animation = 0;
  auto embree = build(scene);

  Hit hit;
  ASSERT_TRUE(embree->intersect({0, 0, 5}, {0, 0, -1}, 0.0f, INFINITY, hit));
  EXPECT_EQ(hit.instance, 0u);
  EXPECT_NEAR(hit.t, 4.5f, 1e-5f);

  SceneState state = staticState(scene);
  state.instanceTransforms[0] = glm::mat4(1.0f);
  state.instanceTransforms[0][3] = glm::vec4(0.0f, 0.0f, -1.0f, 1.0f);  // 1 back along -z
  state.instanceTransforms[1][3] = glm::vec4(0.0f, 5.0f, 0.0f, 1.0f);   // static: ignored
  embree->update(state);
  ASSERT_TRUE(embree->intersect({0, 0, 5}, {0, 0, -1}, 0.0f, INFINITY, hit));
  EXPECT_EQ(hit.instance, 0u);
  EXPECT_NEAR(hit.t, 5.5f, 1e-5f);
  // Moved sideways out of the ray, which now reaches the floor, still where it was.
  state.instanceTransforms[0][3] = glm::vec4(3.0f, 0.0f, 0.0f, 1.0f);
  embree->update(state);
  ASSERT_TRUE(embree->intersect({0, 0, 0}, {0, -1, 0}, 0.0f, INFINITY, hit));
  EXPECT_EQ(hit.instance, 1u);
  EXPECT_NEAR(hit.t, 2.0f, 1e-5f);
  // Rotated a quarter turn about y: the box's +x face now faces -z (normal transform).
  state.instanceTransforms[0] = glm::mat4(glm::vec4(0, 0, -1, 0), glm::vec4(0, 1, 0, 0),
                                          glm::vec4(1, 0, 0, 0), glm::vec4(0, 0, 0, 1));
  embree->update(state);
  ASSERT_TRUE(embree->intersect({0.1f, 0.1f, 5}, {0, 0, -1}, 0.0f, INFINITY, hit));
  EXPECT_EQ(hit.instance, 0u);
  EXPECT_NEAR(hit.t, 4.5f, 1e-5f);
}

// A floor (y = 0, facing up) under a point light, optionally with a blocker in between.
Scene floorScene(bool blocker) {
  Scene scene;
  addObject(scene, squareMesh(0, 0, 10, 0, true), diffuse(0.5f));
  if (blocker) addObject(scene, squareMesh(1, 0, 0.25f, 1, false), diffuse(0.5f));
  Light light;
  light.type = LightType::Point;
  light.position = {0, 2, 0};
  light.intensity = 10.0f;
  light.color = {1.0f, 0.5f, 0.25f};
  scene.lights.push_back(light);
  return scene;
}

TEST(DirectLight, PointLightMatchesInverseSquareCosine) {
  Scene scene = floorScene(false);
  auto embree = build(scene);
  const SceneState state = staticState(scene);
  const EmissiveLights emissive = EmissiveLights::build(scene, state);
  Rng rng(1);
  const glm::vec3 N(0, 1, 0);
  for (float x : {0.0f, 1.0f, 3.0f}) {
    const glm::vec3 P = gpu::pcOffsetRayOrigin({x, 0, 0}, N);
    const float d2 = x * x + 4.0f;
    const float expected = 10.0f * (2.0f / std::sqrt(d2)) / d2;
    const glm::vec3 E = directIrradiance(*embree, packLights(state), emissive, P, N, rng);
    EXPECT_NEAR(E.x, expected, 1e-4f * expected) << "x = " << x;
    EXPECT_NEAR(E.y, 0.5f * expected, 1e-4f * expected);
    EXPECT_NEAR(E.z, 0.25f * expected, 1e-4f * expected);
  }
}

TEST(DirectLight, SpotAndDirectionalLights) {
  Scene scene;
  addObject(scene, squareMesh(0, 0, 10, 0, true), diffuse(0.5f));
  auto embree = build(scene);
  SceneState state = staticState(scene);
  const EmissiveLights emissive = EmissiveLights::build(scene, state);
  Rng rng(1);
  const glm::vec3 N(0, 1, 0);

  Light spot;
  spot.type = LightType::Spot;
  spot.position = {0, 2, 0};
  spot.direction = {0, -1, 0};
  spot.intensity = 4.0f;
  spot.innerConeAngle = 0.3f;
  spot.outerConeAngle = 0.5f;
  state.lights = {spot};
  // Inside the inner cone: full intensity; outside the outer cone: nothing.
  EXPECT_NEAR(directIrradiance(*embree, packLights(state), emissive,
                               gpu::pcOffsetRayOrigin({0, 0, 0}, N), N, rng)
                  .x,
              1.0f, 1e-4f);
  EXPECT_EQ(directIrradiance(*embree, packLights(state), emissive,
                             gpu::pcOffsetRayOrigin({2, 0, 0}, N), N, rng)
                .x,
            0.0f);
  const float mid = directIrradiance(*embree, packLights(state), emissive,
                                     gpu::pcOffsetRayOrigin({0.8f, 0, 0}, N), N, rng)
                        .x;
  EXPECT_GT(mid, 0.0f);  // between the cones (atan(0.4) = 0.38 rad): partly lit
  EXPECT_LT(mid, 4.0f * (2.0f / std::sqrt(4.64f)) / 4.64f);

  Light sun;
  sun.type = LightType::Directional;
  sun.direction = glm::normalize(glm::vec3(1, -1, 0));
  sun.intensity = 3.0f;
  state.lights = {sun};
  EXPECT_NEAR(directIrradiance(*embree, packLights(state), emissive,
                               gpu::pcOffsetRayOrigin({0, 0, 0}, N), N, rng)
                  .x,
              3.0f * std::sqrt(0.5f), 1e-4f);
}

// The emitters are found once per scene (EmissiveSurfaces) and placed at each state: an
// emitter on a turning instance must follow it, with the power it had at rest.
TEST(EmissiveLights, SurfacesFoundOnceFollowAnAnimatedInstance) {
  Scene scene = builtinScene();
  std::size_t spinning = scene.instances.size();
  for (std::size_t i = 0; i < scene.instances.size(); ++i)
    if (scene.instances[i].animation >= 0) spinning = i;
  ASSERT_LT(spinning, scene.instances.size());
  // The spinning block glows (its own mesh and material); it is a small share of the room, so
  // its triangles are sampled as lights.
  Mesh glowing = scene.meshes[scene.instances[spinning].mesh];
  Material lamp = scene.materials[glowing.material];
  lamp.emissive = glm::vec3(4.0f);
  glowing.material = int(scene.materials.size());
  scene.materials.push_back(lamp);
  scene.instances[spinning].mesh = int(scene.meshes.size());
  scene.meshes.push_back(glowing);

  const EmissiveSurfaces surfaces(scene);
  const EmissiveLights rest = EmissiveLights::build(scene, evaluateScene(scene, 0.0), surfaces);
  ASSERT_EQ(rest.count(), glowing.triangleCount());
  for (double t : {0.0, 2.5, 7.0}) {
    const SceneState state = evaluateScene(scene, t);
    const EmissiveLights lights = EmissiveLights::build(scene, state, surfaces);
    ASSERT_EQ(lights.count(), glowing.triangleCount()) << "t = " << t;
    const glm::mat4& m = state.instanceTransforms[spinning];
    for (std::size_t k = 0; k < lights.count(); ++k) {
      const glm::vec3 p0 =
          glm::vec3(m * glm::vec4(glowing.positions[glowing.indices[3 * k]], 1.0f));
      EXPECT_NEAR(glm::distance(lights.triangles()[k].p0, p0), 0.0f, 1e-6f) << "t = " << t;
    }
    EXPECT_NEAR(lights.totalPower(), rest.totalPower(), 1e-5f * rest.totalPower());
    // The same as finding the surfaces again at this state.
    const EmissiveLights again = EmissiveLights::build(scene, state);
    ASSERT_EQ(again.count(), lights.count());
    EXPECT_EQ(again.triangles()[0].p0, lights.triangles()[0].p0);
    EXPECT_EQ(again.cdf(), lights.cdf());
  }
  // At t = 2.5 the block has turned by 0.75 rad: its emitters are elsewhere than at rest.
  const EmissiveLights turned = EmissiveLights::build(scene, evaluateScene(scene, 2.5), surfaces);
  EXPECT_GT(glm::distance(turned.triangles()[0].p0, rest.triangles()[0].p0), 1e-3f);
}

TEST(DirectLight, ShadowedPointGetsNothing) {
  Scene scene = floorScene(true);
  auto embree = build(scene);
  const SceneState state = staticState(scene);
  const EmissiveLights emissive = EmissiveLights::build(scene, state);
  Rng rng(1);
  const glm::vec3 N(0, 1, 0);
  // The blocker spans x in [0.75, 1.25] at y = 1: it shadows x = 2 (line to the light
  // crosses y = 1 at x = 1), not x = -2.
  EXPECT_EQ(directIrradiance(*embree, packLights(state), emissive,
                             gpu::pcOffsetRayOrigin({2, 0, 0}, N), N, rng),
            glm::vec3(0.0f));
  EXPECT_GT(directIrradiance(*embree, packLights(state), emissive,
                             gpu::pcOffsetRayOrigin({-2, 0, 0}, N), N, rng)
                .x,
            0.0f);
}

// Irradiance under a corner of an a x b rectangle of unit radiance parallel to the receiver
// at height h: pi times the rectangle's form factor.
double cornerRectangleIrradiance(double a, double b, double h) {
  const double x = a / h, y = b / h;
  const double sx = std::sqrt(1 + x * x), sy = std::sqrt(1 + y * y);
  return 0.5 * (x / sx * std::atan(y / sx) + y / sy * std::atan(x / sy));
}

TEST(DirectLight, EmissiveSquareMatchesFormFactor) {
  Scene scene;
  addObject(scene, squareMesh(0, 0, 10, 0, true), diffuse(0.5f));
  const float Le = 5.0f, half = 0.25f, height = 1.0f;
  addObject(scene, squareMesh(0, 0, half, height, false), diffuse(0.0f, Le));
  scene.emissiveMode = EmissiveMode::Auto;  // 0.25 m^2 of 400 m^2: sampled as a light
  auto embree = build(scene);
  const SceneState state = staticState(scene);
  const EmissiveLights emissive = EmissiveLights::build(scene, state);
  ASSERT_EQ(emissive.count(), 2u);
  EXPECT_TRUE(emissive.sampled(1));
  EXPECT_FALSE(emissive.sampled(0));

  const glm::vec3 N(0, 1, 0);
  Rng rng(7);
  DirectLightOptions options;
  options.emissiveSamples = 4096;
  // Below the centre: four corner rectangles of half x half.
  const double centre = 4.0 * Le * cornerRectangleIrradiance(half, half, height);
  const glm::vec3 E = directIrradiance(*embree, packLights(state), emissive,
                                       gpu::pcOffsetRayOrigin({0, 0, 0}, N), N, rng, options);
  EXPECT_NEAR(E.x, centre, 0.02 * centre);
  // Below a corner of the light, off-centre.
  const double corner = Le * cornerRectangleIrradiance(2 * half, 2 * half, height);
  const glm::vec3 Ec =
      directIrradiance(*embree, packLights(state), emissive,
                       gpu::pcOffsetRayOrigin({half, 0, half}, N), N, rng, options);
  EXPECT_NEAR(Ec.x, corner, 0.02 * corner);
  // The emitter's back (its top) lights nothing, even for a receiver facing it.
  const glm::vec3 above =
      directIrradiance(*embree, packLights(state), emissive, {0, 2, 0}, {0, -1, 0}, rng, options);
  EXPECT_EQ(above, glm::vec3(0.0f));
  std::printf("emissive square: E %.5f vs %.5f (centre), %.5f vs %.5f (corner)\n", E.x, centre,
              Ec.x, corner);

  // Field mode samples nothing; Auto leaves large emitters to the field.
  scene.emissiveMode = EmissiveMode::Field;
  EXPECT_TRUE(EmissiveLights::build(scene, state).empty());
  EXPECT_FALSE(EmissiveLights::build(scene, state).sampled(1));
  EXPECT_TRUE(emissiveAsLights(EmissiveMode::Auto, 1.0, 100.0));
  EXPECT_FALSE(emissiveAsLights(EmissiveMode::Auto, 20.0, 100.0));
  EXPECT_TRUE(emissiveAsLights(EmissiveMode::Lights, 20.0, 100.0));
}

// Closed box, every surface albedo a and emitting Le: radiance everywhere Le / (1 - a).
Scene furnace(float albedo, float Le, EmissiveMode mode) {
  Scene scene;
  addObject(scene, boxMesh(glm::vec3(-1.0f), glm::vec3(1.0f), true), diffuse(albedo, Le));
  scene.emissiveMode = mode;
  Camera cam;
  cam.position = {0.2f, -0.1f, 0.3f};
  cam.forward = glm::normalize(glm::vec3(0.3f, 0.2f, -1.0f));
  cam.yfov = 1.2f;
  scene.cameras.push_back(cam);
  return scene;
}

PathTraceResult renderFurnace(const Scene& scene, int spp, std::uint64_t seed = 1) {
  auto embree = build(scene);
  const SceneState state = staticState(scene);
  const EmissiveLights emissive = EmissiveLights::build(scene, state);
  PathTraceOptions options;
  options.width = 24;
  options.height = 16;
  options.spp = spp;
  options.seed = seed;
  return pathTrace(*embree, state, emissive, scene.cameras[0], options);
}

// In Lights mode every wall is an area light touching its neighbours: near the edges the
// light-sampling estimate is heavy-tailed, so it approaches the answer more slowly (from
// below) than in Field mode, where emission is picked up by the path itself.
TEST(PathTracer, WhiteFurnaceConverges) {
  for (float albedo : {0.5f, 0.8f}) {
    const float Le = 0.3f;
    const double expected = Le / (1.0 - albedo);
    for (EmissiveMode mode : {EmissiveMode::Field, EmissiveMode::Lights}) {
      const PathTraceResult result = renderFurnace(furnace(albedo, Le, mode), 64);
      const glm::vec3 mean = meanPixel(result.image);
      std::printf("furnace a=%.1f %s: mean %.5f expected %.5f (%.2f%%), halves PSNR %.1f dB\n",
                  albedo, mode == EmissiveMode::Field ? "field " : "lights", mean.x, expected,
                  100.0 * (mean.x / expected - 1.0), result.halvesPsnr);
      EXPECT_NEAR(mean.x, expected, 0.02 * expected) << "albedo " << albedo;
      EXPECT_NEAR(mean.y, expected, 0.02 * expected);
      EXPECT_GT(result.halvesPsnr, 20.0);
      EXPECT_NEAR(result.noisePsnr - result.halvesPsnr, 6.02, 0.01);
    }
  }
}

TEST(PathTracer, SameSeedSameImageOnAnyThreadCount) {
  const Scene scene = furnace(0.7f, 0.5f, EmissiveMode::Lights);
  const PathTraceResult a = renderFurnace(scene, 4, 42);
  PathTraceResult b;
  {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    b = renderFurnace(scene, 4, 42);
  }
  EXPECT_EQ(a.image.pixels, b.image.pixels);
  EXPECT_EQ(a.samples, 24u * 16u * 4u);
  const PathTraceResult c = renderFurnace(scene, 4, 43);
  EXPECT_NE(a.image.pixels, c.image.pixels);
}

TEST(PathTracer, NoiseEstimateMatchesErrorAgainstAConvergedImage) {
  // The halves-based estimate of an image's noise should predict its PSNR against a far
  // better converged render of the same view (whose own, smaller noise is accounted for).
  const Scene scene = builtinScene();
  PathTraceOptions options;
  options.width = 32;
  options.height = 24;
  options.spp = 1024;
  options.seed = 5;
  auto truth = renderReference(scene, options);
  ASSERT_TRUE(truth.ok()) << truth.error().message;
  options.spp = 64;
  options.seed = 6;
  auto test = renderReference(scene, options);
  ASSERT_TRUE(test.ok()) << test.error().message;
  const double measured =
      psnr8(tonemap(test->image, scene.exposure), tonemap(truth->image, scene.exposure));
  // Errors add in power: the test's noise plus the truth's.
  const double expected = -10.0 * std::log10(std::pow(10.0, -test->noisePsnr / 10.0) +
                                             std::pow(10.0, -truth->noisePsnr / 10.0));
  std::printf("noise: estimated %.2f dB (truth %.2f dB), expected %.2f dB, measured %.2f dB\n",
              test->noisePsnr, truth->noisePsnr, expected, measured);
  EXPECT_NEAR(measured, expected, 1.0);
}

TEST(PathTracer, DirectOnlyMatchesAnalyticPointLight) {
  // Looking straight down at a lit floor from the light's position: with no bounces, a pixel
  // shows albedo / pi x E.
  Scene scene = floorScene(false);
  Camera cam;
  cam.position = {0, 1, 0};
  cam.forward = {0, -1, 0};
  cam.up = {0, 0, -1};
  cam.yfov = 0.05f;
  scene.cameras.push_back(cam);
  auto embree = build(scene);
  const SceneState state = staticState(scene);
  const EmissiveLights emissive = EmissiveLights::build(scene, state);
  PathTraceOptions options;
  options.width = options.height = 4;
  options.spp = 2;
  options.maxBounces = 0;
  const PathTraceResult result = pathTrace(*embree, state, emissive, cam, options);
  const float expected = 0.5f / kPi * 10.0f / 4.0f;
  EXPECT_NEAR(result.image.at(2, 2).x, expected, 0.01f * expected);
}

TEST(ProbeLitRender, UniformFieldAddsItsIrradiance) {
  // No lights: the image is emission + albedo / pi x the field's (uniform) irradiance.
  const float albedo = 0.6f, Le = 0.1f, fieldE = 2.0f;
  Scene scene = furnace(albedo, Le, EmissiveMode::Field);
  ProbeVolume volume;
  volume.origin = glm::vec3(-1.0f);
  volume.spacing = 0.5f;
  volume.counts = glm::ivec3(5);
  Field field = Field::create({volume}, FieldSettings{});
  const float encoded = std::pow(fieldE, 1.0f / gpu::PC_IRRADIANCE_GAMMA);
  for (std::size_t i = 0; i < field.irradiance.texels.size(); ++i) {
    field.irradiance.texels[i] = encoded;
  }
  for (ProbeRecord& probe : field.probes) probe.state = gpu::PC_PROBE_ACTIVE;

  auto embree = build(scene);
  const SceneState state = staticState(scene);
  const EmissiveLights emissive = EmissiveLights::build(scene, state);
  ProbeLitOptions options;
  options.width = 12;
  options.height = 8;
  options.primarySamples = 2;
  options.sampleFlags = gpu::PC_SAMPLE_NO_VISIBILITY;
  const Image image = renderProbeLit(*embree, state, emissive, field, scene.cameras[0], options);
  const float expected = Le + albedo / kPi * fieldE;
  for (const glm::vec3& p : image.pixels) EXPECT_NEAR(p.x, expected, 1e-3f * expected);
  const Image again = renderProbeLit(*embree, state, emissive, field, scene.cameras[0], options);
  EXPECT_EQ(image.pixels, again.pixels);
}

}  // namespace
}  // namespace pc
