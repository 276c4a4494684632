#include "field.h"

#include <algorithm>
#include <cmath>

#include "../shaders/interop/probe_update.h"
#include "../shaders/interop/sh_probe.h"
#include "field_shared_sampling.h"

namespace pc {

using namespace pc::gpu;

namespace {

Atlas makeAtlas(int tileSize, int tileRows, int channels) {
  Atlas a;
  a.width = PC_ATLAS_TILES_PER_ROW * tileSize;
  a.height = tileRows * tileSize;
  a.channels = channels;
  a.texels.assign(std::size_t(a.width) * a.height * channels, 0.0f);
  return a;
}

// Bilinear sample of a bordered tile at continuous tile coordinate `tc` (texel centres at
// k + 0.5). The border guarantees all four texels lie inside the tile.
template <int C>
void bilinear(const Atlas& atlas, ivec2 origin, vec2 tc, int tileSize, float* out) {
  // tc lies in [1, tileSize - 1], so fx and fy are positive and truncation is floor.
  float fx = tc.x - 0.5f, fy = tc.y - 0.5f;
  int x0 = std::clamp(int(fx), 0, tileSize - 2);
  int y0 = std::clamp(int(fy), 0, tileSize - 2);
  float ax = std::clamp(fx - float(x0), 0.0f, 1.0f), ay = std::clamp(fy - float(y0), 0.0f, 1.0f);
  const float* t00 = atlas.at(origin.x + x0, origin.y + y0);
  const float* t10 = atlas.at(origin.x + x0 + 1, origin.y + y0);
  const float* t01 = atlas.at(origin.x + x0, origin.y + y0 + 1);
  const float* t11 = atlas.at(origin.x + x0 + 1, origin.y + y0 + 1);
  for (int c = 0; c < C; ++c) {
    float top = t00[c] + (t10[c] - t00[c]) * ax;
    float bottom = t01[c] + (t11[c] - t01[c]) * ax;
    out[c] = top + (bottom - top) * ay;
  }
}

void fixTileBorder(Atlas& atlas, ivec2 origin, int n) {
  const int size = n + 2;
  for (int by = 0; by < size; ++by) {
    for (int bx = 0; bx < size; ++bx) {
      if (bx != 0 && by != 0 && bx != size - 1 && by != size - 1) continue;
      ivec2 src = pcBorderSource(bx, by, n);
      const float* s = atlas.at(origin.x + 1 + src.x, origin.y + 1 + src.y);
      float* d = atlas.at(origin.x + bx, origin.y + by);
      std::copy(s, s + atlas.channels, d);
    }
  }
}

}  // namespace

Field Field::create(const std::vector<ProbeVolume>& volumes, const FieldSettings& settings) {
  Field f;
  f.settings = settings;
  f.settings.raysPerProbe = std::clamp(settings.raysPerProbe, kMinRaysPerProbe, kMaxRaysPerProbe);
  const int count = std::min<int>(int(volumes.size()), PC_MAX_CASCADES);
  f.desc.cascadeCount = count;
  f.desc.hysteresis = settings.hysteresis;
  f.desc.distanceExponent = settings.distanceExponent;
  float finest = count > 0 ? volumes[0].spacing : 1.0f;
  f.desc.occlusionDistance = settings.occlusionDistance * finest;
  int slots = 0, rows = 0;
  for (int k = 0; k < count; ++k) {
    const ProbeVolume& v = volumes[k];
    CascadeDesc& c = f.desc.cascades[k];
    c.origin = v.origin;
    c.spacing = v.spacing;
    c.counts = max(v.counts, ivec3(1));
    c.firstProbe = slots;
    c.scroll = ivec3(0);
    c.atlasTileRow = rows;
    // A volume's own settings (its sidecar entry) stand in for the field's.
    const VolumeSettings& own = v.settings;
    c.hysteresis = own.hysteresis.value_or(settings.hysteresis);
    c.normalBias = own.normalBias.value_or(settings.normalBias) * v.spacing;
    c.viewBias = own.viewBias.value_or(settings.viewBias) * v.spacing;
    // A probe's depth only matters out to the far corner of the cages it belongs to.
    const float maxRay = own.maxRayDistance.value_or(settings.maxRayDistance);
    c.maxRayDistance = maxRay > 0.0f ? maxRay : 1.5f * std::sqrt(3.0f) * v.spacing;
    c.blendMargin = own.blendMargin.value_or(settings.blendMargin) * v.spacing;
    c.encoding = int(own.encoding.value_or(settings.encoding));
    c.follows = own.follow.value_or(settings.followViewers) ? 1 : 0;
    int n = pcSlotCount(c);
    slots += n;
    rows += pcAtlasTileRows(n);
  }
  f.desc.probeCount = slots;
  f.desc.atlasTileRows = rows;
  f.irradiance = makeAtlas(PC_IRRADIANCE_TEXELS + 2, rows, 3);
  f.depth = makeAtlas(PC_DEPTH_TEXELS + 2, rows, 2);
  f.occlusion = makeAtlas(PC_OCCLUSION_TEXELS + 2, rows, 1);
  f.probes.assign(slots, ProbeRecord{});
  for (int k = 0; k < count; ++k) {
    if (pcEncodingIsSh(f.desc.cascades[k].encoding)) f.sh.assign(slots, ShCoefficients{});
  }
  f.brickVersions.resize(count);
  for (int k = 0; k < count; ++k) f.brickVersions[k].assign(pcBrickCount(f.desc.cascades[k]), 0);
  return f;
}

bool sameLayout(const gpu::FieldDesc& a, const gpu::FieldDesc& b) {
  if (a.cascadeCount != b.cascadeCount || a.probeCount != b.probeCount ||
      a.atlasTileRows != b.atlasTileRows)
    return false;
  for (int k = 0; k < a.cascadeCount; ++k) {
    const gpu::CascadeDesc &x = a.cascades[k], &y = b.cascades[k];
    if (x.counts != y.counts || x.firstProbe != y.firstProbe || x.atlasTileRow != y.atlasTileRow ||
        x.origin != y.origin || x.spacing != y.spacing || x.scroll != y.scroll)
      return false;
  }
  return true;
}

int Field::probeCount() const {
  int n = 0;
  for (int k = 0; k < desc.cascadeCount; ++k) {
    ivec3 c = desc.cascades[k].counts;
    n += c.x * c.y * c.z;
  }
  return n;
}

glm::vec3 Field::probePosition(int k, int slot) const {
  const CascadeDesc& c = desc.cascades[k];
  ivec3 logical = pcLogicalCoord(c, pcSlotCoord(c, slot));
  return pcProbeGridPosition(c, logical) + probe(k, slot).offset;
}

void Field::fixBorders(int k, int slot) {
  const CascadeDesc& c = desc.cascades[k];
  fixTileBorder(irradiance, pcAtlasTileOrigin(c, slot, PC_IRRADIANCE_TEXELS + 2),
                PC_IRRADIANCE_TEXELS);
  fixTileBorder(depth, pcAtlasTileOrigin(c, slot, PC_DEPTH_TEXELS + 2), PC_DEPTH_TEXELS);
  fixTileBorder(occlusion, pcAtlasTileOrigin(c, slot, PC_OCCLUSION_TEXELS + 2),
                PC_OCCLUSION_TEXELS);
}

glm::vec4 sampleField(const Field& field, glm::vec3 P, glm::vec3 N, glm::vec3 V, int flags,
                      float* coverage) {
  float cov = 0.0f;
  vec4 r = pcSampleField(field, field.desc, P, N, V, flags, cov);
  if (coverage) *coverage = cov;
  return r;
}

glm::vec4 sampleFieldOrAmbient(const Field& field, glm::vec3 P, glm::vec3 N, glm::vec3 Ns,
                               glm::vec3 V, int flags, glm::vec3 ambient) {
  return pcSampleFieldOrAmbient(field, field.desc, P, N, Ns, V, flags, ambient);
}

glm::vec4 sampleFieldOrAmbientLit(const Field& field, glm::vec3 P, glm::vec3 N, glm::vec3 Ns,
                                  glm::vec3 V, int flags, glm::vec3 ambient, glm::vec3 R,
                                  float roughness, glm::vec3& specular) {
  return pcSampleFieldOrAmbientLit(field, field.desc, P, N, Ns, V, flags | PC_SAMPLE_SPECULAR,
                                   ambient, R, pcGgxSpecularZh(roughness), specular);
}

glm::vec3 fetchIrradiance(const Field& field, int cascade, int slot, glm::vec3 dir) {
  return pcDecodeIrradiance(pcFetchIrradiance(field, cascade, slot, dir));
}
glm::vec2 fetchDepth(const Field& field, int cascade, int slot, glm::vec3 dir) {
  return pcFetchDepth(field, cascade, slot, dir);
}

static_assert(int(ProbeEncoding::Octahedral) == PC_ENCODING_OCTAHEDRAL &&
                  int(ProbeEncoding::Sh1) == PC_ENCODING_SH1 &&
                  int(ProbeEncoding::Sh2) == PC_ENCODING_SH2,
              "ProbeEncoding mirrors the shared PC_ENCODING_* constants");

ShCoefficients projectSh(std::span<const glm::vec3> dirs, std::span<const glm::vec3> radiance,
                         int count) {
  ShCoefficients c{};
  const std::size_t n = std::min(dirs.size(), radiance.size());
  if (n == 0) return c;
  count = std::clamp(count, 0, PC_SH_MAX_COEFFICIENTS);
  for (std::size_t r = 0; r < n; ++r) {
    for (int i = 0; i < count; ++i) c[i] += pcShBasis(i, dirs[r]) * radiance[r];
  }
  const float scale = 4.0f * PC_PI / float(n);
  for (glm::vec3& v : c) v *= scale;
  return c;
}

glm::vec3 shIrradiance(const ShCoefficients& c, int count, glm::vec3 dir) {
  glm::vec3 e(0.0f);
  count = std::clamp(count, 0, PC_SH_MAX_COEFFICIENTS);
  for (int i = 0; i < count; ++i) e += pcShCosineLobe(i) * pcShBasis(i, dir) * c[i];
  return glm::max(e, glm::vec3(0.0f));
}

float deriveShTile(Field& field, int k, int slot) {
  constexpr int n = PC_IRRADIANCE_TEXELS;
  const CascadeDesc& c = field.cascade(k);
  const int count = pcShCoefficientCount(c.encoding);
  const ShCoefficients& coefficients = field.shProbe(k, slot);
  const ivec2 origin = pcAtlasTileOrigin(c, slot, n + 2);
  float maxChange = 0.0f;
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      const vec3 e =
          pcEncodeIrradiance(shIrradiance(coefficients, count, pcTexelDirection(x, y, n)));
      float* texel = field.irradiance.at(origin.x + 1 + x, origin.y + 1 + y);
      const vec3 delta = glm::abs(e - vec3(texel[0], texel[1], texel[2]));
      maxChange = std::max(maxChange, std::max(delta.x, std::max(delta.y, delta.z)));
      texel[0] = e.x, texel[1] = e.y, texel[2] = e.z;
    }
  }
  fixTileBorder(field.irradiance, origin, n);
  return maxChange;
}

void roundShToHalf(Field& field) {
  for (ShCoefficients& probe : field.sh) {
    for (glm::vec3& v : probe) {
      for (int ch = 0; ch < 3; ++ch) v[ch] = glm::unpackHalf1x16(glm::packHalf1x16(v[ch]));
    }
  }
}

int irradianceBytesPerProbe(ProbeEncoding encoding) {
  const int halves = pcShStoredHalves(int(encoding));
  return halves > 0 ? 2 * halves : 2 * 3 * PC_IRRADIANCE_TEXELS * PC_IRRADIANCE_TEXELS;
}

}  // namespace pc

namespace pc::gpu {

namespace {
// The irradiance and occlusion fetches of one cage all look up the surface normal: remember
// the last direction's tile coordinate instead of encoding it eight times.
template <int N>
vec2 cachedTileCoord(vec3 dir) {
  thread_local vec3 lastDir(0.0f);
  thread_local vec2 lastCoord = pcTileCoord(vec3(0.0f, 0.0f, 1.0f), N);
  if (dir != lastDir) {
    lastDir = dir;
    lastCoord = pcTileCoord(dir, N);
  }
  return lastCoord;
}
}  // namespace

vec3 pcFetchIrradiance(const pc::Field& field, int cascade, int slot, vec3 dir) {
  constexpr int n = PC_IRRADIANCE_TEXELS;
  // An SH probe answers from its coefficients: exact in direction, no tile between.
  const int encoding = field.encoding(cascade);
  if (pcEncodingIsSh(encoding)) {
    return pcEncodeIrradiance(
        pc::shIrradiance(field.shProbe(cascade, slot), pcShCoefficientCount(encoding), dir));
  }
  vec3 out;
  pc::bilinear<3>(field.irradiance, pcAtlasTileOrigin(field.desc.cascades[cascade], slot, n + 2),
                  cachedTileCoord<n>(dir), n + 2, &out.x);
  return out;
}

vec2 pcFetchDepth(const pc::Field& field, int cascade, int slot, vec3 dir) {
  constexpr int n = PC_DEPTH_TEXELS;
  vec2 out;
  pc::bilinear<2>(field.depth, pcAtlasTileOrigin(field.desc.cascades[cascade], slot, n + 2),
                  pcTileCoord(dir, n), n + 2, &out.x);
  return out;
}

float pcFetchOcclusion(const pc::Field& field, int cascade, int slot, vec3 dir) {
  constexpr int n = PC_OCCLUSION_TEXELS;
  float out;
  pc::bilinear<1>(field.occlusion, pcAtlasTileOrigin(field.desc.cascades[cascade], slot, n + 2),
                  pcTileCoord(dir, n), n + 2, &out);  // rarely needed: no cache
  return out;
}

vec4 pcFetchProbe(const pc::Field& field, int cascade, int slot) {
  const pc::ProbeRecord& p = field.probe(cascade, slot);
  return vec4(p.offset, float(p.state));
}

}  // namespace pc::gpu
