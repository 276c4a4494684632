// Probe-ray hits on surfaces without metallic-roughness data (metallic 0, roughness 1, what
// the OBJ and built-in scenes load) reflect by Lambert's law exactly as they did before the
// tracers shaded hits with the whole material (shaders/interop/probe_hit_shading.h): the
// Embree field of the built-in scene keeps the figures it had then. The figures were recorded
// from the Lambert-only tracer; a change of the diffuse path (a coat weight, another order of
// the sums) moves them by far more than the tolerance, which only absorbs float reordering.
#include <gtest/gtest.h>

#include <cstdio>

#include "common/field.h"
#include "common/scene.h"
#include "server/embree_tracer.h"
#include "test_tracer_support.h"

namespace pc {
namespace {

struct FieldFigures {
  double sum = 0.0, sumSquares = 0.0;
  std::size_t texels = 0;
};

FieldFigures irradianceFigures(const Field& f) {
  FieldFigures r;
  for (float t : f.irradiance.texels) {
    r.sum += double(t);
    r.sumSquares += double(t) * double(t);
  }
  r.texels = f.irradiance.texels.size();
  return r;
}

TEST(ProbeHitFields, DiffuseSceneFieldIsUnchanged) {
  const Scene scene = builtinScene();
  for (const Material& m : scene.materials)
    ASSERT_TRUE(m.metallic == 0.0f && m.roughness == 1.0f && m.metallicRoughnessTexture < 0)
        << "material '" << m.name << "' is not the plain diffuse surface";
  auto tracer = makeEmbreeTracer(scene);
  ASSERT_TRUE(tracer) << tracer.error().message;
  Field field = Field::create(scene.volumes, FieldSettings{});
  BakeOptions bake;
  bake.updates = 3;  // the third update reads the field the first two left: indirect light
  bakeOrFail(field, **tracer, bake);
  const FieldFigures f = irradianceFigures(field);
  std::printf("built-in scene, 3 updates: %zu texels, sum %.9g, sum of squares %.9g\n", f.texels,
              f.sum, f.sumSquares);
  // Recorded from the Lambert-only tracer.
  const double kSum = 158206.934, kSumSquares = 156126.86;
  EXPECT_NEAR(f.sum, kSum, 1e-5 * kSum);
  EXPECT_NEAR(f.sumSquares, kSumSquares, 1e-5 * kSumSquares);
}

}  // namespace
}  // namespace pc
