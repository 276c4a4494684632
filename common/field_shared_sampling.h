// The shared sampling code (shaders/interop/probe_sampling.h) bound to a CPU Field: its fetches
// read the atlases bilinearly (field.cpp), exactly as a GPU sampler with linear filtering would.
// For the code that runs the shared functions on a Field; others use sampleField (field.h).
#pragma once

#include "field.h"

namespace pc::gpu {
vec3 pcFetchIrradiance(const pc::Field& field, int cascade, int slot, vec3 dir);
vec2 pcFetchDepth(const pc::Field& field, int cascade, int slot, vec3 dir);
float pcFetchOcclusion(const pc::Field& field, int cascade, int slot, vec3 dir);
vec4 pcFetchProbe(const pc::Field& field, int cascade, int slot);
}  // namespace pc::gpu
#define PC_FIELD_PARAM const pc::Field &field,
#define PC_FIELD_ARG field,
#include "../shaders/interop/probe_sampling.h"
