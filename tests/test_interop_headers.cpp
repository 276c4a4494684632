// Every header shared by C++ and GLSL (shaders/interop/) in one translation unit: a struct or
// constant defined twice, or twice with different layouts (a one-definition-rule violation
// once both are linked into one program), fails to compile here. The layouts are then checked
// against the 16-byte rows the headers mark, which std430 and std140 lay out alike.
#include <gtest/gtest.h>

#include <cstddef>

#include "shaders/interop/brdf.h"
#include "shaders/interop/client_frame.h"
#include "shaders/interop/field_desc.h"
#include "shaders/interop/gpu_trace.h"
#include "shaders/interop/ldm.h"
#include "shaders/interop/light_model.h"
#include "shaders/interop/normal_map.h"
#include "shaders/interop/pc_interop.h"
#include "shaders/interop/probe_hit_shading.h"
#include "shaders/interop/probe_math.h"
#include "shaders/interop/probe_update.h"
#include "shaders/interop/probe_view.h"
#include "shaders/interop/screen_ao.h"
#include "shaders/interop/sdf_grid.h"
#include "shaders/interop/sh_probe.h"
#include "shaders/interop/shadow_roulette.h"
#include "shaders/interop/tonemap.h"

// probe_sampling.h reads the field through fetches its includer declares (as common/field.cpp
// does on the CPU and the shaders do on the GPU); constant ones suffice to compile it here.
namespace pc::gpu {
struct NoField {};
inline vec3 pcFetchIrradiance(const NoField &, int, int, vec3) { return vec3(1.0f); }
inline vec2 pcFetchDepth(const NoField &, int, int, vec3) { return vec2(1.0f, 1.0f); }
inline float pcFetchOcclusion(const NoField &, int, int, vec3) { return 1.0f; }
inline vec4 pcFetchProbe(const NoField &, int, int) { return vec4(0.0f, 0.0f, 0.0f, 1.0f); }
}  // namespace pc::gpu
#define PC_FIELD_PARAM const pc::gpu::NoField &field,
#define PC_FIELD_ARG field,
#include "shaders/interop/probe_sampling.h"

// screen_ao_horizons.h reads a surface buffer through hooks as well: an empty buffer (no
// occluder anywhere) and straight-ahead rays compile it.
namespace pc::gpu {
struct NoSurfaces {};
inline vec4 pcAoSurface(const NoSurfaces &, ivec2) { return vec4(0.0f); }
inline vec3 pcAoNormal(const NoSurfaces &, ivec2) { return vec3(0.0f, 0.0f, 1.0f); }
inline vec3 pcAoRay(const NoSurfaces &, vec2 p) {
  return normalize(vec3(p.x * 0.01f, p.y * 0.01f, -1.0f));
}
}  // namespace pc::gpu
#define PC_AO_PARAM const pc::gpu::NoSurfaces &in,
#define PC_AO_ARG in,
#include "shaders/interop/screen_ao_horizons.h"

namespace {

using namespace pc::gpu;

TEST(InteropHeaders, OneLightRecordWithItsMarkedRows) {
  EXPECT_EQ(sizeof(GpuLight), 80u);
  EXPECT_EQ(offsetof(GpuLight, type), 12u);
  EXPECT_EQ(offsetof(GpuLight, direction), 16u);
  EXPECT_EQ(offsetof(GpuLight, range), 28u);
  EXPECT_EQ(offsetof(GpuLight, power), 32u);
  EXPECT_EQ(offsetof(GpuLight, cosOuter), 44u);
  EXPECT_EQ(offsetof(GpuLight, cosInner), 48u);
  EXPECT_EQ(offsetof(GpuLight, shadowMatrix), 64u);
  EXPECT_EQ(offsetof(GpuLight, depthBias), 72u);
}

TEST(InteropHeaders, LightKindsAreDistinct) {
  const int kinds[] = {PC_LIGHT_POINT, PC_LIGHT_SPOT, PC_LIGHT_DIRECTIONAL, PC_LIGHT_AREA};
  for (int i = 0; i < 4; ++i)
    for (int j = i + 1; j < 4; ++j) EXPECT_NE(kinds[i], kinds[j]);
}

// The client's and the tracer's descriptor sets are separate, each numbered from 0 without
// gaps up to its count.
TEST(InteropHeaders, BindingsFitTheirCounts) {
  const int client[] = {PC_CLIENT_BIND_FRAME, PC_CLIENT_BIND_LIGHTS, PC_CLIENT_BIND_TEXTURES,
                        PC_CLIENT_BIND_RASTER_COUNTERS};
  for (int b : client) EXPECT_LT(b, PC_CLIENT_BINDING_COUNT);
  const int trace[] = {PC_BIND_TLAS,        PC_BIND_LIGHTS,     PC_BIND_EMISSIVE,
                       PC_BIND_SDF_GRID,    PC_BIND_SDF_BRICKS, PC_BIND_SDF_TRIANGLES,
                       PC_BIND_SDF_OUTSIDE, PC_BIND_SDF_LISTS,  PC_BIND_TEXTURES};
  for (int b : trace) EXPECT_LT(b, PC_BINDING_COUNT);
  // The tracer's textures are its variable-count binding, which must be the last.
  EXPECT_EQ(PC_BIND_TEXTURES, PC_BINDING_COUNT - 1);
}

TEST(InteropHeaders, SamplingCompilesAgainstAnyFetch) {
  FieldDesc desc{};
  desc.cascadeCount = 0;
  float coverage = -1.0f;
  const vec4 s = pcSampleField(NoField{}, desc, vec3(0.0f), vec3(0.0f, 1.0f, 0.0f),
                               vec3(0.0f, 0.0f, 1.0f), PC_SAMPLE_DEFAULT, coverage);
  // No cascade holds data: nothing sampled, and the coverage says so.
  EXPECT_EQ(coverage, 0.0f);
  EXPECT_EQ(s, vec4(0.0f));
}

// With nothing in the buffer around it a surface is open: visibility 1, whatever its normal.
TEST(InteropHeaders, OcclusionOfAnEmptyBufferIsNone) {
  const NoSurfaces none;
  EXPECT_FLOAT_EQ(
      pcScreenAo(none, ivec2(10, 10), vec3(0.0f, 0.0f, -2.0f), vec3(0.0f, 0.0f, 1.0f), 0.5f), 1.0f);
  EXPECT_FLOAT_EQ(pcScreenAo(none, ivec2(10, 10), vec3(0.0f, 0.0f, -2.0f),
                             normalize(vec3(0.0f, 1.0f, 0.3f)), 0.5f),
                  1.0f);
}

}  // namespace
