// GPU-visible structures of the Vulkan field update (server/vulkan_tracer.cpp and the shaders
// probe_trace.*, probe_blend.comp, brick_*.comp): descriptor bindings, the scene in buffers,
// probe records and the per-update parameters. std430 layout; 16-byte rows are marked and C++
// checks the sizes with static_assert.
#ifndef PC_GPU_TRACE_H
#define PC_GPU_TRACE_H

#include "probe_math.h"

PC_BEGIN

// One descriptor set (set 0) shared by every pipeline of the update.
PC_CONST int PC_BIND_TLAS = 0;
PC_CONST int PC_BIND_PARAMS = 1;      // UpdateParams
PC_CONST int PC_BIND_FIELD = 2;       // FieldDesc
PC_CONST int PC_BIND_IRRADIANCE = 3;  // float[]: the CPU atlas layout (rgb interleaved)
PC_CONST int PC_BIND_DEPTH = 4;       // float[] (rg)
PC_CONST int PC_BIND_OCCLUSION = 5;   // float[] (r)
PC_CONST int PC_BIND_PROBES = 6;      // GpuProbeRecord[], field-wide slot index
PC_CONST int PC_BIND_REQUESTS = 7;    // ivec2[]: (cascade, slot) of each probe to update
PC_CONST int PC_BIND_RAY_DIRS = 8;    // vec4[]: this update's ray directions (xyz)
PC_CONST int PC_BIND_RAYS = 9;        // vec4[]: radiance rgb, signed distance; [probe * rays + ray]
PC_CONST int PC_BIND_VERTICES = 10;   // GpuVertex[]
PC_CONST int PC_BIND_INDICES = 11;    // uint[], mesh-local
PC_CONST int PC_BIND_MESHES = 12;     // GpuMesh[]
PC_CONST int PC_BIND_INSTANCES = 13;  // GpuInstance[]: shading records (custom + geometry index)
PC_CONST int PC_BIND_MATERIALS = 14;  // GpuMaterial[]
PC_CONST int PC_BIND_LIGHTS = 15;     // GpuLight[]
PC_CONST int PC_BIND_EMISSIVE = 16;   // GpuEmissiveTriangle[]
PC_CONST int PC_BIND_CHANGES = 17;    // float[] per requested probe: largest irradiance change
PC_CONST int PC_BIND_BRICK_FLAGS = 18;  // uint[] per field-wide brick: changed this update
PC_CONST int PC_BIND_BRICK_LIST = 19;   // uint[]: dispatch args (x = count, 1, 1), then bricks
PC_CONST int PC_BIND_PACKED = 20;       // float[]: changed bricks' tile rows, for the host
PC_CONST int PC_BIND_COUNTERS = 21;     // uint[PC_COUNTER_SLOTS]: shadow rays traced
PC_CONST int PC_BIND_TAPS = 22;         // uvec2[]: this update's blend taps (see below)
PC_CONST int PC_BIND_TEXTURES = 23;     // sampler2D[]: base colour and emissive textures; the
                                        // variable-count binding, so it must stay the last
PC_CONST int PC_BINDING_COUNT = 24;

PC_CONST int PC_COUNTER_SLOTS = 1024;  // shadow-ray counters are spread to avoid contention
PC_CONST int PC_BRICK_LIST_HEADER = 3;  // uints of dispatch arguments before the brick list
PC_CONST int PC_BLEND_THREADS = 256;    // probe_blend.comp workgroup: one depth texel each
PC_CONST int PC_BLEND_ROWS = 32768;     // workgroups per row of a 2D blend dispatch
PC_CONST int PC_MAX_RAYS_PER_PROBE = 1024;  // kMaxRaysPerProbe (common/field.h): blend scratch

// Blend taps (PC_BIND_TAPS), built on the host from the update's ray directions exactly as the
// CPU's BlendTaps: which rays feed which texel, with what lobe weight. Texels are numbered
// irradiance (n_i^2), then depth (n_d^2), then occlusion (n_o^2), each channel row-major. Entry
// t < PC_TAP_TEXELS is texel t's (tap count, first tap); tap j of a texel of a channel with N
// texels is at first + j * N (texels' taps interleave, so a warp's loads are contiguous), as
// (ray index, weight's float bits).
PC_CONST int PC_TAP_TEXELS = PC_IRRADIANCE_TEXELS * PC_IRRADIANCE_TEXELS + PC_DEPTH_TEXELS * PC_DEPTH_TEXELS +
                             PC_OCCLUSION_TEXELS * PC_OCCLUSION_TEXELS;

// Probe-ray launches are one-dimensional: a warp's 32 invocations trace the same ray direction
// from PC_TRACE_TILE_PROBES neighbouring probes (neighbouring slots of a brick), which keeps
// traversal, hit shading and field fetches coherent; launch index i covers probe
// tile * PC_TRACE_TILE_PROBES + (i mod tile's probes) and ray (i / tile's probes) within its tile.
PC_CONST int PC_TRACE_TILE_PROBES = 32;

// Misses report this distance instead of +infinity: shader compilers may assume finite
// floats. Above every comparison the update makes.
PC_CONST float PC_MISS_DISTANCE = 1e30f;

// Floats per probe in the packed readback: bordered irradiance, depth and occlusion tiles. A
// brick's probes are consecutive slots in one atlas tile row, so a brick packs as the atlas
// rows it covers: irradiance's n_i + 2 texel rows of PC_PROBES_PER_BRICK tiles, then depth's,
// then occlusion's; the host copies each packed row into the atlas with one memcpy.
PC_CONST int PC_PACKED_IRRADIANCE = (PC_IRRADIANCE_TEXELS + 2) * (PC_IRRADIANCE_TEXELS + 2) * 3;
PC_CONST int PC_PACKED_DEPTH = (PC_DEPTH_TEXELS + 2) * (PC_DEPTH_TEXELS + 2) * 2;
PC_CONST int PC_PACKED_OCCLUSION = (PC_OCCLUSION_TEXELS + 2) * (PC_OCCLUSION_TEXELS + 2);
PC_CONST int PC_PACKED_PROBE_FLOATS = PC_PACKED_IRRADIANCE + PC_PACKED_DEPTH + PC_PACKED_OCCLUSION;

PC_CONST int PC_LIGHT_POINT = 0;
PC_CONST int PC_LIGHT_SPOT = 1;
PC_CONST int PC_LIGHT_DIRECTIONAL = 2;

struct GpuVertex {
  vec3 position;  // object space
  float u;
  // -- 16
  vec3 normal;    // object space; zero when the mesh has none
  float v;
  // -- 32
};

struct GpuMesh {
  int firstVertex;
  int firstIndex;
  int material;
  int pad0;
  // -- 16
};

struct GpuInstance {
  mat4 objectToWorld;
  // -- 64
  mat4 normalToWorld;  // inverse transpose of the upper 3x3, in a mat4 for simple std430
  // -- 128
  int mesh;
  float side;  // -1 when the time-0 transform mirrors: the front face flips
  int pad0;
  int pad1;
  // -- 144
};

struct GpuMaterial {
  vec3 baseColor;
  int baseColorTexture;  // index into the texture array, -1: none
  // -- 16
  vec3 emissive;
  int emissiveTexture;
  // -- 32
  int sampled;  // 1: emission is light-sampled (EmissiveLights), so hits must not add it
  int pad0;
  int pad1;
  int pad2;
  // -- 48
};

struct GpuLight {
  vec3 position;
  int type;  // PC_LIGHT_*
  // -- 16
  vec3 direction;  // unit, where the light travels
  float range;     // 0: unlimited
  // -- 32
  vec3 power;  // colour x intensity
  float cosOuter;
  // -- 48
  float cosInner;
  float pad0;
  float pad1;
  float pad2;
  // -- 64
};

struct GpuEmissiveTriangle {
  vec3 p0;
  float area;
  // -- 16
  vec3 e1;
  float cdf;  // cumulative selection probability up to and including this triangle
  // -- 32
  vec3 e2;
  float pad0;
  // -- 48
  vec3 normal;
  float pad1;
  // -- 64
  vec3 radiance;
  float pad2;
  // -- 80
};

// Push constants of the probe-ray launches: the launch covers requests
// [probeBase, probeBase + probeCount).
struct TracePush {
  int probeBase;
  int probeCount;
};

struct GpuProbeRecord {
  vec3 offset;
  int state;
  // -- 16
  uint updates;
  uint pad0;
  uint pad1;
  uint pad2;
  // -- 32
};

struct UpdateParams {
  vec3 skyZenith;
  int rayCount;
  // -- 16
  vec3 skyHorizon;
  int probeCount;  // requested probes this update
  // -- 32
  vec3 skyGround;
  int shading;     // ShadingFlags (1: no indirect)
  // -- 48
  int lightCount;
  int emissiveCount;
  int emissiveSamples;
  uint seed;
  // -- 64
  float hysteresis;
  float changeThreshold;
  int brickTotal;  // bricks over all cascades
  int pad0;
  // -- 80
  ivec4 cascadeBrickOffset;  // first field-wide brick of each cascade
  // -- 96
};

PC_END

#ifdef __cplusplus
static_assert(sizeof(pc::gpu::GpuVertex) == 32);
static_assert(sizeof(pc::gpu::GpuMesh) == 16);
static_assert(sizeof(pc::gpu::GpuInstance) == 144);
static_assert(sizeof(pc::gpu::GpuMaterial) == 48);
static_assert(sizeof(pc::gpu::GpuLight) == 64);
static_assert(sizeof(pc::gpu::GpuEmissiveTriangle) == 80);
static_assert(sizeof(pc::gpu::GpuProbeRecord) == 32);
static_assert(sizeof(pc::gpu::TracePush) == 8);
static_assert(sizeof(pc::gpu::UpdateParams) == 96);
static_assert(pc::gpu::PC_MAX_CASCADES == 4);  // cascadeBrickOffset is an ivec4
#endif

#endif
