// Scene lights packed as the shared light model reads them (shaders/interop/light_model.h):
// what the Embree tracer, the CPU renders, the Vulkan tracer and the client all evaluate, so
// a light's cone angles and direction are turned into the record in one place.
#pragma once

#include <vector>

#include "../shaders/interop/light_model.h"
#include "scene.h"

namespace pc {

// One scene light as a GpuLight: unit direction, cosines of the cones (inner clamped to the
// outer), power = colour x intensity; the client's shadow-map fields left clear (no shadow).
gpu::GpuLight packLight(const Light& light);
// Every light of `state`, in order.
std::vector<gpu::GpuLight> packLights(const SceneState& state);

}  // namespace pc
