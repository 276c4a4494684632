// GPU-visible description of a probe field: one CascadeDesc per cascade and the constants
// every side (Embree path, CPU renders, shaders, wire format) agrees on. std430 layout:
// 16-byte rows are marked; C++ checks the sizes with static_assert.
#ifndef PC_FIELD_DESC_H
#define PC_FIELD_DESC_H

#include "pc_interop.h"

PC_BEGIN

// Texels per side of each probe tile, without the 1-texel border. Fixed at compile time so the
// shaders can size their shared memory and loops; the wire format records them anyway.
PC_CONST int PC_IRRADIANCE_TEXELS = 8;
PC_CONST int PC_DEPTH_TEXELS = 16;
PC_CONST int PC_OCCLUSION_TEXELS = 8;
PC_CONST int PC_BRICK_SIZE = 4;  // probes per brick side
PC_CONST int PC_MAX_CASCADES = 4;
PC_CONST int PC_ATLAS_TILES_PER_ROW = 128;  // tiles per atlas row; cascades stack vertically

// Probe states (ProbeRecord.state).
PC_CONST int PC_PROBE_ACTIVE = 0;
PC_CONST int PC_PROBE_SLEEPING = 1;  // no geometry near: kept, sampled, not traced every update
PC_CONST int PC_PROBE_INSIDE = 2;    // inside geometry: never sampled
PC_CONST int PC_PROBE_UNINITIALIZED = 3;  // no data yet: never sampled

// Sampling flags (pcSampleField).
PC_CONST int PC_SAMPLE_DEFAULT = 0;
PC_CONST int PC_SAMPLE_NO_VISIBILITY = 1;  // trilinear only: the naive baseline that leaks
PC_CONST int PC_SAMPLE_NO_OCCLUSION = 2;   // skip the occlusion tile (probe-ray hit shading)
// No wider search when a point's cages hold no probe with data (tests: what the fallback saves).
PC_CONST int PC_SAMPLE_NO_FALLBACK = 4;
// Also the probes' GGX-filtered radiance toward a mirror direction (specular_probe.h), with the
// same probe weights as the irradiance: pcSampleFieldLit.
PC_CONST int PC_SAMPLE_SPECULAR = 8;

// Irradiance encodings of a cascade (CascadeDesc.encoding). Octahedral: the irradiance tiles
// are the field's own. SH: spherical-harmonics coefficients of radiance per probe (sh_probe.h)
// are the field's own, and the irradiance tiles are derived from them after every update, so
// that whatever reads tiles (wire, GPU client) keeps working. Depth moments and occlusion stay
// octahedral in every encoding: SH this low in order cannot carry visibility.
PC_CONST int PC_ENCODING_OCTAHEDRAL = 0;
PC_CONST int PC_ENCODING_SH1 = 1;  // L1: 4 coefficients per colour channel
PC_CONST int PC_ENCODING_SH2 = 2;  // L2: 9 coefficients per colour channel

PC_CONST float PC_PI = 3.14159265358979f;
PC_CONST float PC_IRRADIANCE_GAMMA = 5.0f;  // encoding gamma of the irradiance atlas

struct CascadeDesc {
  vec3 origin;    // world position of logical probe (0,0,0)
  float spacing;  // distance between neighbouring probes (same on all axes)
  // -- 16
  ivec3 counts;    // probes per axis
  int firstProbe;  // index of this cascade's first probe in field-wide probe arrays
  // -- 32
  ivec3 scroll;      // toroidal shift, in [0, counts): physical = (logical + scroll) mod counts
  int atlasTileRow;  // first atlas tile row of this cascade
  // -- 48
  float normalBias;      // world units, along the surface normal
  float viewBias;        // world units, towards the viewer
  float maxRayDistance;  // depth moments are clamped to this
  float blendMargin;     // world units over which a point fades to the next coarser cascade
  // -- 64
  float hysteresis;  // the blend's weight of history (FieldSettings, or the volume's own)
  int encoding;      // PC_ENCODING_*: how the cascade stores irradiance (sh_probe.h)
  // 1: the cascade follows the viewers (common/field_scroll.h): its origin and scroll move at
  // run time, and its bricks carry a layout stamp. Server-side; shaders ignore it.
  int follows;
  float pad2;
  // -- 80
};

struct FieldDesc {
  int cascadeCount;
  int probeCount;    // all cascades
  float hysteresis;  // FieldSettings::hysteresis; each cascade blends with its own
  float distanceExponent;
  // -- 16
  float occlusionDistance;  // d_max of the occlusion tile
  int atlasTileRows;        // all cascades
  int pad0;
  int pad1;
  // -- 32
  CascadeDesc cascades[PC_MAX_CASCADES];
};

PC_END

#ifdef __cplusplus
static_assert(sizeof(pc::gpu::CascadeDesc) == 80);
static_assert(sizeof(pc::gpu::FieldDesc) == 32 + 80 * pc::gpu::PC_MAX_CASCADES);
// probe_sampling.h decodes e^(gamma/2) as e*e*sqrt(e): valid for gamma 5 only.
static_assert(pc::gpu::PC_IRRADIANCE_GAMMA == 5.0f);
#endif

#endif
