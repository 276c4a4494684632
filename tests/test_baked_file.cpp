// Baked field files: exact round trips, and rejection of truncated, corrupted, foreign and
// mismatched files with messages that say what is wrong.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "common/temp_file.h"
#include "protocol/baked_field_generated.h"
#include "protocol/baked_file.h"
#include "protocol/crc64.h"

namespace fs = std::filesystem;

namespace {

constexpr std::uint64_t kSceneHash = 0x1234abcd5678ef01ull;

// A field laid out by Field::create and filled with deterministic pseudo-random contents.
pc::Field makeField(unsigned seed, bool twoCascades = true) {
  std::vector<pc::ProbeVolume> volumes(1);
  volumes[0].origin = glm::vec3(-1.0f, 0.0f, -1.5f);
  volumes[0].spacing = 0.5f;
  volumes[0].counts = glm::ivec3(6, 5, 7);
  if (twoCascades) {
    pc::ProbeVolume coarse;
    coarse.origin = glm::vec3(-3.0f, -1.0f, -3.0f);
    coarse.spacing = 1.5f;
    coarse.counts = glm::ivec3(5, 4, 5);
    volumes.push_back(coarse);
  }
  pc::FieldSettings settings;
  settings.raysPerProbe = 128;
  pc::Field f = pc::Field::create(volumes, settings);

  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 3.0f), offset(-0.2f, 0.2f);
  for (pc::Atlas* a : {&f.irradiance, &f.depth, &f.occlusion}) {
    for (float& v : a->texels) v = u(rng);
  }
  for (pc::ProbeRecord& p : f.probes) {
    p.offset = glm::vec3(offset(rng), offset(rng), offset(rng));
    p.state = int(rng() % 4);
    p.updates = std::uint32_t(rng() % 1000);
  }
  for (auto& bricks : f.brickVersions) {
    for (auto& v : bricks) v = rng();
  }
  f.desc.cascades[0].scroll = glm::ivec3(1, -2, 3);
  f.version = 42;
  f.sceneHash = kSceneHash;
  return f;
}

void expectEqual(const pc::Field& a, const pc::Field& b) {
  EXPECT_EQ(std::memcmp(&a.desc, &b.desc, sizeof a.desc), 0);
  EXPECT_EQ(a.settings.raysPerProbe, b.settings.raysPerProbe);
  EXPECT_EQ(a.settings.hysteresis, b.settings.hysteresis);
  EXPECT_EQ(a.settings.distanceExponent, b.settings.distanceExponent);
  EXPECT_EQ(a.settings.normalBias, b.settings.normalBias);
  EXPECT_EQ(a.settings.viewBias, b.settings.viewBias);
  EXPECT_EQ(a.settings.maxRayDistance, b.settings.maxRayDistance);
  EXPECT_EQ(a.settings.occlusionDistance, b.settings.occlusionDistance);
  EXPECT_EQ(a.settings.blendMargin, b.settings.blendMargin);
  for (auto [x, y] : {std::pair{&a.irradiance, &b.irradiance}, std::pair{&a.depth, &b.depth},
                      std::pair{&a.occlusion, &b.occlusion}}) {
    EXPECT_EQ(x->width, y->width);
    EXPECT_EQ(x->height, y->height);
    EXPECT_EQ(x->channels, y->channels);
    EXPECT_TRUE(x->texels == y->texels);
  }
  ASSERT_EQ(a.probes.size(), b.probes.size());
  for (std::size_t i = 0; i < a.probes.size(); ++i) {
    ASSERT_EQ(a.probes[i].offset, b.probes[i].offset) << i;
    ASSERT_EQ(a.probes[i].state, b.probes[i].state) << i;
    ASSERT_EQ(a.probes[i].updates, b.probes[i].updates) << i;
  }
  EXPECT_EQ(a.brickVersions, b.brickVersions);
  EXPECT_EQ(a.version, b.version);
  EXPECT_EQ(a.sceneHash, b.sceneHash);
}

std::vector<std::uint8_t> encode(const pc::Field& f, pc::BakedWriteOptions o = {}) {
  auto bytes = pc::encodeBakedField(f, o);
  EXPECT_TRUE(bytes.ok()) << bytes.error().message;
  return bytes.ok() ? std::move(bytes.value()) : std::vector<std::uint8_t>{};
}

bool contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

// Byte offset of a scalar field of a table inside `buf` (which the table lies in).
template <typename T>
std::size_t fieldOffset(const std::vector<std::uint8_t>& buf, const T* table,
                        flatbuffers::voffset_t field) {
  const auto* t = reinterpret_cast<const flatbuffers::Table*>(table);
  const std::uint8_t* p = t->GetAddressOf(field);
  EXPECT_NE(p, nullptr);
  return std::size_t(p - buf.data());
}

void putU32(std::vector<std::uint8_t>& buf, std::size_t at, std::uint32_t v) {
  std::memcpy(&buf[at], &v, 4);
}

class BakedFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           ("pc_test_baked_" + std::to_string(::getpid()) + "_" + info->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

}  // namespace

TEST(BakedField, RoundTripIsExact) {
  const pc::Field f = makeField(1);
  for (int level : {0, 3}) {
    pc::BakedWriteOptions o;
    o.zstdLevel = level;
    std::vector<std::uint8_t> bytes = encode(f, o);
    auto back = pc::decodeBakedField(bytes, kSceneHash);
    ASSERT_TRUE(back.ok()) << back.error().message;
    expectEqual(f, *back);
  }
}

TEST(BakedField, FreshFieldRoundTrip) {
  // All zero atlases and uninitialized probes, straight from Field::create.
  pc::Field f = pc::Field::create({pc::ProbeVolume{}}, pc::FieldSettings{});
  std::vector<std::uint8_t> bytes = encode(f);
  auto back = pc::decodeBakedField(bytes, 0);
  ASSERT_TRUE(back.ok()) << back.error().message;
  expectEqual(f, *back);

  // No cascades at all: empty atlases, still a valid file.
  pc::Field empty = pc::Field::create({}, pc::FieldSettings{});
  auto none = pc::decodeBakedField(encode(empty), 0);
  ASSERT_TRUE(none.ok()) << none.error().message;
  expectEqual(empty, *none);
}

TEST(BakedField, HalfPrecision) {
  const pc::Field f = makeField(2);
  pc::BakedWriteOptions o;
  o.halfPrecision = true;
  std::vector<std::uint8_t> half = encode(f, o), full = encode(f);
  EXPECT_LT(half.size(), full.size());
  auto back = pc::decodeBakedField(half, kSceneHash);
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_TRUE(back->depth.texels == f.depth.texels);  // depth stays float32
  for (std::size_t i = 0; i < f.irradiance.texels.size(); ++i) {
    ASSERT_NEAR(back->irradiance.texels[i], f.irradiance.texels[i],
                1e-3f * f.irradiance.texels[i] + 1e-6f);
  }
  EXPECT_EQ(back->probes.size(), f.probes.size());
}

TEST(BakedField, UnalignedInput) {
  std::vector<std::uint8_t> bytes = encode(makeField(3, false));
  std::vector<std::uint8_t> shifted(bytes.size() + 1);
  std::copy(bytes.begin(), bytes.end(), shifted.begin() + 1);
  auto back = pc::decodeBakedField(std::span(shifted).subspan(1), kSceneHash);
  ASSERT_TRUE(back.ok()) << back.error().message;
}

TEST(BakedField, TruncatedRejected) {
  std::vector<std::uint8_t> bytes = encode(makeField(4, false));
  // Every short length near the start, then a spread over the rest.
  std::vector<std::size_t> lengths;
  for (std::size_t n = 0; n < 512; ++n) lengths.push_back(n);
  for (std::size_t n = 512; n < bytes.size(); n += bytes.size() / 997 + 1) lengths.push_back(n);
  lengths.push_back(bytes.size() - 1);
  for (std::size_t n : lengths) {
    auto r = pc::decodeBakedField(std::span(bytes.data(), n), 0, "t.probes");
    ASSERT_FALSE(r.ok()) << "length " << n;
    ASSERT_TRUE(contains(r.error().message, "baked file t.probes: truncated")) << r.error().message;
  }
  // The same with the size prefix rewritten to match, so the Verifier and the layout checks
  // (not the announced size) must catch it.
  for (std::size_t n : lengths) {
    if (n < 12) continue;
    std::vector<std::uint8_t> cut(bytes.begin(), bytes.begin() + std::ptrdiff_t(n));
    putU32(cut, 0, std::uint32_t(n - 4));
    auto r = pc::decodeBakedField(cut, 0, "t.probes");
    ASSERT_FALSE(r.ok()) << "length " << n;
  }
}

TEST(BakedField, TrailingBytesRejected) {
  std::vector<std::uint8_t> bytes = encode(makeField(5, false));
  bytes.push_back(0);
  auto r = pc::decodeBakedField(bytes, 0);
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "unexpected bytes")) << r.error().message;
}

// Flipped bits anywhere in a file, in the tables where the structure lives and in the atlases:
// each is refused with a message, never loaded as a slightly different field. (Before the
// whole-file checksum, format version 1, most flips outside the zstd frames loaded silently.)
// A small field with compressed atlases: every bit of every byte. The same field with stored
// atlases (half a megabyte): every byte of its first 2 KiB and last 64 bytes, and 1,000 bits
// drawn at random.
TEST(BakedField, EveryFlipRejected) {
  std::vector<pc::ProbeVolume> volumes(1);
  volumes[0].counts = glm::ivec3(2, 2, 2);
  pc::Field small = pc::Field::create(volumes, {});
  small.sceneHash = kSceneHash;
  for (int level : {3, 0}) {
    pc::BakedWriteOptions o;
    o.zstdLevel = level;
    const std::vector<std::uint8_t> bytes = encode(small, o);
    std::vector<std::uint8_t> bad = bytes;
    int flips = 0, byChecksum = 0;
    auto tryFlip = [&](std::size_t at, std::uint8_t mask) {
      bad[at] ^= mask;
      auto r = pc::decodeBakedField(bad, 0, "f.probes");
      bad[at] ^= mask;
      ++flips;
      ASSERT_FALSE(r.ok()) << "byte " << at << " mask " << int(mask) << " loaded";
      ASSERT_TRUE(contains(r.error().message, "baked file f.probes: ")) << r.error().message;
      if (contains(r.error().message, "checksum mismatch")) ++byChecksum;
    };
    if (level > 0) {
      ASSERT_LT(bytes.size(), 16384u);
      for (std::size_t at = 0; at < bytes.size(); ++at)
        for (int bit = 0; bit < 8; ++bit) tryFlip(at, std::uint8_t(1u << bit));
    } else {
      for (std::size_t at = 0; at < 2048; ++at) tryFlip(at, 0xff);
      for (std::size_t at = bytes.size() - 64; at < bytes.size(); ++at) tryFlip(at, 0xff);
      std::mt19937 rng(5);
      for (int i = 0; i < 1000; ++i) tryFlip(rng() % bytes.size(), std::uint8_t(1u << (rng() % 8)));
    }
    // The few flips another check catches first: size prefix, identifier, root offset and
    // table start, format version.
    EXPECT_GT(byChecksum, flips * 9 / 10) << byChecksum << " of " << flips;
    RecordProperty("flips_level_" + std::to_string(level), flips);
    RecordProperty("by_checksum_level_" + std::to_string(level), byChecksum);
    std::printf("zstd level %d: %zu-byte file, %d flips rejected, %d by the checksum\n", level,
                bytes.size(), flips, byChecksum);
  }
}

// Mutations past the checksum (as a fuzzer sealing its inputs makes them) still meet the
// structure and value checks.
TEST(BakedField, SealedRandomFlipsRejectedOrValid) {
  for (int level : {0, 3}) {
    pc::BakedWriteOptions o;
    o.zstdLevel = level;
    const std::vector<std::uint8_t> bytes = encode(makeField(6, false), o);
    std::mt19937 rng(77 + level);
    int rejected = 0;
    for (int trial = 0; trial < 500; ++trial) {
      std::vector<std::uint8_t> bad = bytes;
      const std::size_t span = trial % 2 ? bad.size() : std::min<std::size_t>(bad.size(), 1024);
      const int flips = 1 + int(rng() % 4);
      for (int i = 0; i < flips; ++i) bad[rng() % span] ^= std::uint8_t(1 + rng() % 255);
      pc::sealBakedChecksum(bad);
      auto r = pc::decodeBakedField(bad, 0);
      if (!r.ok()) {
        ++rejected;
        ASSERT_TRUE(contains(r.error().message, "baked file")) << r.error().message;
        continue;
      }
      // Whatever decodes is a usable field.
      pc::Status s = pc::validateField(*r);
      ASSERT_TRUE(s.ok()) << s.error().message;
    }
    EXPECT_GT(rejected, 0);
  }
}

TEST(BakedField, ChecksumIsCrc64OfTheWholeFile) {
  const char* check = "123456789";  // the catalogue's check value for CRC-64/XZ
  EXPECT_EQ(pc::crc64({reinterpret_cast<const std::uint8_t*>(check), 9}), 0x995DC9BBDF1939FAull);
  // Split anywhere, the running form gives the same value.
  EXPECT_EQ(pc::crc64({reinterpret_cast<const std::uint8_t*>(check) + 4, 5},
                      pc::crc64({reinterpret_cast<const std::uint8_t*>(check), 4})),
            0x995DC9BBDF1939FAull);

  const std::vector<std::uint8_t> bytes = encode(makeField(15, false));
  const auto* root = pc::wire::GetSizePrefixedBakedField(bytes.data());
  const std::size_t at = fieldOffset(bytes, root, pc::wire::BakedField::VT_CHECKSUM);
  std::vector<std::uint8_t> zeroed = bytes;
  std::memset(&zeroed[at], 0, 8);
  std::uint64_t stored;
  std::memcpy(&stored, &bytes[at], 8);
  EXPECT_EQ(stored, pc::crc64(zeroed));
  // A wrong checksum is named as such.
  std::vector<std::uint8_t> bad = bytes;
  bad[at] ^= 1;
  auto r = pc::decodeBakedField(bad, 0, "c.probes");
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "baked file c.probes: checksum mismatch (stored 0x"))
      << r.error().message;
  EXPECT_TRUE(contains(r.error().message, "the file is corrupt")) << r.error().message;
}

TEST(BakedField, SceneHashChecked) {
  std::vector<std::uint8_t> bytes = encode(makeField(7, false));
  auto wrong = pc::decodeBakedField(bytes, kSceneHash + 1, "a.probes");
  ASSERT_FALSE(wrong.ok());
  EXPECT_TRUE(contains(wrong.error().message,
                       "baked file a.probes: scene hash 0x1234abcd5678ef01 does not match scene "
                       "0x1234abcd5678ef02"))
      << wrong.error().message;
  EXPECT_TRUE(pc::decodeBakedField(bytes, 0).ok());
  EXPECT_TRUE(pc::decodeBakedField(bytes, kSceneHash).ok());
}

TEST(BakedField, WrongIdentifierRejected) {
  std::vector<std::uint8_t> bytes = encode(makeField(8, false));
  std::memcpy(&bytes[8], "XXXX", 4);
  auto r = pc::decodeBakedField(bytes, 0);
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "not a baked field file (identifier 'XXXX'"))
      << r.error().message;

  std::vector<std::uint8_t> png = {0x89, 'P', 'N', 'G', 0x0d, 0x0a, 0x1a, 0x0a, 0, 0, 0, 13};
  EXPECT_FALSE(pc::decodeBakedField(png, 0).ok());
}

TEST(BakedField, FormatVersionChecked) {
  const std::vector<std::uint8_t> bytes = encode(makeField(9, false));
  const auto* root = pc::wire::GetSizePrefixedBakedField(bytes.data());
  const std::size_t at = fieldOffset(bytes, root, pc::wire::BakedField::VT_FORMAT_VERSION);
  for (std::uint32_t v : {pc::kBakedFormatVersion + 1, pc::kBakedMinFormatVersion - 1, 1000u}) {
    std::vector<std::uint8_t> bad = bytes;
    putU32(bad, at, v);
    auto r = pc::decodeBakedField(bad, 0);
    ASSERT_FALSE(r.ok());
    EXPECT_TRUE(
        contains(r.error().message, "format version " + std::to_string(v) + " is not supported"))
        << r.error().message;
  }
  // Version 1 files (no checksum) are refused with what to do about them.
  std::vector<std::uint8_t> v1 = bytes;
  putU32(v1, at, 1);
  auto r = pc::decodeBakedField(v1, 0);
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message,
                       "format version 1 is not supported (this build reads 2..2; bake the "
                       "field again)"))
      << r.error().message;
}

TEST(BakedField, LayoutConstantsChecked) {
  const std::vector<std::uint8_t> bytes = encode(makeField(10, false));
  const auto* root = pc::wire::GetSizePrefixedBakedField(bytes.data());
  std::vector<std::uint8_t> bad = bytes;
  putU32(bad, fieldOffset(bytes, root->layout(), pc::wire::Layout::VT_IRRADIANCE_TEXELS), 6);
  ASSERT_TRUE(pc::sealBakedChecksum(bad));
  auto r = pc::decodeBakedField(bad, 0);
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "layout constants")) << r.error().message;
}

TEST(BakedField, InvalidValuesRejected) {
  pc::BakedWriteOptions raw;
  raw.zstdLevel = 0;
  const std::vector<std::uint8_t> bytes = encode(makeField(11, false), raw);
  const auto* root = pc::wire::GetSizePrefixedBakedField(bytes.data());

  // A probe state outside the enumeration.
  std::vector<std::uint8_t> bad = bytes;
  const auto* probe = root->probes()->Get(5);
  const std::size_t stateAt =
      std::size_t(reinterpret_cast<const std::uint8_t*>(probe) - bytes.data()) + 12;
  putU32(bad, stateAt, 9);
  ASSERT_TRUE(pc::sealBakedChecksum(bad));
  auto r = pc::decodeBakedField(bad, 0);
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "probe 5: invalid state 9")) << r.error().message;

  // A NaN in the irradiance atlas.
  bad = bytes;
  const std::size_t nanAt = std::size_t(root->irradiance()->data()->data() - bytes.data()) + 400;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(&bad[nanAt], &nan, 4);
  ASSERT_TRUE(pc::sealBakedChecksum(bad));
  r = pc::decodeBakedField(bad, 0);
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "irradiance atlas value 100 not finite"))
      << r.error().message;

  // Probe counts that disagree with the layout.
  bad = bytes;
  const auto* cascade = root->cascades()->Get(0);
  const std::size_t countsAt =
      std::size_t(reinterpret_cast<const std::uint8_t*>(cascade->counts()) - bytes.data());
  putU32(bad, countsAt, 9);
  ASSERT_TRUE(pc::sealBakedChecksum(bad));
  EXPECT_FALSE(pc::decodeBakedField(bad, 0).ok());
  putU32(bad, countsAt, 0x7fffffff);
  ASSERT_TRUE(pc::sealBakedChecksum(bad));
  r = pc::decodeBakedField(bad, 0);
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "out of range")) << r.error().message;
}

TEST(BakedField, WriterRefusesInvalidFields) {
  pc::Field f = makeField(12, false);
  f.probes[3].state = 17;
  EXPECT_FALSE(pc::encodeBakedField(f).ok());
  f = makeField(12, false);
  f.depth.texels[10] = std::numeric_limits<float>::infinity();
  EXPECT_FALSE(pc::encodeBakedField(f).ok());
  f = makeField(12, false);
  f.irradiance.texels.pop_back();
  EXPECT_FALSE(pc::encodeBakedField(f).ok());
  f = makeField(12, false);
  pc::BakedWriteOptions half;
  half.halfPrecision = true;
  f.irradiance.texels[0] = 1e6f;  // beyond float16
  EXPECT_FALSE(pc::encodeBakedField(f, half).ok());
}

TEST_F(BakedFileTest, FileRoundTripAndAtomicWrite) {
  const pc::Field f = makeField(13);
  const fs::path p = dir_ / "scene.probes";
  ASSERT_TRUE(pc::writeBakedField(p, f).ok());
  // Overwriting goes through a temporary that is renamed: nothing else is left behind.
  ASSERT_TRUE(pc::writeBakedField(p, f).ok());
  int files = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir_)) ++files;
  EXPECT_EQ(files, 1);
  auto back = pc::readBakedField(p, kSceneHash);
  ASSERT_TRUE(back.ok()) << back.error().message;
  expectEqual(f, *back);

  auto wrong = pc::readBakedField(p, 7);
  ASSERT_FALSE(wrong.ok());
  EXPECT_TRUE(contains(wrong.error().message, "baked file " + p.string() + ": scene hash"))
      << wrong.error().message;

  // A failed write leaves no file.
  EXPECT_FALSE(pc::writeBakedField(dir_ / "no" / "such.probes", f).ok());
}

// Names in the test folder that look like a writer's temporaries.
int tempFiles(const fs::path& dir) {
  int n = 0;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().filename().string().find(".tmp.") != std::string::npos) ++n;
  return n;
}

// A write that fails after its temporary file exists (here the rename: the target is a folder
// that is not empty) removes the temporary and says why.
TEST_F(BakedFileTest, FailedWriteLeavesNoTemporary) {
  const fs::path target = dir_ / "taken.probes";
  fs::create_directories(target / "inside");
  pc::Status s = pc::writeBakedField(target, makeField(16, false));
  ASSERT_FALSE(s.ok());
  EXPECT_TRUE(contains(s.error().message, "baked file " + target.string() + ": cannot rename " +
                                              target.string() + ".tmp."))
      << s.error().message;
  EXPECT_EQ(tempFiles(dir_), 0);
}

// A SIGTERM (or SIGINT) while a temporary is pending: the handler the bake installs removes it
// and the process ends by that signal.
TEST_F(BakedFileTest, SignalRemovesPendingTemporary) {
  const fs::path tmp = dir_ / "field.probes.tmp.123";
  EXPECT_EXIT(
      {
        pc::installTempFileCleanup();
        pc::TempFile pending(tmp);
        std::ofstream(tmp) << "part of a field";
        if (!fs::exists(tmp)) std::exit(3);
        std::raise(SIGTERM);
        std::exit(4);  // not reached
      },
      ::testing::KilledBySignal(SIGTERM), "");
  EXPECT_FALSE(fs::exists(tmp));
  EXPECT_EQ(tempFiles(dir_), 0);
  // Without a signal, the destructor removes it; a committed one is kept under its new name.
  {
    pc::TempFile dropped(tmp);
    std::ofstream(tmp) << "x";
  }
  EXPECT_FALSE(fs::exists(tmp));
  {
    pc::TempFile kept(tmp);
    std::ofstream(tmp) << "x";
    ASSERT_TRUE(kept.commit(dir_ / "kept").ok());
  }
  EXPECT_TRUE(fs::exists(dir_ / "kept"));
  EXPECT_EQ(tempFiles(dir_), 0);
}

TEST_F(BakedFileTest, MissingAndTruncatedFiles) {
  auto missing = pc::readBakedField(dir_ / "nope.probes", 0);
  ASSERT_FALSE(missing.ok());
  EXPECT_TRUE(contains(missing.error().message, "nope.probes: missing")) << missing.error().message;

  std::vector<std::uint8_t> bytes = encode(makeField(14, false));
  const fs::path p = dir_ / "cut.probes";
  {
    std::ofstream out(p, std::ios::binary);
    out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size() / 3));
  }
  auto cut = pc::readBakedField(p, 0);
  ASSERT_FALSE(cut.ok());
  EXPECT_TRUE(contains(cut.error().message,
                       "cut.probes: truncated (" + std::to_string(bytes.size() / 3) + " bytes"))
      << cut.error().message;

  EXPECT_FALSE(pc::readBakedField(dir_, 0).ok());  // a folder
}
