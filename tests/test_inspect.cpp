// probecast-inspect on a field written here with known states, offsets, versions and atlas
// values: its JSON report counts and measures what was written, --slices writes PNGs of the
// expected sizes with each probe where the scroll puts it, and a corrupt file or a bad command
// line ends it with exit code 1 or 2 and a message.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "common/image.h"
#include "protocol/baked_file.h"
#include "test_protocol_support.h"

extern char** environ;

namespace {

namespace fs = std::filesystem;
using pc::gpu::ivec3;

const std::string kTool = std::string(PC_BUILD_DIR) + "/bin/probecast-inspect";
constexpr std::uint64_t kSceneHash = 0x0123456789abcdefull;
constexpr float kDimEncoded = 0.5f;   // decodes to 0.5^5 = 0.03125
constexpr float kDepthShare = 0.75f;  // of the cascade's max ray distance
constexpr float kOcclusion = 0.25f;
const ivec3 kBright(2, 1, 3);  // cascade 0: the one probe whose irradiance decodes to 1
const ivec3 kInside(3, 1, 3);  // cascade 0: forced inside
const ivec3 kDim(1, 1, 3);     // cascade 0: forced sleeping (dim, with data)

struct ToolRun {
  int code = -1;
  std::string output;  // stdout and stderr
};

ToolRun runTool(std::vector<std::string> args, const fs::path& log) {
  args.insert(args.begin(), kTool);
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, 1, 2);
  pid_t pid = -1;
  ToolRun r;
  if (posix_spawn(&pid, argv[0], &actions, nullptr, argv.data(), environ) == 0) {
    int status = 0;
    waitpid(pid, &status, 0);
    r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }
  posix_spawn_file_actions_destroy(&actions);
  std::ifstream in(log);
  std::stringstream ss;
  ss << in.rdbuf();
  r.output = ss.str();
  return r;
}

int slotOf(const pc::Field& f, int k, ivec3 logical) {
  const auto& c = f.cascade(k);
  return pc::gpu::pcProbeSlot(c, pc::gpu::pcPhysicalCoord(c, logical));
}

void fillTile(pc::Atlas& atlas, const pc::gpu::CascadeDesc& c, int slot, int n, float v) {
  const auto origin = pc::gpu::pcAtlasTileOrigin(c, slot, n + 2);
  for (int y = 0; y < n + 2; ++y) {
    for (int x = 0; x < n + 2; ++x) {
      float* t = atlas.at(origin.x + x, origin.y + y);
      for (int ch = 0; ch < atlas.channels; ++ch) t[ch] = v;
    }
  }
}

// The shared synthetic layout (two cascades, bricks overhanging the grid), the first cascade
// scrolled; states cycling over the real probes, one relocated probe, brick versions
// 0..bricks-1 in cascade 0 and 7 in cascade 1, uniform atlases but for one bright probe.
pc::Field makeField() {
  pc::Field f = pc::test::makeSyntheticLayout();
  f.desc.cascades[0].scroll = glm::ivec3(1, 2, 3);
  f.version = 42;
  f.sceneHash = kSceneHash;
  for (int k = 0; k < f.cascadeCount(); ++k) {
    const auto& c = f.cascade(k);
    int real = 0;
    for (int slot = 0; slot < pc::gpu::pcSlotCount(c); ++slot) {
      if (!pc::gpu::pcSlotValid(c, slot)) continue;
      f.probe(k, slot).state = real++ % 4;
      fillTile(f.irradiance, c, slot, pc::gpu::PC_IRRADIANCE_TEXELS, kDimEncoded);
      fillTile(f.depth, c, slot, pc::gpu::PC_DEPTH_TEXELS, kDepthShare * c.maxRayDistance);
      fillTile(f.occlusion, c, slot, pc::gpu::PC_OCCLUSION_TEXELS, kOcclusion);
    }
    auto& versions = f.brickVersions[std::size_t(k)];
    for (std::size_t b = 0; b < versions.size(); ++b) versions[b] = k == 0 ? b : 7;
  }
  const auto& c0 = f.cascade(0);
  f.probe(0, slotOf(f, 0, kBright)).state = pc::gpu::PC_PROBE_ACTIVE;
  fillTile(f.irradiance, c0, slotOf(f, 0, kBright), pc::gpu::PC_IRRADIANCE_TEXELS, 1.0f);
  f.probe(0, slotOf(f, 0, kInside)).state = pc::gpu::PC_PROBE_INSIDE;
  f.probe(0, slotOf(f, 0, kDim)).state = pc::gpu::PC_PROBE_SLEEPING;
  // Relocated by half its spacing (0.3, 0, 0.4 of it).
  f.probe(0, slotOf(f, 0, ivec3(0, 0, 0))).offset = glm::vec3(0.15f, 0.0f, 0.2f);
  return f;
}

// Per cascade, the real probes of each state.
std::array<int, 4> stateCounts(const pc::Field& f, int k) {
  std::array<int, 4> n{};
  const auto& c = f.cascade(k);
  for (int slot = 0; slot < pc::gpu::pcSlotCount(c); ++slot) {
    if (pc::gpu::pcSlotValid(c, slot)) ++n[std::size_t(f.probe(k, slot).state)];
  }
  return n;
}

class InspectTool : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::path(PC_BUILD_DIR) / ("test-inspect-" + std::string(info->name()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    field_ = makeField();
    file_ = dir_ / "field.probes";
    pc::Status s = pc::writeBakedField(file_, field_);
    ASSERT_TRUE(s.ok()) << s.error().message;
  }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }
  nlohmann::json report(std::vector<std::string> extra = {}) {
    const fs::path json = dir_ / "report.json";
    std::vector<std::string> args = {file_.string(), "--json", json.string()};
    args.insert(args.end(), extra.begin(), extra.end());
    last_ = runTool(args, dir_ / "log.txt");
    EXPECT_EQ(last_.code, 0) << last_.output;
    std::ifstream in(json);
    return nlohmann::json::parse(in, nullptr, false);
  }
  fs::path dir_, file_;
  pc::Field field_;
  ToolRun last_;
};

}  // namespace

TEST_F(InspectTool, ReportCountsWhatTheFieldHolds) {
  const nlohmann::json j = report();
  ASSERT_FALSE(j.is_discarded()) << last_.output;
  EXPECT_EQ(j["format_version"], pc::kBakedFormatVersion);
  EXPECT_EQ(j["scene_hash"], "0x0123456789abcdef");
  EXPECT_EQ(j["field_version"], 42u);
  EXPECT_EQ(j["file_bytes"], fs::file_size(file_));
  EXPECT_EQ(j["layout"]["depth_texels"], pc::gpu::PC_DEPTH_TEXELS);
  EXPECT_EQ(j["settings"]["rays_per_probe"], field_.settings.raysPerProbe);
  EXPECT_EQ(j["probe_count"], 8 * 6 * 8 + 5 * 4 * 5);
  ASSERT_EQ(j["cascades"].size(), 2u);

  const char* names[] = {"active", "sleeping", "inside", "uninitialized"};
  for (int k = 0; k < 2; ++k) {
    SCOPED_TRACE("cascade " + std::to_string(k));
    const nlohmann::json& c = j["cascades"][std::size_t(k)];
    const auto& desc = field_.cascade(k);
    EXPECT_EQ(c["spacing"], desc.spacing);
    EXPECT_EQ(c["counts"], nlohmann::json::array({desc.counts.x, desc.counts.y, desc.counts.z}));
    EXPECT_EQ(c["scroll"], nlohmann::json::array({desc.scroll.x, desc.scroll.y, desc.scroll.z}));
    EXPECT_EQ(c["probes"], desc.counts.x * desc.counts.y * desc.counts.z);
    const std::array<int, 4> states = stateCounts(field_, k);
    for (int s = 0; s < 4; ++s) EXPECT_EQ(c["states"][names[s]], states[std::size_t(s)]) << s;
    const int withData = states[0] + states[1];
    EXPECT_EQ(c["probes_with_data"], withData);
    const int bricks = pc::gpu::pcBrickCount(desc);
    EXPECT_EQ(c["bricks"], bricks);
    EXPECT_EQ(c["brick_versions"]["min"], k == 0 ? 0 : 7);
    EXPECT_EQ(c["brick_versions"]["max"], k == 0 ? bricks - 1 : 7);
    EXPECT_EQ(c["brick_versions"]["at_zero"], k == 0 ? 1 : 0);

    // Decoded irradiance: every probe with data at 0.5^5 but cascade 0's bright one at 1.
    const double dim = std::pow(double(kDimEncoded), 5.0);
    const double mean = k == 0 ? (dim * (withData - 1) + 1.0) / withData : dim;
    for (int ch = 0; ch < 3; ++ch) {
      EXPECT_NEAR(c["irradiance_mean"][std::size_t(ch)].get<double>(), mean, 1e-6);
      EXPECT_NEAR(c["irradiance_max"][std::size_t(ch)].get<double>(), k == 0 ? 1.0 : dim, 1e-6);
    }
    EXPECT_NEAR(c["depth_mean"].get<double>(), kDepthShare * desc.maxRayDistance, 1e-5);
    EXPECT_NEAR(c["occlusion_mean"].get<double>(), kOcclusion, 1e-6);
    const int probes = c["probes"].get<int>();
    EXPECT_NEAR(c["offset_max"].get<double>(), k == 0 ? 0.5 : 0.0, 1e-6);
    EXPECT_NEAR(c["offset_mean"].get<double>(), k == 0 ? 0.5 / probes : 0.0, 1e-6);
  }
  // The table says the same.
  ToolRun table = runTool({file_.string()}, dir_ / "table.txt");
  EXPECT_EQ(table.code, 0);
  EXPECT_NE(table.output.find("scene hash        0x0123456789abcdef"), std::string::npos)
      << table.output;
  const std::array<int, 4> s0 = stateCounts(field_, 0);
  const std::string states0 = std::to_string(s0[0]) + " active, " + std::to_string(s0[1]) +
                              " sleeping, " + std::to_string(s0[2]) + " inside, " +
                              std::to_string(s0[3]) + " uninitialized";
  EXPECT_NE(table.output.find(states0), std::string::npos) << table.output;
}

TEST_F(InspectTool, SlicesAreImagesOfTheSliceWhereTheScrollPutsIt) {
  const fs::path slices = dir_ / "slices";
  const nlohmann::json j = report({"--slices", slices.string(), "--slice-y", "1", "--scale", "2"});
  ASSERT_FALSE(j.is_discarded()) << last_.output;
  ASSERT_EQ(j["slices"].size(), 2u);
  for (int k = 0; k < 2; ++k) {
    const auto& c = field_.cascade(k);
    const std::string stem = "cascade" + std::to_string(k) + "_";
    struct Expected {
      const char* what;
      int texels;
    };
    for (const Expected e : {Expected{"irradiance", pc::gpu::PC_IRRADIANCE_TEXELS},
                             Expected{"depth", pc::gpu::PC_DEPTH_TEXELS},
                             Expected{"occlusion", pc::gpu::PC_OCCLUSION_TEXELS},
                             Expected{"states", pc::gpu::PC_IRRADIANCE_TEXELS}}) {
      const fs::path path = slices / (stem + e.what + "_y1.png");
      EXPECT_NE(last_.output.find("wrote " + path.string()), std::string::npos) << last_.output;
      auto png = pc::readPng(path);
      ASSERT_TRUE(png.ok()) << png.error().message;
      EXPECT_EQ(png->width, c.counts.x * e.texels * 2) << path;
      EXPECT_EQ(png->height, c.counts.z * e.texels * 2) << path;
    }
  }

  // Cascade 0: the bright probe's tile is brighter than its dim neighbour's, and the state map
  // shows it active (green) and its neighbour inside (red), at their logical x and z.
  const int tile = pc::gpu::PC_IRRADIANCE_TEXELS * 2;
  auto pixel = [&](const pc::Image8& image, ivec3 probe) {
    const std::size_t at =
        (std::size_t(probe.z * tile + tile / 2) * image.width + probe.x * tile + tile / 2) * 3;
    return std::array<int, 3>{image.rgb[at], image.rgb[at + 1], image.rgb[at + 2]};
  };
  auto irradiance = pc::readPng(slices / "cascade0_irradiance_y1.png");
  auto states = pc::readPng(slices / "cascade0_states_y1.png");
  ASSERT_TRUE(irradiance.ok() && states.ok());
  EXPECT_GT(pixel(*irradiance, kBright)[0], pixel(*irradiance, kDim)[0] + 50);
  EXPECT_EQ(pixel(*states, kBright), (std::array<int, 3>{60, 200, 80}));
  EXPECT_EQ(pixel(*states, kInside), (std::array<int, 3>{220, 60, 50}));
  EXPECT_EQ(pixel(*states, kDim), (std::array<int, 3>{70, 120, 230}));

  // By default, each cascade's middle layer.
  ToolRun byDefault =
      runTool({file_.string(), "--slices", (dir_ / "middle").string()}, dir_ / "middle.txt");
  EXPECT_EQ(byDefault.code, 0) << byDefault.output;
  EXPECT_TRUE(fs::exists(dir_ / "middle" / "cascade0_depth_y3.png"));
  EXPECT_TRUE(fs::exists(dir_ / "middle" / "cascade1_occlusion_y2.png"));
}

TEST_F(InspectTool, CorruptFileExits1AndBadUsageExits2) {
  // One flipped bit half way through the file.
  std::fstream f(file_, std::ios::in | std::ios::out | std::ios::binary);
  const auto at = std::streamoff(fs::file_size(file_) / 2);
  f.seekg(at);
  char byte = 0;
  f.read(&byte, 1);
  byte = char(byte ^ 4);
  f.seekp(at);
  f.write(&byte, 1);
  f.close();
  ToolRun corrupt =
      runTool({file_.string(), "--json", (dir_ / "r.json").string()}, dir_ / "corrupt.txt");
  EXPECT_EQ(corrupt.code, 1);
  EXPECT_NE(corrupt.output.find("baked file " + file_.string() + ": checksum mismatch"),
            std::string::npos)
      << corrupt.output;
  EXPECT_FALSE(fs::exists(dir_ / "r.json"));

  ToolRun missing = runTool({(dir_ / "nope.probes").string()}, dir_ / "missing.txt");
  EXPECT_EQ(missing.code, 1);
  EXPECT_NE(missing.output.find("nope.probes: missing"), std::string::npos) << missing.output;

  EXPECT_EQ(runTool({}, dir_ / "usage.txt").code, 2);
  EXPECT_EQ(runTool({file_.string(), "--scale", "0"}, dir_ / "usage.txt").code, 2);
}
