// The probe field as storage buffers, in the CPU atlas layout (common/field.h) but for the
// irradiance texel, widened to a vec4 (rgb, w unused): every texel is then one aligned 16-byte
// load or store instead of three scalar ones (a depth texel, two floats, is one 8-byte load
// as it is). The host widens the CPU's rgb atlas on upload and brick_pack.comp narrows it
// back. Every stage of the update that reads or writes the field includes this. Define
// PC_FIELD_READONLY first for stages that only read it.
#ifndef PC_FIELD_BUFFERS_GLSL
#define PC_FIELD_BUFFERS_GLSL

#include "interop/gpu_trace.h"

#ifdef PC_FIELD_READONLY
#define PC_FIELD_ACCESS readonly
#else
#define PC_FIELD_ACCESS
#endif

layout(std430, set = 0, binding = PC_BIND_FIELD) readonly buffer FieldBuffer { FieldDesc field; };
layout(std430, set = 0, binding = PC_BIND_IRRADIANCE) PC_FIELD_ACCESS buffer IrradianceAtlas { vec4 irradianceTexels[]; };
layout(std430, set = 0, binding = PC_BIND_DEPTH) PC_FIELD_ACCESS buffer DepthAtlas { vec2 depthTexels[]; };
layout(std430, set = 0, binding = PC_BIND_OCCLUSION) PC_FIELD_ACCESS buffer OcclusionAtlas { float occlusionTexels[]; };
layout(std430, set = 0, binding = PC_BIND_PROBES) PC_FIELD_ACCESS buffer ProbeRecords { GpuProbeRecord probes[]; };

// Atlas widths in texels (PC_ATLAS_TILES_PER_ROW tiles per row).
const int PC_IRRADIANCE_ATLAS_WIDTH = PC_ATLAS_TILES_PER_ROW * (PC_IRRADIANCE_TEXELS + 2);
const int PC_DEPTH_ATLAS_WIDTH = PC_ATLAS_TILES_PER_ROW * (PC_DEPTH_TEXELS + 2);
const int PC_OCCLUSION_ATLAS_WIDTH = PC_ATLAS_TILES_PER_ROW * (PC_OCCLUSION_TEXELS + 2);

// Texel indices into the atlas arrays.
int pcIrradianceIndex(ivec2 p) { return p.y * PC_IRRADIANCE_ATLAS_WIDTH + p.x; }
int pcDepthIndex(ivec2 p) { return p.y * PC_DEPTH_ATLAS_WIDTH + p.x; }
int pcOcclusionIndex(ivec2 p) { return p.y * PC_OCCLUSION_ATLAS_WIDTH + p.x; }

#endif
