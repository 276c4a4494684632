// One case of the light model's GLSL/C++ agreement test (tests/test_light_model.cpp and
// light_model_check.comp): a light, a surface point and its normal. The emitter-geometry and
// ray-offset checks reuse the light's position and direction as the emitter point and normal.
#ifndef PC_LIGHT_MODEL_CHECK_H
#define PC_LIGHT_MODEL_CHECK_H

#include "../../shaders/interop/light_model.h"

PC_BEGIN

struct LightCheckCase {
  GpuLight light;
  // -- 80
  vec4 position;  // xyz: P
  vec4 normal;    // xyz: N (unit)
  // -- 112
};

// Per case, three vec4 results:
//   [0] pcLightIrradiance (xyz) and its distance (w)
//   [1] its wi (xyz) and pcEmitterGeometry(light.position, light.direction, P, N) (w)
//   [2] pcOffsetRayOrigin(P, N) (xyz), pcRangeWindow(distance to the light, range) (w)
PC_CONST int PC_LIGHT_CHECK_RESULTS = 3;

PC_END

#ifdef __cplusplus
static_assert(sizeof(pc::gpu::LightCheckCase) == 112);
#endif

#endif
