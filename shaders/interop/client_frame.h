// GPU-visible structs of the client renderer, shared by client/ and shaders/client/: the
// per-frame uniforms, one record per draw and the descriptor bindings. std140
// (uniforms) and std430 (buffers) agree on these layouts because every member is a scalar,
// a vec4 or a mat4 placed on a 16-byte boundary; C++ checks the sizes with static_assert.
#ifndef PC_CLIENT_FRAME_H
#define PC_CLIENT_FRAME_H

#include "light_model.h"
#include "pc_interop.h"
#include "probe_view.h"
#include "specular_probe.h"

PC_BEGIN

// Descriptor bindings of the client's one descriptor set (set 0).
PC_CONST int PC_CLIENT_BIND_FRAME = 0;            // uniform FrameUniforms
PC_CONST int PC_CLIENT_BIND_FIELD_DESC = 1;       // uniform FieldDesc
PC_CONST int PC_CLIENT_BIND_DRAWS = 2;            // buffer DrawData[]
PC_CONST int PC_CLIENT_BIND_LIGHTS = 3;           // buffer GpuLight[] (light_model.h)
PC_CONST int PC_CLIENT_BIND_SHADOW_MATRICES = 4;  // buffer mat4[] (one per shadow layer)
PC_CONST int PC_CLIENT_BIND_PROBES = 5;           // buffer vec4[]: relocation offset xyz, state w
PC_CONST int PC_CLIENT_BIND_IRRADIANCE = 6;       // sampler2D, linear
PC_CONST int PC_CLIENT_BIND_DEPTH = 7;            // sampler2D, linear
PC_CONST int PC_CLIENT_BIND_OCCLUSION = 8;        // sampler2D, linear
PC_CONST int PC_CLIENT_BIND_SHADOW_MAPS =
    9;  // sampler2DArrayShadow[3]: large maps, small maps, point-light cube faces
PC_CONST int PC_CLIENT_BIND_TEXTURES = 10;  // sampler2D[textureCount]
PC_CONST int PC_CLIENT_BIND_G_VISIBILITY =
    11;  // usampler2DMSArray: draw's triangleBase + primitive + 1, 0: sky
PC_CONST int PC_CLIENT_BIND_VERTICES = 12;   // buffer float[]: the packed Vertex records
PC_CONST int PC_CLIENT_BIND_INDICES = 13;    // buffer uint[]: the packed index buffer
PC_CONST int PC_CLIENT_BIND_HDR_IMAGE = 14;  // image2DArray rgba32f: the final linear frame
PC_CONST int PC_CLIENT_BIND_HDR_TEXTURE =
    15;                                    // sampler2DArray: the same image, read by tone mapping
PC_CONST int PC_CLIENT_BIND_OVERLAY = 16;  // buffer OverlayText
// The compute rasterizer (RendererOptions::computeRaster; client_raster*.comp):
PC_CONST int PC_CLIENT_BIND_VIS_SAMPLES =
    17;  // buffer uint64 per sample: depth bits << 32 | visibility id
PC_CONST int PC_CLIENT_BIND_RASTER_TRIANGLES =
    18;  // buffer RasterTriangle[]: triangles split into tile jobs
PC_CONST int PC_CLIENT_BIND_RASTER_JOBS =
    19;  // buffer uvec2[]: (RasterTriangle index, tile y << 16 | x)
PC_CONST int PC_CLIENT_BIND_RASTER_COUNTERS = 20;  // buffer RasterCounters
// Ambient occlusion of the indirect light (screen_ao.h), written by client_ao_surfaces.comp:
PC_CONST int PC_CLIENT_BIND_AO_SURFACES =
    21;  // buffer vec4[2] per pixel and view: (position - eye, 1 or 0: sky), (normal, 0)
// The probe debug view (probe_view.h): per brick of every cascade, how much it flashes.
PC_CONST int PC_CLIENT_BIND_BRICK_FLASH = 22;  // buffer float[] (ProbeViewParams::brickBase)
PC_CONST int PC_CLIENT_BINDING_COUNT = 23;

PC_CONST int PC_MAX_VIEWS = 2;

// Floats per packed vertex (client/scene_pack.h, Vertex): position, normal, uv, tangent.
PC_CONST int PC_CLIENT_VERTEX_FLOATS = 12;

struct ClientView {
  mat4 viewProj;  // world -> clip (Vulkan: y down, reversed depth 1 at near, 0 at infinity)
  mat4 invViewProjFromEye;  // clip -> world offset from `position` (no translation: see camera.h)
  vec4 position;            // camera position, w unused
};

struct FrameUniforms {
  ClientView views[PC_MAX_VIEWS];
  // -- 288
  vec4 skyZenith;  // rgb radiance, w unused
  vec4 skyHorizon;
  vec4 skyGround;
  vec4 ambient;  // rgb: irradiance used where no cascade holds data
  // -- 352
  vec2 viewport;  // render size in pixels
  float exposure;
  int lightCount;
  // -- 368
  int viewCount;
  int fieldPresent;  // 0: no field at all, ambient everywhere
  int sampleFlags;   // PC_SAMPLE_* of field_desc.h
  int overlayLines;  // 0: no overlay text
  // -- 384
  int drawCount;       // DrawData records (the visibility buffer's triangle ids index them)
  uint triangleCount;  // triangle ids in all (PackedScene::triangleIds)
  uint rasterTriangleCapacity;  // RasterTriangle records the compute rasterizer may append
  uint rasterJobCapacity;       // tile jobs it may append
  // -- 400
  float aoRadius;  // ambient occlusion radius of the indirect light, in probe spacings; 0: off
  // Foveated field sampling: outside this radius (a fraction of the view's half width and half
  // height, an ellipse about its centre) the field is sampled at one pixel of four and shared
  // with the neighbours whose surface matches (client_indirect.comp); 0: every pixel.
  float foveaRadius;
  int pad1;
  int pad2;
  // -- 416
  ProbeViewParams probeView;
  // -- 448
  // The split-sum table (specular_probe.h), two (A, B) entries per vec4: entry e in
  // splitSum[e / 2], .xy when e is even, .zw when odd.
  vec4 splitSum[PC_SPLIT_SUM_ENTRIES / 2];
  // -- 448 + 16 x 128
};

// One draw: an instance of a mesh with its material. Indexed by gl_InstanceIndex (each draw
// is issued with firstInstance = its index). The visibility buffer names a triangle by
// triangleBase + its primitive index in the draw, so every draw owns a range of ids; the
// lighting pass finds the draw by binary search over triangleBase (ascending with the index).
struct DrawData {
  mat4 model;         // object -> world
  mat4 normalMatrix;  // inverse transpose of model (upper 3x3 used)
  vec4 baseColor;     // linear albedo factor; w: cut-outs' base alpha
  vec4 emissive;      // linear emitted radiance factor; w: cut-outs' alpha cutoff (0: opaque)
  ivec4 textures;     // x: base color texture (-1 none), y: emissive texture (-1 none),
                      // z: bit v set when the draw's bounds touch view v's frustum,
                      // w: cut-outs' alpha texture x 4 + channel (-1 none)
  // x: first index in the packed index buffer, y: vertex offset, z: triangleBase,
  // w: +1 or -1, the sign of the model's determinant (a mirroring transform keeps the mesh's
  // own front faces, as the CPU renders do)
  ivec4 geometry;
  // -- 192
  int normalTexture;  // tangent-space normal map (-1: none, or the mesh has no tangents)
  float normalScale;  // its x and y scale (Material::normalScale)
  float metallic;     // Material::metallic and roughness (brdf.h), multiplied by the texture's
  float roughness;    // B and G where metallicRoughnessTexture is one
  // -- 208
  int metallicRoughnessTexture;  // linear (UNORM) texture: B metallic, G roughness; -1: none
  int pad0;
  int pad1;
  int pad2;
};

// Shadow map rendering's push constants (client_shadow.vert): the layer's view-projection from
// the shadow origin, and that origin (light_pack.h, ShadowView).
struct ShadowPush {
  mat4 fromOrigin;
  vec4 origin;  // xyz; w unused
};

// The field-write pass (client_field_write.comp, its own descriptor set): writes whole
// bordered tiles of the listed bricks from their interiors (borders derived on the GPU), each
// texel moved `weight` of the way from what the atlas holds toward the brick's new value.
PC_CONST int PC_FW_BIND_FIELD_DESC = 0;       // uniform FieldDesc
PC_CONST int PC_FW_BIND_WRITES = 1;           // buffer FieldWrite[]
PC_CONST int PC_FW_BIND_IRRADIANCE_NEW = 2;   // buffer vec4[]: per probe slot n*n interior texels
PC_CONST int PC_FW_BIND_DEPTH_NEW = 3;        // buffer vec2[]
PC_CONST int PC_FW_BIND_OCCLUSION_NEW = 4;    // buffer float[]
PC_CONST int PC_FW_BIND_IRRADIANCE_HELD = 5;  // sampler2D: the atlases as they are
PC_CONST int PC_FW_BIND_DEPTH_HELD = 6;
PC_CONST int PC_FW_BIND_OCCLUSION_HELD = 7;
PC_CONST int PC_FW_BIND_IRRADIANCE_OUT = 8;  // image2D (written without a format)
PC_CONST int PC_FW_BIND_DEPTH_OUT = 9;
PC_CONST int PC_FW_BIND_OCCLUSION_OUT = 10;
PC_CONST int PC_FW_BINDING_COUNT = 11;
PC_CONST int PC_FW_GROUP_SIZE = 64;  // threads per probe tile set

struct FieldWrite {
  int cascade;
  int brick;
  float weight;  // 1: the new value exactly; below 1: part of the way (fading in)
  int pad0;
};

// The compute rasterizer: a thread per triangle clips it (near plane and a guard band), snaps
// it to PC_RASTER_SUBPIXEL fixed point and covers small ones itself; larger ones become one
// job per PC_RASTER_TILE^2 pixel tile they touch, each covered by a workgroup. Depth and id go
// into each sample with one 64-bit atomic max (reversed depth: nearer is larger).
PC_CONST int PC_RASTER_SUBPIXEL = 256;      // fixed-point steps per pixel
PC_CONST int PC_RASTER_TILE = 32;           // pixels per side of a tile job
PC_CONST int PC_RASTER_SMALL = 64;          // bounding boxes up to this many pixels: one thread
PC_CONST int PC_RASTER_GROUP = 64;          // threads per workgroup of the triangle pass
PC_CONST int PC_RASTER_TILE_GROUP = 256;    // threads per tile job
PC_CONST int PC_RASTER_MAX_GROUPS = 65535;  // per dispatch dimension (the Vulkan minimum limit)
PC_CONST float PC_RASTER_GUARD =
    8.0;  // guard band, in viewport half-sizes (keeps fixed point in range)

struct RasterTriangle {
  ivec4 ab;       // fixed-point screen positions of the corners a, b
  ivec4 cIdView;  // c, visibility id, view
  vec4 depth;     // at a, b, c (w unused)
};

struct RasterCounters {
  uvec4 dispatch;  // xyz: the tile pass's indirect workgroup counts
  uint triangles;  // RasterTriangle records appended
  uint jobs;       // tile jobs appended
  uint dropped;    // triangles or jobs past a capacity (not drawn)
  uint pad0;
};

// Overlay text: `lines` x `columns` character codes (ASCII), one per uint, drawn with the
// 5x7 font in `glyphs` (7 rows of 5 bits per glyph, glyphs for codes 32..127).
PC_CONST int PC_OVERLAY_COLUMNS = 48;
PC_CONST int PC_OVERLAY_MAX_LINES = 6;
PC_CONST int PC_FONT_FIRST = 32;
PC_CONST int PC_FONT_GLYPHS = 96;
PC_CONST int PC_FONT_ROWS = 7;
PC_CONST int PC_FONT_COLUMNS = 5;

struct OverlayText {
  uint glyphs[PC_FONT_GLYPHS * PC_FONT_ROWS];
  uint text[PC_OVERLAY_MAX_LINES * PC_OVERLAY_COLUMNS];
};

PC_END

#ifdef __cplusplus
static_assert(sizeof(pc::gpu::ClientView) == 144);
static_assert(sizeof(pc::gpu::FrameUniforms) == 448 + 16 * pc::gpu::PC_SPLIT_SUM_ENTRIES / 2);
static_assert(sizeof(pc::gpu::DrawData) == 224);
static_assert(sizeof(pc::gpu::FieldWrite) == 16);
static_assert(sizeof(pc::gpu::RasterTriangle) == 48);
static_assert(sizeof(pc::gpu::RasterCounters) == 32);
static_assert(sizeof(pc::gpu::OverlayText) ==
              4 * (pc::gpu::PC_FONT_GLYPHS * pc::gpu::PC_FONT_ROWS +
                   pc::gpu::PC_OVERLAY_MAX_LINES * pc::gpu::PC_OVERLAY_COLUMNS));
#endif

#endif
