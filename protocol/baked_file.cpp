// Baked field files: pc::Field <-> size-prefixed flatbuffer (baked_field.fbs), with the checks
// that keep a corrupt or hostile file from crashing a client or producing an unusable field.
#include "baked_file.h"

#include <flatbuffers/flatbuffers.h>
#include <unistd.h>
#include <zstd.h>

#include <bit>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <glm/gtc/packing.hpp>
#include <memory>
#include <string>
#include <system_error>

#include "common/temp_file.h"
#include "protocol/baked_field_generated.h"
#include "protocol/crc64.h"
#include "shaders/interop/sh_probe.h"

namespace pc {

namespace {

using namespace pc::gpu;

// Bounds that keep every count inside int arithmetic (the shared layout functions use int)
// long before the atlas byte cap applies.
constexpr int kMaxProbesPerAxis = 1024;
constexpr std::int64_t kMaxSlots = std::int64_t(1) << 28;
constexpr int kMaxScroll = 1 << 24;

// Verifier limits: the schema nests 3 deep and a valid file holds 6 + cascade count tables;
// the margins leave room for fields a later minor change may add.
constexpr flatbuffers::uoffset_t kMaxDepth = 16;
constexpr flatbuffers::uoffset_t kMaxTables = 64;

static_assert(std::endian::native == std::endian::little,
              "baked files store little-endian values; add byte swapping for big-endian hosts");
static_assert(kMaxBakedFileBytes < FLATBUFFERS_MAX_BUFFER_SIZE);

std::string hex(std::uint64_t v) {
  char buf[24];
  std::snprintf(buf, sizeof buf, "0x%016llx", static_cast<unsigned long long>(v));
  return buf;
}

bool finite(glm::vec3 v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

struct AtlasSpec {
  const char* name;
  int texels;  // interior texels per tile side
  int channels;
};
constexpr AtlasSpec kIrradiance{"irradiance", PC_IRRADIANCE_TEXELS, 3};
constexpr AtlasSpec kDepth{"depth", PC_DEPTH_TEXELS, 2};
constexpr AtlasSpec kOcclusion{"occlusion", PC_OCCLUSION_TEXELS, 1};

// Slot and tile-row totals of a set of cascades, from the shared layout functions.
struct LayoutTotals {
  std::int64_t slots = 0;
  std::int64_t rows = 0;
};

// Checks one cascade's description and its place in the layout; on success adds it to `t`.
Status checkCascade(const CascadeDesc& c, int k, LayoutTotals& t) {
  auto bad = [&](const std::string& what) {
    return Error{"cascade " + std::to_string(k) + ": " + what};
  };
  const ivec3 n = c.counts;
  if (n.x < 1 || n.y < 1 || n.z < 1 || n.x > kMaxProbesPerAxis || n.y > kMaxProbesPerAxis ||
      n.z > kMaxProbesPerAxis) {
    return bad("probe counts " + std::to_string(n.x) + "x" + std::to_string(n.y) + "x" +
               std::to_string(n.z) + " out of range 1.." + std::to_string(kMaxProbesPerAxis));
  }
  const int slots = pcSlotCount(c);  // <= 1024^3: fits in int
  if (t.slots + slots > kMaxSlots) return bad("too many probe slots");
  if (c.firstProbe != t.slots) {
    return bad("first probe " + std::to_string(c.firstProbe) + ", layout gives " +
               std::to_string(t.slots));
  }
  if (c.atlasTileRow != t.rows) {
    return bad("atlas tile row " + std::to_string(c.atlasTileRow) + ", layout gives " +
               std::to_string(t.rows));
  }
  if (!finite(c.origin) || !std::isfinite(c.spacing) || !(c.spacing > 0.0f)) {
    return bad("origin or spacing not finite / positive");
  }
  for (float v : {c.normalBias, c.viewBias, c.maxRayDistance, c.blendMargin}) {
    if (!std::isfinite(v) || v < 0.0f) return bad("bias, ray distance or blend margin invalid");
  }
  if (std::abs(c.scroll.x) > kMaxScroll || std::abs(c.scroll.y) > kMaxScroll ||
      std::abs(c.scroll.z) > kMaxScroll) {
    return bad("scroll out of range");
  }
  t.slots += slots;
  t.rows += pcAtlasTileRows(slots);
  return Status::success();
}

Status checkAtlas(const Atlas& a, const AtlasSpec& spec, std::int64_t rows) {
  const int tile = spec.texels + 2;
  const std::int64_t w = std::int64_t(PC_ATLAS_TILES_PER_ROW) * tile, h = rows * tile;
  if (a.width != w || a.height != h || a.channels != spec.channels ||
      a.texels.size() != std::size_t(w) * std::size_t(h) * std::size_t(spec.channels)) {
    return Error{std::string(spec.name) + " atlas is " + std::to_string(a.width) + "x" +
                 std::to_string(a.height) + "x" + std::to_string(a.channels) + " (" +
                 std::to_string(a.texels.size()) + " values), layout gives " + std::to_string(w) +
                 "x" + std::to_string(h) + "x" + std::to_string(spec.channels)};
  }
  for (std::size_t i = 0; i < a.texels.size(); ++i) {
    if (!std::isfinite(a.texels[i])) {
      return Error{std::string(spec.name) + " atlas value " + std::to_string(i) + " not finite"};
    }
  }
  return Status::success();
}

// ---- atlas blobs ---------------------------------------------------------------------------

// Values -> little-endian bytes in the chosen encoding. Fails only on float16 overflow.
Result<std::vector<std::uint8_t>> encodeValues(const std::vector<float>& v, wire::Encoding enc,
                                               const char* name) {
  std::vector<std::uint8_t> out;
  if (enc == wire::Encoding::Float32) {
    out.resize(v.size() * 4);
    std::memcpy(out.data(), v.data(), out.size());
    return out;
  }
  out.resize(v.size() * 2);
  for (std::size_t i = 0; i < v.size(); ++i) {
    std::uint16_t h = glm::packHalf1x16(v[i]);
    if ((h & 0x7c00u) == 0x7c00u) {
      return Error{std::string(name) + " atlas value " + std::to_string(v[i]) +
                   " does not fit float16; write with full precision"};
    }
    std::memcpy(&out[2 * i], &h, 2);
  }
  return out;
}

// Byte planes: the exponent bytes of neighbouring texels are alike, so grouping each byte
// position together lets zstd find far more repetition than in interleaved floats.
std::vector<std::uint8_t> shuffle(const std::vector<std::uint8_t>& in, std::size_t width) {
  std::vector<std::uint8_t> out(in.size());
  const std::size_t n = in.size() / width;
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t b = 0; b < width; ++b) out[b * n + i] = in[i * width + b];
  }
  return out;
}
std::vector<std::uint8_t> unshuffle(const std::vector<std::uint8_t>& in, std::size_t width) {
  std::vector<std::uint8_t> out(in.size());
  const std::size_t n = in.size() / width;
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t b = 0; b < width; ++b) out[i * width + b] = in[b * n + i];
  }
  return out;
}

struct ZstdCCtxFree {
  void operator()(ZSTD_CCtx* c) const { ZSTD_freeCCtx(c); }
};

struct EncodedAtlas {
  wire::Encoding encoding;
  wire::Compression compression;
  std::vector<std::uint8_t> data;
};

Result<EncodedAtlas> encodeAtlas(const Atlas& a, const char* name, bool half, int zstdLevel) {
  EncodedAtlas e;
  e.encoding = half ? wire::Encoding::Float16 : wire::Encoding::Float32;
  auto raw = encodeValues(a.texels, e.encoding, name);
  if (!raw) return raw.error();
  if (zstdLevel <= 0 || raw->empty()) {
    e.compression = wire::Compression::None;
    e.data = std::move(raw.value());
    return e;
  }
  e.compression = wire::Compression::ZstdShuffled;
  std::vector<std::uint8_t> planes = shuffle(*raw, half ? 2 : 4);
  std::unique_ptr<ZSTD_CCtx, ZstdCCtxFree> cctx(ZSTD_createCCtx());
  if (!cctx) return Error{std::string(name) + " atlas: out of memory for zstd"};
  // The frame records its content size (checked before decoding) and a checksum, so a
  // corrupted atlas is rejected instead of decoding to wrong values.
  ZSTD_CCtx_setParameter(cctx.get(), ZSTD_c_compressionLevel,
                         std::min(zstdLevel, ZSTD_maxCLevel()));
  ZSTD_CCtx_setParameter(cctx.get(), ZSTD_c_checksumFlag, 1);
  e.data.resize(ZSTD_compressBound(planes.size()));
  std::size_t n =
      ZSTD_compress2(cctx.get(), e.data.data(), e.data.size(), planes.data(), planes.size());
  if (ZSTD_isError(n)) {
    return Error{std::string(name) + " atlas: zstd failed: " + ZSTD_getErrorName(n)};
  }
  e.data.resize(n);
  return e;
}

Result<Atlas> decodeAtlas(const wire::Atlas* w, const AtlasSpec& spec, std::int64_t rows,
                          std::uint64_t& budget) {
  auto bad = [&](const std::string& what) {
    return Error{std::string(spec.name) + " atlas: " + what};
  };
  if (!w) return bad("missing");
  const int tile = spec.texels + 2;
  const std::int64_t width = std::int64_t(PC_ATLAS_TILES_PER_ROW) * tile, height = rows * tile;
  if (w->width() != width || w->height() != height || w->channels() != spec.channels) {
    return bad("size " + std::to_string(w->width()) + "x" + std::to_string(w->height()) + "x" +
               std::to_string(w->channels()) + ", layout gives " + std::to_string(width) + "x" +
               std::to_string(height) + "x" + std::to_string(spec.channels));
  }
  std::size_t valueBytes;
  switch (w->encoding()) {
    case wire::Encoding::Float32:
      valueBytes = 4;
      break;
    case wire::Encoding::Float16:
      valueBytes = 2;
      break;
    default:
      return bad("unknown encoding " + std::to_string(int(w->encoding())));
  }
  const std::uint64_t count = std::uint64_t(width) * std::uint64_t(height) * spec.channels;
  if (count * 4 > budget) return bad("decoded atlases exceed the size limit");
  budget -= count * 4;
  const std::size_t rawSize = std::size_t(count) * valueBytes;
  const flatbuffers::Vector<std::uint8_t>* blob = w->data();
  const std::size_t blobSize = blob ? blob->size() : 0;

  std::vector<std::uint8_t> raw;
  switch (w->compression()) {
    case wire::Compression::None:
      if (blobSize != rawSize) {
        return bad(std::to_string(blobSize) + " bytes, expected " + std::to_string(rawSize));
      }
      if (rawSize) raw.assign(blob->data(), blob->data() + blobSize);
      break;
    case wire::Compression::ZstdShuffled: {
      if (rawSize == 0) return bad("compressed data for an empty atlas");
      if (blobSize == 0) return bad("no data");
      unsigned long long content = ZSTD_getFrameContentSize(blob->data(), blobSize);
      if (content != rawSize) {
        return bad("zstd frame holds " +
                   (content == ZSTD_CONTENTSIZE_ERROR || content == ZSTD_CONTENTSIZE_UNKNOWN
                        ? std::string("an unknown size")
                        : std::to_string(content) + " bytes") +
                   ", expected " + std::to_string(rawSize));
      }
      std::vector<std::uint8_t> planes(rawSize);
      std::size_t n = ZSTD_decompress(planes.data(), planes.size(), blob->data(), blobSize);
      if (ZSTD_isError(n)) return bad(std::string("zstd: ") + ZSTD_getErrorName(n));
      if (n != rawSize) return bad("zstd data decodes to " + std::to_string(n) + " bytes");
      raw = unshuffle(planes, valueBytes);
      break;
    }
    default:
      return bad("unknown compression " + std::to_string(int(w->compression())));
  }

  Atlas a;
  a.width = int(width);
  a.height = int(height);
  a.channels = spec.channels;
  a.texels.resize(std::size_t(count));
  if (valueBytes == 4) {
    if (count) std::memcpy(a.texels.data(), raw.data(), rawSize);
  } else {
    for (std::size_t i = 0; i < a.texels.size(); ++i) {
      std::uint16_t h;
      std::memcpy(&h, &raw[2 * i], 2);
      a.texels[i] = glm::unpackHalf1x16(h);
    }
  }
  return a;
}

// ---- whole-file checksum -------------------------------------------------------------------

constexpr std::size_t kChecksumBytes = 8;

// The verifier limits for a baked file's buffer.
flatbuffers::Verifier::Options verifierOptions() {
  flatbuffers::Verifier::Options opts;
  opts.max_depth = kMaxDepth;
  opts.max_tables = kMaxTables;
  return opts;
}

// The root table of a size-prefixed buffer, having verified the table's start and its format
// version and checksum fields (not the rest of the buffer); null when those do not verify.
// `data` must be 8-byte aligned (the Verifier checks alignment against the address).
const flatbuffers::Table* verifiedRootStart(const std::uint8_t* data, std::size_t size) {
  flatbuffers::Verifier v(data, size, verifierOptions());
  const flatbuffers::uoffset_t o = v.VerifyOffset(sizeof(flatbuffers::uoffset_t));
  if (o == 0) return nullptr;
  const auto* table = reinterpret_cast<const flatbuffers::Table*>(data + 4 + o);
  if (!table->VerifyTableStart(v) ||
      !table->VerifyField<std::uint32_t>(v, wire::BakedField::VT_FORMAT_VERSION, 4) ||
      !table->VerifyField<std::uint64_t>(v, wire::BakedField::VT_CHECKSUM, 8))
    return nullptr;
  return table;
}

// The checksum's byte offset in the buffer, or 0 when the root table has no checksum field.
std::size_t checksumOffset(const std::uint8_t* data, const flatbuffers::Table* root) {
  const std::uint8_t* at = root->GetAddressOf(wire::BakedField::VT_CHECKSUM);
  return at ? std::size_t(at - data) : 0;
}

// CRC-64 of the whole buffer with the checksum's own bytes taken as zero.
std::uint64_t fileChecksum(std::span<const std::uint8_t> bytes, std::size_t at) {
  const std::uint8_t zeros[kChecksumBytes] = {};
  std::uint64_t crc = crc64(bytes.first(at));
  crc = crc64(zeros, crc);
  return crc64(bytes.subspan(at + kChecksumBytes), crc);
}

std::uint64_t readU64(const std::uint8_t* p) {
  std::uint64_t v;
  std::memcpy(&v, p, sizeof v);
  return flatbuffers::EndianScalar(v);
}

// ---- files ---------------------------------------------------------------------------------

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};
using FilePtr = std::unique_ptr<std::FILE, FileCloser>;

}  // namespace

// SH cascades (PC_ENCODING_SH1/SH2): a known encoding per cascade, coefficients for every
// slot when any cascade is SH, finite, and within float16's range (files store halves).
Status checkSh(const Field& f) {
  bool any = false;
  for (int k = 0; k < f.desc.cascadeCount; ++k) {
    const int e = f.desc.cascades[k].encoding;
    if (e < PC_ENCODING_OCTAHEDRAL || e > PC_ENCODING_SH2)
      return Error{"cascade " + std::to_string(k) + ": unknown irradiance encoding " +
                   std::to_string(e) + " (0 octahedral, 1 sh1, 2 sh2)"};
    any = any || pcEncodingIsSh(e);
  }
  if (!any) return Status::success();
  if (f.sh.size() != std::size_t(f.desc.probeCount)) {
    return Error{std::to_string(f.sh.size()) + " SH probes, layout gives " +
                 std::to_string(f.desc.probeCount)};
  }
  for (int k = 0; k < f.desc.cascadeCount; ++k) {
    const CascadeDesc& c = f.desc.cascades[k];
    const int count = pcShCoefficientCount(c.encoding);
    for (int slot = 0; slot < pcSlotCount(c) && count > 0; ++slot) {
      const ShCoefficients& p = f.shProbe(k, slot);
      for (int i = 0; i < count; ++i) {
        if (!finite(p[i]) || glm::any(glm::greaterThan(glm::abs(p[i]), glm::vec3(65504.0f))))
          return Error{"cascade " + std::to_string(k) + " probe " + std::to_string(slot) +
                       ": SH coefficient not finite or beyond float16's range"};
      }
    }
  }
  return Status::success();
}

// One SH cascade's coefficients as the file stores them (baked_field.fbs, sh_coefficients).
std::vector<std::uint16_t> packSh(const Field& f, int k) {
  const CascadeDesc& c = f.desc.cascades[k];
  const int count = pcShCoefficientCount(c.encoding), stride = pcShStoredHalves(c.encoding);
  std::vector<std::uint16_t> halves(std::size_t(pcSlotCount(c)) * std::size_t(stride), 0);
  for (int slot = 0; slot < pcSlotCount(c); ++slot) {
    const ShCoefficients& p = f.shProbe(k, slot);
    for (int i = 0; i < count; ++i) {
      for (int ch = 0; ch < 3; ++ch)
        halves[std::size_t(slot) * stride + 3 * i + ch] = glm::packHalf1x16(p[i][ch]);
    }
  }
  return halves;
}

// The inverse of packSh, after checking the count; the padding half is ignored.
Status unpackSh(const flatbuffers::Vector<std::uint16_t>* halves, Field& f, int k) {
  const CascadeDesc& c = f.desc.cascades[k];
  const int count = pcShCoefficientCount(c.encoding), stride = pcShStoredHalves(c.encoding);
  const std::size_t expected = std::size_t(pcSlotCount(c)) * std::size_t(stride);
  const std::size_t got = halves ? halves->size() : 0;
  if (got != expected) {
    return Error{"cascade " + std::to_string(k) + ": " + std::to_string(got) +
                 " SH coefficient halves, layout gives " + std::to_string(expected)};
  }
  for (int slot = 0; slot < pcSlotCount(c); ++slot) {
    ShCoefficients& p = f.shProbe(k, slot);
    for (int i = 0; i < count; ++i) {
      for (int ch = 0; ch < 3; ++ch) {
        const flatbuffers::uoffset_t at = flatbuffers::uoffset_t(slot * stride + 3 * i + ch);
        p[i][ch] = glm::unpackHalf1x16(halves->Get(at));
      }
    }
  }
  return Status::success();
}

Status validateField(const Field& f) {
  const FieldDesc& d = f.desc;
  if (d.cascadeCount < 0 || d.cascadeCount > PC_MAX_CASCADES) {
    return Error{"cascade count " + std::to_string(d.cascadeCount) + " out of range 0.." +
                 std::to_string(PC_MAX_CASCADES)};
  }
  LayoutTotals t;
  for (int k = 0; k < d.cascadeCount; ++k) {
    if (Status s = checkCascade(d.cascades[k], k, t); !s) return s;
  }
  if (d.probeCount != t.slots || d.atlasTileRows != t.rows) {
    return Error{"field holds " + std::to_string(d.probeCount) + " probe slots in " +
                 std::to_string(d.atlasTileRows) + " tile rows, layout gives " +
                 std::to_string(t.slots) + " in " + std::to_string(t.rows)};
  }
  for (float v : {d.hysteresis, d.distanceExponent, d.occlusionDistance}) {
    if (!std::isfinite(v)) return Error{"field parameters not finite"};
  }
  const FieldSettings& s = f.settings;
  if (s.raysPerProbe < kMinRaysPerProbe || s.raysPerProbe > kMaxRaysPerProbe)
    return Error{"rays per probe " + std::to_string(s.raysPerProbe) + " outside " +
                 std::to_string(kMinRaysPerProbe) + ".." + std::to_string(kMaxRaysPerProbe)};
  for (float v : {s.hysteresis, s.distanceExponent, s.normalBias, s.viewBias, s.maxRayDistance,
                  s.occlusionDistance, s.blendMargin}) {
    if (!std::isfinite(v)) return Error{"field settings not finite"};
  }
  if (f.probes.size() != std::size_t(t.slots)) {
    return Error{std::to_string(f.probes.size()) + " probe records, layout gives " +
                 std::to_string(t.slots)};
  }
  for (std::size_t i = 0; i < f.probes.size(); ++i) {
    const ProbeRecord& p = f.probes[i];
    if (!finite(p.offset)) return Error{"probe " + std::to_string(i) + ": offset not finite"};
    if (p.state < PC_PROBE_ACTIVE || p.state > PC_PROBE_UNINITIALIZED) {
      return Error{"probe " + std::to_string(i) + ": invalid state " + std::to_string(p.state)};
    }
  }
  if (f.brickVersions.size() != std::size_t(d.cascadeCount)) {
    return Error{"brick versions for " + std::to_string(f.brickVersions.size()) +
                 " cascades, field has " + std::to_string(d.cascadeCount)};
  }
  for (int k = 0; k < d.cascadeCount; ++k) {
    const std::size_t bricks = std::size_t(pcBrickCount(d.cascades[k]));
    if (f.brickVersions[k].size() != bricks) {
      return Error{"cascade " + std::to_string(k) + ": " +
                   std::to_string(f.brickVersions[k].size()) + " brick versions, layout gives " +
                   std::to_string(bricks)};
    }
  }
  if (Status st = checkAtlas(f.irradiance, kIrradiance, t.rows); !st) return st;
  if (Status st = checkAtlas(f.depth, kDepth, t.rows); !st) return st;
  if (Status st = checkAtlas(f.occlusion, kOcclusion, t.rows); !st) return st;
  return checkSh(f);
}

Result<std::vector<std::uint8_t>> encodeBakedField(const Field& f,
                                                   const BakedWriteOptions& options) {
  if (Status s = validateField(f); !s) return Error{"cannot encode field: " + s.error().message};
  auto irr = encodeAtlas(f.irradiance, kIrradiance.name, options.halfPrecision, options.zstdLevel);
  if (!irr) return irr.error();
  auto dep = encodeAtlas(f.depth, kDepth.name, false, options.zstdLevel);
  if (!dep) return dep.error();
  auto occ = encodeAtlas(f.occlusion, kOcclusion.name, options.halfPrecision, options.zstdLevel);
  if (!occ) return occ.error();
  // The builder cannot grow past 2 GiB; refuse before it would.
  std::uint64_t estimate = irr->data.size() + dep->data.size() + occ->data.size() +
                           f.probes.size() * sizeof(wire::Probe) + 65536;
  for (const auto& b : f.brickVersions) estimate += b.size() * 8;
  estimate += f.sh.size() * std::size_t(2 * PC_SH2_STORED_HALVES);
  if (estimate > kMaxBakedFileBytes) {
    return Error{"cannot encode field: about " + std::to_string(estimate) +
                 " bytes, over the baked file limit of " + std::to_string(kMaxBakedFileBytes)};
  }

  flatbuffers::FlatBufferBuilder fbb(static_cast<std::size_t>(estimate));
  auto atlas = [&](const Atlas& a, const EncodedAtlas& e) {
    auto data = fbb.CreateVector(e.data.data(), e.data.size());
    return wire::CreateAtlas(fbb, a.width, a.height, a.channels, e.encoding, e.compression, data);
  };
  auto irrOff = atlas(f.irradiance, *irr);
  auto depOff = atlas(f.depth, *dep);
  auto occOff = atlas(f.occlusion, *occ);

  std::vector<wire::Probe> probes;
  probes.reserve(f.probes.size());
  for (const ProbeRecord& p : f.probes) {
    probes.emplace_back(wire::Vec3(p.offset.x, p.offset.y, p.offset.z), p.state, p.updates);
  }
  auto probesOff = fbb.CreateVectorOfStructs(probes);

  std::vector<flatbuffers::Offset<wire::Cascade>> cascades;
  for (int k = 0; k < f.desc.cascadeCount; ++k) {
    const CascadeDesc& c = f.desc.cascades[k];
    auto bricks = fbb.CreateVector(f.brickVersions[k]);
    wire::Vec3 origin(c.origin.x, c.origin.y, c.origin.z);
    wire::Int3 counts(c.counts.x, c.counts.y, c.counts.z);
    wire::Int3 scroll(c.scroll.x, c.scroll.y, c.scroll.z);
    flatbuffers::Offset<flatbuffers::Vector<std::uint16_t>> sh;
    if (pcEncodingIsSh(c.encoding)) sh = fbb.CreateVector(packSh(f, k));
    cascades.push_back(wire::CreateCascade(fbb, &origin, c.spacing, &counts, c.firstProbe, &scroll,
                                           c.atlasTileRow, c.normalBias, c.viewBias,
                                           c.maxRayDistance, c.blendMargin, bricks, c.hysteresis,
                                           std::uint8_t(c.encoding), sh));
  }
  auto cascadesOff = fbb.CreateVector(cascades);

  const FieldSettings& s = f.settings;
  auto settings =
      wire::CreateSettings(fbb, s.raysPerProbe, s.hysteresis, s.distanceExponent, s.normalBias,
                           s.viewBias, s.maxRayDistance, s.occlusionDistance, s.blendMargin);
  auto layout = wire::CreateLayout(fbb, PC_IRRADIANCE_TEXELS, PC_DEPTH_TEXELS, PC_OCCLUSION_TEXELS,
                                   PC_BRICK_SIZE, PC_ATLAS_TILES_PER_ROW, PC_MAX_CASCADES);
  // The checksum is written as a placeholder (a non-default value, so the field is stored)
  // and filled in once the buffer is whole.
  auto root = wire::CreateBakedField(
      fbb, kBakedFormatVersion, f.sceneHash, f.version, layout, settings, f.desc.probeCount,
      f.desc.hysteresis, f.desc.distanceExponent, f.desc.occlusionDistance, f.desc.atlasTileRows,
      cascadesOff, probesOff, irrOff, depOff, occOff, ~std::uint64_t(0));
  // Size-prefixed: a reader tells a truncated file from a corrupt one by the announced size.
  wire::FinishSizePrefixedBakedFieldBuffer(fbb, root);
  std::vector<std::uint8_t> bytes(fbb.GetBufferPointer(), fbb.GetBufferPointer() + fbb.GetSize());
  if (!sealBakedChecksum(bytes)) return Error{"cannot encode field: no checksum field to fill"};
  return bytes;
}

bool sealBakedChecksum(std::span<std::uint8_t> bytes) {
  if (bytes.size() < 12) return false;
  // The Verifier checks alignment against the address: work on an aligned copy if need be.
  std::vector<std::uint8_t> aligned;
  const std::uint8_t* data = bytes.data();
  if (reinterpret_cast<std::uintptr_t>(data) % 8 != 0) {
    aligned.assign(bytes.begin(), bytes.end());
    data = aligned.data();
  }
  const flatbuffers::Table* root = verifiedRootStart(data, bytes.size());
  const std::size_t at = root ? checksumOffset(data, root) : 0;
  if (at == 0) return false;
  std::memset(bytes.data() + at, 0, kChecksumBytes);
  const std::uint64_t crc = flatbuffers::EndianScalar(fileChecksum(bytes, at));
  std::memcpy(bytes.data() + at, &crc, kChecksumBytes);
  return true;
}

Result<Field> decodeBakedField(std::span<const std::uint8_t> bytes, std::uint64_t expectedSceneHash,
                               std::string_view name) {
  const std::string prefix = "baked file " + std::string(name) + ": ";
  auto fail = [&](const std::string& what) { return Error{prefix + what}; };
  const std::size_t size = bytes.size();
  constexpr std::size_t kHeader = 12;  // size prefix, root offset, identifier

  if (size > kMaxBakedFileBytes) {
    return fail("too large (" + std::to_string(size) + " bytes, limit " +
                std::to_string(kMaxBakedFileBytes) + ")");
  }
  if (size < kHeader) return fail("truncated (" + std::to_string(size) + " bytes)");
  if (!flatbuffers::BufferHasIdentifier(bytes.data(), wire::BakedFieldIdentifier(), true)) {
    std::string id;
    for (std::size_t i = 8; i < 12; ++i) {
      char c = char(bytes[i]);
      id += std::isprint(static_cast<unsigned char>(c)) ? std::string(1, c) : std::string("?");
    }
    return fail("not a baked field file (identifier '" + id + "', expected '" +
                wire::BakedFieldIdentifier() + "')");
  }
  const std::uint64_t announced =
      std::uint64_t(flatbuffers::ReadScalar<flatbuffers::uoffset_t>(bytes.data())) + 4;
  if (announced > size) {
    return fail("truncated (" + std::to_string(size) + " bytes, header announces " +
                std::to_string(announced) + ")");
  }
  if (announced < size) {
    return fail(std::to_string(size - announced) + " unexpected bytes after the field (" +
                std::to_string(size) + " bytes, header announces " + std::to_string(announced) +
                ")");
  }

  // The Verifier checks alignment against the address; callers may hand in any span.
  std::vector<std::uint8_t> aligned;
  const std::uint8_t* data = bytes.data();
  if (reinterpret_cast<std::uintptr_t>(data) % 8 != 0) {
    aligned.assign(bytes.begin(), bytes.end());
    data = aligned.data();
  }
  // The format version first, verified on its own, so a file from a newer or older writer is
  // reported as such rather than as corrupt.
  {
    const flatbuffers::Table* table = verifiedRootStart(data, size);
    if (!table) return fail("corrupt (bad root table)");
    const auto version = table->GetField<std::uint32_t>(wire::BakedField::VT_FORMAT_VERSION, 0);
    if (version < kBakedMinFormatVersion || version > kBakedFormatVersion) {
      return fail("format version " + std::to_string(version) +
                  " is not supported (this build reads " + std::to_string(kBakedMinFormatVersion) +
                  ".." + std::to_string(kBakedFormatVersion) +
                  (version < kBakedMinFormatVersion ? "; bake the field again" : "") + ")");
    }
    // Then the whole file's checksum, before anything else is read from it: a flipped bit
    // anywhere (in a count, a bias, a probe state, an uncompressed atlas) is caught here, not
    // loaded as a slightly different field.
    const std::size_t at = checksumOffset(data, table);
    if (at == 0)
      return fail("no checksum (format version " + std::to_string(version) +
                  " files carry one): the file is corrupt");
    const std::uint64_t stored = readU64(data + at);
    const std::uint64_t computed = fileChecksum({data, size}, at);
    if (stored != computed) {
      return fail("checksum mismatch (stored " + hex(stored) + ", computed " + hex(computed) +
                  "): the file is corrupt");
    }
  }
  {
    flatbuffers::Verifier v(data, size, verifierOptions());
    if (!wire::VerifySizePrefixedBakedFieldBuffer(v)) {
      return fail("corrupt (flatbuffer verification failed)");
    }
  }
  const wire::BakedField* root = wire::GetSizePrefixedBakedField(data);

  const wire::Layout* layout = root->layout();
  if (!layout) return fail("no layout constants");
  if (layout->irradiance_texels() != PC_IRRADIANCE_TEXELS ||
      layout->depth_texels() != PC_DEPTH_TEXELS ||
      layout->occlusion_texels() != PC_OCCLUSION_TEXELS || layout->brick_size() != PC_BRICK_SIZE ||
      layout->atlas_tiles_per_row() != PC_ATLAS_TILES_PER_ROW) {
    auto str = [](int a, int b, int c, int d, int e) {
      return std::to_string(a) + "/" + std::to_string(b) + "/" + std::to_string(c) + "/" +
             std::to_string(d) + "/" + std::to_string(e);
    };
    return fail(
        "layout constants (irradiance/depth/occlusion texels, brick size, tiles per "
        "row) " +
        str(layout->irradiance_texels(), layout->depth_texels(), layout->occlusion_texels(),
            layout->brick_size(), layout->atlas_tiles_per_row()) +
        " differ from this build's " +
        str(PC_IRRADIANCE_TEXELS, PC_DEPTH_TEXELS, PC_OCCLUSION_TEXELS, PC_BRICK_SIZE,
            PC_ATLAS_TILES_PER_ROW));
  }
  // A reader with fewer cascade slots than the writer only fails if the file uses them: the
  // cascade count check below.

  if (expectedSceneHash != 0 && root->scene_hash() != expectedSceneHash) {
    return fail("scene hash " + hex(root->scene_hash()) + " does not match scene " +
                hex(expectedSceneHash));
  }

  Field f;
  const wire::Settings* ws = root->settings();
  if (!ws) return fail("no field settings");
  f.settings.raysPerProbe = ws->rays_per_probe();
  f.settings.hysteresis = ws->hysteresis();
  f.settings.distanceExponent = ws->distance_exponent();
  f.settings.normalBias = ws->normal_bias();
  f.settings.viewBias = ws->view_bias();
  f.settings.maxRayDistance = ws->max_ray_distance();
  f.settings.occlusionDistance = ws->occlusion_distance();
  f.settings.blendMargin = ws->blend_margin();

  const auto* cascades = root->cascades();
  const std::size_t cascadeCount = cascades ? cascades->size() : 0;
  if (cascadeCount > std::size_t(PC_MAX_CASCADES)) {
    return fail(std::to_string(cascadeCount) + " cascades, at most " +
                std::to_string(PC_MAX_CASCADES) + " supported");
  }
  f.desc.cascadeCount = int(cascadeCount);
  f.desc.hysteresis = root->hysteresis();
  f.desc.distanceExponent = root->distance_exponent();
  f.desc.occlusionDistance = root->occlusion_distance();
  f.brickVersions.resize(cascadeCount);
  LayoutTotals t;
  for (std::size_t k = 0; k < cascadeCount; ++k) {
    const wire::Cascade* wc = cascades->Get(flatbuffers::uoffset_t(k));
    if (!wc->origin() || !wc->counts() || !wc->scroll()) {
      return fail("cascade " + std::to_string(k) + ": missing origin, counts or scroll");
    }
    CascadeDesc& c = f.desc.cascades[k];
    c.origin = vec3(wc->origin()->x(), wc->origin()->y(), wc->origin()->z());
    c.spacing = wc->spacing();
    c.counts = ivec3(wc->counts()->x(), wc->counts()->y(), wc->counts()->z());
    c.firstProbe = wc->first_probe();
    c.scroll = ivec3(wc->scroll()->x(), wc->scroll()->y(), wc->scroll()->z());
    c.atlasTileRow = wc->atlas_tile_row();
    c.normalBias = wc->normal_bias();
    c.viewBias = wc->view_bias();
    c.maxRayDistance = wc->max_ray_distance();
    c.blendMargin = wc->blend_margin();
    c.hysteresis = wc->hysteresis() < 0.0f ? f.settings.hysteresis : wc->hysteresis();
    if (!(c.hysteresis >= 0.0f && c.hysteresis < 1.0f))
      return fail("cascade " + std::to_string(k) + ": hysteresis " + std::to_string(c.hysteresis) +
                  " outside [0, 1)");
    c.encoding = wc->encoding();
    if (c.encoding > PC_ENCODING_SH2)
      return fail("cascade " + std::to_string(k) + ": unknown irradiance encoding " +
                  std::to_string(c.encoding) + " (0 octahedral, 1 sh1, 2 sh2)");
    if (!pcEncodingIsSh(c.encoding) && wc->sh_coefficients() && wc->sh_coefficients()->size())
      return fail("cascade " + std::to_string(k) + ": SH coefficients in an octahedral cascade");
    // The layout check comes before any allocation sized by these counts.
    if (Status s = checkCascade(c, int(k), t); !s) return fail(s.error().message);
    const auto* bricks = wc->brick_versions();
    const std::size_t brickCount = std::size_t(pcBrickCount(c));
    if (!bricks || bricks->size() != brickCount) {
      return fail("cascade " + std::to_string(k) + ": " +
                  std::to_string(bricks ? bricks->size() : 0) + " brick versions, layout gives " +
                  std::to_string(brickCount));
    }
    // The Verifier checks the vector's length field alignment, not its 8-byte elements': copy
    // each one out rather than reading it in place.
    f.brickVersions[k].resize(brickCount);
    for (std::size_t i = 0; i < brickCount; ++i) {
      std::uint64_t v;
      std::memcpy(&v, bricks->Data() + i * sizeof v, sizeof v);
      f.brickVersions[k][i] = flatbuffers::EndianScalar(v);
    }
  }
  f.desc.probeCount = root->probe_count();
  f.desc.atlasTileRows = root->atlas_tile_rows();
  if (f.desc.probeCount != t.slots || f.desc.atlasTileRows != t.rows) {
    return fail("field holds " + std::to_string(f.desc.probeCount) + " probe slots in " +
                std::to_string(f.desc.atlasTileRows) + " tile rows, cascades give " +
                std::to_string(t.slots) + " in " + std::to_string(t.rows));
  }

  // SH coefficients, now that the slot total (checked above) bounds the allocation.
  for (std::size_t k = 0; k < cascadeCount; ++k) {
    if (!pcEncodingIsSh(f.desc.cascades[k].encoding)) continue;
    if (f.sh.empty()) f.sh.assign(std::size_t(t.slots), ShCoefficients{});
    const wire::Cascade* wc = cascades->Get(flatbuffers::uoffset_t(k));
    if (Status s = unpackSh(wc->sh_coefficients(), f, int(k)); !s) return fail(s.error().message);
  }

  const auto* probes = root->probes();
  const std::size_t probeCount = probes ? probes->size() : 0;
  if (probeCount != std::size_t(t.slots)) {
    return fail(std::to_string(probeCount) + " probe records, layout gives " +
                std::to_string(t.slots));
  }
  f.probes.resize(probeCount);
  for (std::size_t i = 0; i < probeCount; ++i) {
    const wire::Probe* p = probes->Get(flatbuffers::uoffset_t(i));
    f.probes[i].offset = vec3(p->offset().x(), p->offset().y(), p->offset().z());
    f.probes[i].state = p->state();
    f.probes[i].updates = p->updates();
  }

  std::uint64_t budget = kMaxBakedAtlasBytes;
  auto irr = decodeAtlas(root->irradiance(), kIrradiance, t.rows, budget);
  if (!irr) return fail(irr.error().message);
  auto dep = decodeAtlas(root->depth(), kDepth, t.rows, budget);
  if (!dep) return fail(dep.error().message);
  auto occ = decodeAtlas(root->occlusion(), kOcclusion, t.rows, budget);
  if (!occ) return fail(occ.error().message);
  f.irradiance = std::move(irr.value());
  f.depth = std::move(dep.value());
  f.occlusion = std::move(occ.value());
  f.version = root->field_version();
  f.sceneHash = root->scene_hash();

  // Values: finite, valid probe states (and the layout once more, for free).
  if (Status s = validateField(f); !s) return fail(s.error().message);
  return f;
}

Status writeBakedField(const std::filesystem::path& path, const Field& field,
                       const BakedWriteOptions& options) {
  const std::string prefix = "baked file " + path.string() + ": ";
  auto bytes = encodeBakedField(field, options);
  if (!bytes) return Error{prefix + bytes.error().message};

  // Same folder as the target, so the rename cannot cross file systems.
  // Removed on every failure below, and by the bake's signal handler if a signal ends it.
  TempFile tmp(path.string() + ".tmp." + std::to_string(::getpid()));
  {
    FilePtr f(std::fopen(tmp.path().c_str(), "wb"));
    if (!f)
      return Error{prefix + "cannot create " + tmp.path().string() + ": " + std::strerror(errno)};
    if (std::fwrite(bytes->data(), 1, bytes->size(), f.get()) != bytes->size() ||
        std::fflush(f.get()) != 0) {
      return Error{prefix + "write failed: " + std::strerror(errno)};
    }
    // On disk before the rename makes it visible: a power loss leaves the old file or the
    // whole new one.
    if (::fsync(fileno(f.get())) != 0)
      return Error{prefix + "fsync failed: " + std::strerror(errno)};
    if (std::fclose(f.release()) != 0)
      return Error{prefix + "close failed: " + std::strerror(errno)};
  }
  if (Status s = tmp.commit(path); !s) return Error{prefix + s.error().message};
  return Status::success();
}

Result<Field> readBakedField(const std::filesystem::path& path, std::uint64_t expectedSceneHash) {
  const std::string prefix = "baked file " + path.string() + ": ";
  std::error_code ec;
  auto st = std::filesystem::status(path, ec);
  if (ec || !std::filesystem::exists(st)) return Error{prefix + "missing (no such file)"};
  if (!std::filesystem::is_regular_file(st)) return Error{prefix + "not a regular file"};
  const std::uintmax_t size = std::filesystem::file_size(path, ec);
  if (ec) return Error{prefix + "cannot stat: " + ec.message()};
  if (size > kMaxBakedFileBytes) {
    return Error{prefix + "too large (" + std::to_string(size) + " bytes, limit " +
                 std::to_string(kMaxBakedFileBytes) + ")"};
  }
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(size));
  {
    FilePtr f(std::fopen(path.c_str(), "rb"));
    if (!f) return Error{prefix + "cannot open: " + std::strerror(errno)};
    const std::size_t got = std::fread(bytes.data(), 1, bytes.size(), f.get());
    if (got != bytes.size()) {
      return Error{prefix + "read " + std::to_string(got) + " of " + std::to_string(size) +
                   " bytes (file changed while reading?)"};
    }
  }
  return decodeBakedField(bytes, expectedSceneHash, path.string());
}

}  // namespace pc
