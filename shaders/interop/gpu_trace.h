// GPU-visible structures of the Vulkan field update (server/vulkan_tracer*.cpp and the shaders
// probe_trace.*, probe_shade.comp, probe_shadow.rgen, probe_blend.comp, brick_*.comp):
// descriptor bindings, the scene in buffers, probe records, the per-ray wavefront records and
// the per-update parameters. std430 layout; 16-byte rows are marked and C++ checks the sizes
// with static_assert.
//
// An update runs as a wavefront of passes, each over every probe ray of the update:
//   trace   (probe_trace.rgen)   closest hit of each probe ray -> GpuHit
//   shade   (probe_shade.comp)   material, emission, previous field at the hit -> `rays`
//                                (radiance toward the probe without direct light, distance);
//                                for each shadow slot with a real shadow ray, what the light adds
//                                to that radiance (GpuShadowLight), and the ray appended to a
//                                compacted list of GpuShadowRay
//   shadow  (probe_shadow.rgen)  any-hit test of each listed ray -> a bit in its ray's mask
// (The SDF backend traces and shadow-tests in compute: sdf_trace.comp, sdf_shadow.comp.)
//   blend   (probe_blend.comp)   adds the visible slots' light, blends into the tiles
// Per-ray records are stored in launch order (pcLaunchProbeRay below), so every pass reads
// and writes them coalesced. The shadow list is appended a subgroup at a time, so each
// subgroup's rays stay together in launch order (neighbouring probes, one direction, one
// light); the order of the subgroups' runs varies from run to run, which changes nothing:
// each ray sets only its own bit, and the blend sums the visible slots in slot order.
// Only what a ray needs travels: a miss or a backface hit leaves 16 bytes and a mask word,
// and the blend reads a slot's light only where its bit is set.
#ifndef PC_GPU_TRACE_H
#define PC_GPU_TRACE_H

#include "light_model.h"
#include "probe_math.h"
#include "specular_probe.h"

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
PC_CONST int PC_BIND_RAYS =
    9;  // vec4[] per ray, launch order: radiance without direct light, signed distance
PC_CONST int PC_BIND_VERTICES = 10;     // GpuVertex[]
PC_CONST int PC_BIND_INDICES = 11;      // uint[], mesh-local
PC_CONST int PC_BIND_MESHES = 12;       // GpuMesh[]
PC_CONST int PC_BIND_INSTANCES = 13;    // GpuInstance[]: shading records (custom + geometry index)
PC_CONST int PC_BIND_MATERIALS = 14;    // GpuMaterial[]
PC_CONST int PC_BIND_LIGHTS = 15;       // GpuLight[]
PC_CONST int PC_BIND_EMISSIVE = 16;     // GpuEmissiveTriangle[]
PC_CONST int PC_BIND_CHANGES = 17;      // float[] per requested probe: largest irradiance change
PC_CONST int PC_BIND_BRICK_FLAGS = 18;  // uint[] per field-wide brick: changed this update
PC_CONST int PC_BIND_BRICK_LIST = 19;   // uint[]: dispatch args (x = count, 1, 1), then bricks
PC_CONST int PC_BIND_PACKED = 20;       // float[]: changed bricks' tile rows, for the host
PC_CONST int PC_BIND_COUNTERS = 21;  // uint[PC_COUNTER_WORDS per slot]: its list's length, 1, 1, 0
PC_CONST int PC_BIND_TAPS = 22;      // uint[]: this update's blend taps (see below)
PC_CONST int PC_BIND_HITS = 23;      // GpuHit[] per ray, launch order
PC_CONST int PC_BIND_SHADOW_MASK =
    24;  // uint[]: visible shadow slots, [word * (rays of the update) + launch index]
PC_CONST int PC_BIND_SHADOW_RAYS = 25;   // GpuShadowRay[]: [slot * rays of the update + i], each
                                         // slot's compacted list of real shadow rays
PC_CONST int PC_BIND_SHADOW_LIGHT = 26;  // GpuShadowLight[]: [slot * rays of the update + launch
                                         // index] (masks, lists and lights: the slot's place in its
                                         // round, pcShadowRounds)
// The SDF tracer's distance field (interop/sdf_grid.h), in place of the TLAS: the
// ray-tracing backend's layout leaves these out, the SDF backend's leaves out PC_BIND_TLAS.
PC_CONST int PC_BIND_SDF_GRID = 27;       // SdfHeader, then SdfCell[]
PC_CONST int PC_BIND_SDF_BRICKS = 28;     // SdfSample[]
PC_CONST int PC_BIND_SDF_TRIANGLES = 29;  // SdfTriangle[]
PC_CONST int PC_BIND_SDF_OUTSIDE = 30;    // uint[]: triangles reaching outside the grid
PC_CONST int PC_BIND_SDF_LISTS = 31;      // uint[]: each brick's cell's triangles (sdf_grid.h)
PC_CONST int PC_BIND_TEXTURES = 32;       // sampler2D[]: base colour and emissive textures; the
                                          // variable-count binding, so it must stay the last
PC_CONST int PC_BINDING_COUNT = 33;

// The counters (PC_BIND_COUNTERS), PC_COUNTER_WORDS per shadow slot: the length of the slot's
// shadow list (the shadow rays it traces), then 1, 1: a VkTraceRaysIndirectCommandKHR for the
// slot's shadow launch, which covers exactly its list where the device can launch from a
// buffer. Each slot (light, or emissive sample) has its own list, so the rays of a warp of the
// shadow launch all head for the same light.
PC_CONST int PC_COUNTER_WORDS = 4;
PC_CONST int PC_BRICK_LIST_HEADER = 3;      // uints of dispatch arguments before the brick list
PC_CONST int PC_DISPATCH_ROWS = 32768;      // workgroups per row of a 2D compute dispatch
PC_CONST int PC_SHADE_THREADS = 128;        // probe_shade.comp workgroup: one ray each
PC_CONST int PC_MAX_RAYS_PER_PROBE = 1024;  // kMaxRaysPerProbe (common/field.h): blend scratch

// probe_blend.comp: a workgroup blends up to PC_BLEND_MAX_PROBES consecutive requests, as many
// as its shared scratch of PC_MAX_RAYS_PER_PROBE rays holds (a power of two, so a group never
// straddles a launch tile), so each tap it loads serves every one of them. Its first
// PC_IRRADIANCE_TEXELS^2 threads own an irradiance and occlusion texel each, the others share
// the depth texels: about the same number of taps per thread.
PC_CONST int PC_BLEND_THREADS = 128;
PC_CONST int PC_BLEND_MAX_PROBES = 4;
PC_FN int pcBlendProbes(int rayCount) {
  return rayCount * 4 <= PC_MAX_RAYS_PER_PROBE ? 4 : rayCount * 2 <= PC_MAX_RAYS_PER_PROBE ? 2 : 1;
}
// The blend's shared ray scratch, in rays (a padded row of rayCount + 1 per probe of the
// group): the pipeline is specialized with it (constant_id 1), so a group holds no more shared
// memory than its rays need.
PC_FN int pcBlendScratch(int groupProbes, int rayCount) { return groupProbes * (rayCount + 1); }

// Blend taps (PC_BIND_TAPS), built on the host from the update's ray directions exactly as the
// CPU's BlendTaps: which rays feed which texel, with what lobe weight. Irradiance and occlusion
// tiles have the same size and the same cosine lobe, so their taps are one list (the CPU builds
// it twice). Texels are numbered irradiance/occlusion (n_i^2), then depth (n_d^2), each channel
// row-major. Words 2t and 2t + 1 (t < PC_TAP_TEXELS) are texel t's tap count and first tap
// word. A tap is one word: the ray index in the low 16 bits, the weight's float16 bits in the
// high 16 (the CPU rounds its weights to float16, so both sum the same weights). A texel's
// taps come in blocks of four consecutive words, and a channel with N texels interleaves its
// texels' blocks: tap j of texel t is word first + (j / 4) * 4N + j % 4, with first = base +
// 4t (a block's unused words are zero). So each thread loads four taps at once, and a warp's
// loads are contiguous. Every workgroup reads the whole table: at two words a tap, one at a
// time, those reads were a third of the blend's time on an H200.
PC_CONST int PC_TAP_TEXELS =
    PC_IRRADIANCE_TEXELS * PC_IRRADIANCE_TEXELS + PC_DEPTH_TEXELS * PC_DEPTH_TEXELS;

// Probe-ray launches are one-dimensional: a warp's 32 invocations trace the same ray direction
// from PC_TRACE_TILE_PROBES neighbouring probes (neighbouring slots of a brick), which keeps
// traversal, hit shading and field fetches coherent; launch index i covers probe
// tile * PC_TRACE_TILE_PROBES + (i mod tile's probes) and ray (i / tile's probes) within its tile.
// The later passes keep this order.
PC_CONST int PC_TRACE_TILE_PROBES = 32;

// Request (x) and ray (y) of launch index `id` of a launch over `probeCount` requests.
PC_FN ivec2 pcLaunchProbeRay(uint id, int probeCount, int rayCount) {
  uint tileRays = uint(PC_TRACE_TILE_PROBES * rayCount);
  int tile = int(id / tileRays);
  int first = tile * PC_TRACE_TILE_PROBES;
  uint tileProbes = uint(min(PC_TRACE_TILE_PROBES, probeCount - first));
  uint within = id - uint(tile) * tileRays;
  return ivec2(first + int(within % tileProbes), int(within / tileProbes));
}
// The inverse: launch index of ray `ray` of request `probe`.
PC_FN uint pcProbeRayLaunchIndex(int probe, int ray, int probeCount, int rayCount) {
  int tile = probe / PC_TRACE_TILE_PROBES;
  int first = tile * PC_TRACE_TILE_PROBES;
  int tileProbes = min(PC_TRACE_TILE_PROBES, probeCount - first);
  return uint(first) * uint(rayCount) + uint(ray * tileProbes + probe - first);
}

// Shadow rays per probe ray: a fixed slot per punctual light, then one per emissive sample
// (when the scene has light-sampled emitters). Slot s of launch index i is GpuShadowLight
// s * (rays of the update) + i; only slots with a real ray are in the shadow list.
PC_FN int pcShadowSlots(int lightCount, int emissiveCount, int emissiveSamples) {
  return lightCount + (emissiveCount > 0 && emissiveSamples > 0 ? emissiveSamples : 0);
}
// Words of a ray's visibility mask (PC_BIND_SHADOW_MASK): bit s % 32 of word s / 32 is slot s.
PC_FN int pcShadowMaskWords(int slots) { return (slots + 31) / 32; }

// Shadow rounds. A slot's shadow list and lights take a record per probe ray of the update, so
// the memory of shadow slots grows with lights x probes x rays (48 bytes per ray and slot:
// 200 MB a slot at 16,384 probes x 256 rays). The tracer holds at most `roundSlots` slots'
// records (UpdateParams::roundSlots, from a memory budget and the device's storage-buffer
// range, which one round's shadow-ray buffer may not pass) and, with more slots, runs shade
// and shadow trace once per round of that many slots (TracePush::slotBase: the round's first
// slot): the first round writes the rays' records, every round requests its own slots'
// shadow rays, and a resolve pass (probe_resolve.comp) adds the visible light of the round's
// slots to the rays in slot order, the order in which the blend adds them in a single round.
// So the rounds give the very same field. Masks, lists and lights are indexed by the slot's
// place in its round; counters by the slot itself.
PC_FN int pcShadowRounds(int slots, int roundSlots) {
  return slots <= 0 ? 0 : (slots + roundSlots - 1) / roundSlots;
}

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

struct GpuVertex {
  vec3 position;  // object space
  float u;
  // -- 16
  vec3 normal;  // object space; zero when the mesh has none
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
  // Cut-outs (Material::isCutOut, pc::coveredAt): a hit counts where baseAlpha x channel
  // alphaChannel of texture alphaTexture (-1: none) reaches alphaCutoff; 0: opaque, no test.
  int alphaTexture;
  int alphaChannel;
  float alphaCutoff;
  // -- 48
  float baseAlpha;
  int alphaWrapU;  // the alpha texture's wrap modes (TextureWrap: 0 repeat, 1 clamp to edge,
  int alphaWrapV;  // 2 mirrored repeat), for the any-hit shader's own bilinear lookup
  int pad2;
  // -- 64
  // The metallic-roughness model (Material::metallic, roughness, metallicRoughnessTexture: a
  // linear texture, B metallic, G roughness), for probe_hit_shading.h.
  float metallic;
  float roughness;
  int metallicRoughnessTexture;
  int pad3;
  // -- 80
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

// Push constants of the ray launches: the launch covers items [first, first + count), requests
// for the probe-ray launch, shadow requests for the shadow launch. slotBase: the first shadow
// slot of the round (the shade pass and the shadow launch; see pcShadowRounds).
struct TracePush {
  int first;
  int count;
  int slotBase;
  int pad0;
};

// A probe ray's closest hit (probe_trace.rgen -> probe_shade.comp).
struct GpuHit {
  vec2 barycentric;
  float t;
  int instance;  // shading record (GpuInstance); -1: miss
  // -- 16
  int primitive;
  int pad0;
  // -- 24
};

// One real shadow ray of the compacted list (probe_shade.comp -> probe_shadow.rgen).
struct GpuShadowRay {
  vec3 origin;
  float tmax;
  // -- 16
  vec3 direction;
  uint light;  // its GpuShadowLight: slot * (rays of the update) + launch index
  // -- 32
};

// What a shadow slot adds to its ray's radiance toward the probe when its shadow ray reaches
// the light: albedo / pi x the light's irradiance (divided by the sample count for emissive
// samples). Written by the shade pass for real shadow rays only; the blend reads it where
// the slot's mask bit is set.
struct GpuShadowLight {
  vec3 radiance;
  float pad0;
  // -- 16
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
  int shading;  // ShadingFlags (1: no indirect)
  // -- 48
  int lightCount;
  int emissiveCount;
  int emissiveSamples;
  uint seed;
  // -- 64
  float pad0;  // (each cascade's hysteresis is in its CascadeDesc)
  float changeThreshold;
  int brickTotal;   // bricks over all cascades
  int shadowSlots;  // pcShadowSlots
  // -- 80
  ivec4 cascadeBrickOffset;  // first field-wide brick of each cascade
  // -- 96
  float shadowRouletteShare;  // TracerOptions::shadowRouletteShare (interop/shadow_roulette.h)
  int roundSlots;             // shadow slots per round (pcShadowRounds)
  int lightsResolved;         // 1: the rounds' resolve passes added the visible light to the rays
  int requestBase;            // the request index of this pass's first probe (an update in slices)
  // -- 112
  // The split-sum table (specular_probe.h, common/split_sum_table.h) that glossy hits weigh
  // their specular lobe by: entry e in splitSum[e / 2], .xy when e is even, .zw when odd.
  vec4 splitSum[PC_SPLIT_SUM_ENTRIES / 2];
  // -- 112 + 16 x 128
};

PC_END

#ifdef __cplusplus
static_assert(sizeof(pc::gpu::GpuVertex) == 32);
static_assert(sizeof(pc::gpu::GpuMesh) == 16);
static_assert(sizeof(pc::gpu::GpuInstance) == 144);
static_assert(sizeof(pc::gpu::GpuMaterial) == 80);
static_assert(sizeof(pc::gpu::GpuEmissiveTriangle) == 80);
static_assert(sizeof(pc::gpu::GpuProbeRecord) == 32);
static_assert(sizeof(pc::gpu::TracePush) == 16);
static_assert(sizeof(pc::gpu::GpuHit) == 24);
static_assert(sizeof(pc::gpu::GpuShadowRay) == 32);
static_assert(sizeof(pc::gpu::GpuShadowLight) == 16);
static_assert(sizeof(pc::gpu::UpdateParams) == 112 + 16 * pc::gpu::PC_SPLIT_SUM_ENTRIES / 2);
static_assert(pc::gpu::PC_MAX_CASCADES == 4);  // cascadeBrickOffset is an ivec4
#endif

#endif
