// probecast-inspect: shows what a baked probe field (.probes) holds: the file's header and
// settings, each cascade's layout, and per cascade its probes by state, their relocation, its
// brick versions and what its atlases hold; --json writes the same as JSON, --slices renders one
// horizontal slice of each cascade's atlases and states as PNGs.
//
// Exit codes: 0 done, 1 the file cannot be used (the reader's message names the file and the
// problem) or an output cannot be written, 2 a usage error.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "common/field.h"
#include "protocol/baked_field_generated.h"
#include "protocol/baked_file.h"
#include "tools/command_line.h"
#include "tools/inspect/field_summary.h"
#include "tools/inspect/slice_images.h"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using pc::gpu::CascadeDesc;

int fail(const std::string& message) {
  std::fprintf(stderr, "probecast-inspect: error: %s\n", message.c_str());
  return 1;
}

// What the file itself says beyond the Field: its size, format version and layout constants.
// Read from the bytes the reader has just accepted, verified once more (the file may have
// changed since).
struct FileHeader {
  std::uint64_t bytes = 0;
  std::uint32_t formatVersion = 0;
  json layout;
};

pc::Result<FileHeader> readHeader(const fs::path& path) {
  const std::string prefix = "baked file " + path.string() + ": ";
  std::ifstream in(path, std::ios::binary);
  std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                  std::istreambuf_iterator<char>());
  if (!in.eof() && in.fail()) return pc::Error{prefix + "read failed"};
  flatbuffers::Verifier v(bytes.data(), bytes.size());
  if (!pc::wire::VerifySizePrefixedBakedFieldBuffer(v) ||
      !pc::wire::GetSizePrefixedBakedField(bytes.data())->layout()) {
    return pc::Error{prefix + "changed while it was read"};
  }
  const pc::wire::BakedField* root = pc::wire::GetSizePrefixedBakedField(bytes.data());
  const pc::wire::Layout* l = root->layout();
  FileHeader h;
  h.bytes = bytes.size();
  h.formatVersion = root->format_version();
  h.layout = {
      {"irradiance_texels", l->irradiance_texels()},     {"depth_texels", l->depth_texels()},
      {"occlusion_texels", l->occlusion_texels()},       {"brick_size", l->brick_size()},
      {"atlas_tiles_per_row", l->atlas_tiles_per_row()}, {"max_cascades", l->max_cascades()}};
  return h;
}

std::string hex64(std::uint64_t v) {
  char buf[24];
  std::snprintf(buf, sizeof buf, "0x%016llx", static_cast<unsigned long long>(v));
  return buf;
}

template <typename V>
json array3(const V& v) {
  return json::array({v.x, v.y, v.z});
}

json settingsJson(const pc::FieldSettings& s) {
  return {{"rays_per_probe", s.raysPerProbe},
          {"hysteresis", s.hysteresis},
          {"distance_exponent", s.distanceExponent},
          {"normal_bias", s.normalBias},
          {"view_bias", s.viewBias},
          {"max_ray_distance", s.maxRayDistance},
          {"occlusion_distance", s.occlusionDistance},
          {"blend_margin", s.blendMargin}};
}

json cascadeJson(const pc::Field& field, int k, const pc::inspect::CascadeSummary& s) {
  const CascadeDesc& c = field.cascade(k);
  const int slots = pc::gpu::pcSlotCount(c);
  json states = json::object();
  for (int state = 0; state < int(s.byState.size()); ++state) {
    states[pc::inspect::stateName(state)] = s.byState[std::size_t(state)];
  }
  // Means over no probes are null, not 0.
  const bool data = s.probesWithData > 0;
  return {{"index", k},
          {"origin", array3(c.origin)},
          {"spacing", c.spacing},
          {"counts", array3(c.counts)},
          {"probes", s.probes},
          {"slots", slots},
          {"bricks", pc::gpu::pcBrickCount(c)},
          {"scroll", array3(c.scroll)},
          {"normal_bias", c.normalBias},
          {"view_bias", c.viewBias},
          {"max_ray_distance", c.maxRayDistance},
          {"blend_margin", c.blendMargin},
          {"encoding", pc::probeEncodingName(pc::ProbeEncoding(c.encoding))},
          {"atlas_tile_row", c.atlasTileRow},
          {"atlas_tile_rows", pc::gpu::pcAtlasTileRows(slots)},
          {"states", states},
          {"offset_mean", s.offsetMean},
          {"offset_max", s.offsetMax},
          {"brick_versions",
           {{"min", s.versionMin}, {"max", s.versionMax}, {"at_zero", s.bricksAtVersionZero}}},
          {"probes_with_data", s.probesWithData},
          {"irradiance_mean", data ? array3(s.irradianceMean) : json(nullptr)},
          {"irradiance_max", data ? array3(s.irradianceMax) : json(nullptr)},
          {"depth_mean", data ? json(s.depthMean) : json(nullptr)},
          {"occlusion_mean", data ? json(s.occlusionMean) : json(nullptr)}};
}

void printTable(const json& j) {
  const json& st = j["settings"];
  const json& l = j["layout"];
  std::printf("file              %s\n", j["file"].get<std::string>().c_str());
  std::printf("size              %llu bytes\n", j["file_bytes"].get<unsigned long long>());
  std::printf("format version    %u\n", j["format_version"].get<unsigned>());
  std::printf("scene hash        %s\n", j["scene_hash"].get<std::string>().c_str());
  std::printf("field version     %llu\n", j["field_version"].get<unsigned long long>());
  std::printf(
      "layout            tiles %d/%d/%d texels (irradiance/depth/occlusion), bricks of %d^3,"
      " %d tiles per atlas row, at most %d cascades\n",
      l["irradiance_texels"].get<int>(), l["depth_texels"].get<int>(),
      l["occlusion_texels"].get<int>(), l["brick_size"].get<int>(),
      l["atlas_tiles_per_row"].get<int>(), l["max_cascades"].get<int>());
  std::printf("settings          %d rays, hysteresis %g, distance exponent %g\n",
              st["rays_per_probe"].get<int>(), st["hysteresis"].get<double>(),
              st["distance_exponent"].get<double>());
  std::printf("                  normal bias %g, view bias %g, blend margin %g (x spacing)\n",
              st["normal_bias"].get<double>(), st["view_bias"].get<double>(),
              st["blend_margin"].get<double>());
  std::printf(
      "                  max ray distance %g (0: per cascade), occlusion distance %g"
      " (x finest spacing)\n",
      st["max_ray_distance"].get<double>(), st["occlusion_distance"].get<double>());
  std::printf("probes            %d in %d cascades (%d slots, %d atlas tile rows)\n",
              j["probe_count"].get<int>(), int(j["cascades"].size()), j["slot_count"].get<int>(),
              j["atlas_tile_rows"].get<int>());
  for (const json& c : j["cascades"]) {
    auto v3 = [](const json& a, const char* f) {
      char buf[96];
      std::snprintf(buf, sizeof buf, f, a[0].get<double>(), a[1].get<double>(), a[2].get<double>());
      return std::string(buf);
    };
    std::printf("\ncascade %d\n", c["index"].get<int>());
    std::printf("  origin          %s, spacing %g\n", v3(c["origin"], "(%g, %g, %g)").c_str(),
                c["spacing"].get<double>());
    std::printf("  counts          %s = %d probes, %d brick(s) (%d slots), scroll %s\n",
                v3(c["counts"], "%gx%gx%g").c_str(), c["probes"].get<int>(), c["bricks"].get<int>(),
                c["slots"].get<int>(), v3(c["scroll"], "(%g, %g, %g)").c_str());
    std::printf("  biases          normal %g, view %g, blend margin %g, max ray distance %g\n",
                c["normal_bias"].get<double>(), c["view_bias"].get<double>(),
                c["blend_margin"].get<double>(), c["max_ray_distance"].get<double>());
    std::printf("  encoding        %s\n", c["encoding"].get<std::string>().c_str());
    std::printf("  atlas rows      %d..%d\n", c["atlas_tile_row"].get<int>(),
                c["atlas_tile_row"].get<int>() + c["atlas_tile_rows"].get<int>() - 1);
    const json& s = c["states"];
    std::printf("  states          %d active, %d sleeping, %d inside, %d uninitialized\n",
                s["active"].get<int>(), s["sleeping"].get<int>(), s["inside"].get<int>(),
                s["uninitialized"].get<int>());
    std::printf("  relocation      mean %.4f, max %.4f (x spacing)\n",
                c["offset_mean"].get<double>(), c["offset_max"].get<double>());
    const json& b = c["brick_versions"];
    std::printf("  brick versions  %llu..%llu, %d at version 0\n",
                b["min"].get<unsigned long long>(), b["max"].get<unsigned long long>(),
                b["at_zero"].get<int>());
    if (c["probes_with_data"].get<int>() == 0) {
      std::printf("  atlases         no probe holds data (none active or sleeping)\n");
      continue;
    }
    std::printf("  irradiance      mean %s, max %s W/m^2 (%d probes with data)\n",
                v3(c["irradiance_mean"], "(%.4g, %.4g, %.4g)").c_str(),
                v3(c["irradiance_max"], "(%.4g, %.4g, %.4g)").c_str(),
                c["probes_with_data"].get<int>());
    std::printf("  depth           mean distance %.4g\n", c["depth_mean"].get<double>());
    std::printf("  occlusion       mean %.4f\n", c["occlusion_mean"].get<double>());
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "Show what a baked probe field (.probes) holds: its header and settings, each cascade's "
      "layout, its probes by state, relocation, brick versions and atlas contents. Exit 0 done, "
      "1 the file cannot be used or an output not written, 2 usage error."};
  std::string path, jsonPath, slicesDir;
  int sliceY = -1;
  pc::inspect::SliceOptions slice;
  app.add_option("FILE", path, "baked field file (.probes)")->required();
  app.add_option("--json", jsonPath,
                 "also write the report as JSON to this file (- for stdout, "
                 "instead of the table)");
  app.add_option("--slices", slicesDir,
                 "write PNGs of one horizontal slice of probes of each cascade into this folder: "
                 "irradiance (/pi, tone-mapped), depth (mean distance / max ray distance), "
                 "occlusion and a state map (green active, blue sleeping, red inside, grey "
                 "uninitialized)");
  app.add_option("--slice-y", sliceY,
                 "the slice's probe layer (logical y; cascades that have "
                 "no such layer are skipped)")
      ->check(CLI::NonNegativeNumber)
      ->default_str("each cascade's middle layer");
  app.add_option("--scale", slice.scale, "image pixels per atlas texel")->check(CLI::Range(1, 32));
  app.add_option("--exposure", slice.exposure, "exposure of the irradiance slices")
      ->check(pc::kFinite & CLI::PositiveNumber);
  if (auto code = pc::parseCommandLine(app, argc, argv)) return *code == 0 ? 0 : 2;

  auto field = pc::readBakedField(path, 0);
  if (!field) return fail(field.error().message);
  auto header = readHeader(path);
  if (!header) return fail(header.error().message);
  const pc::Field& f = *field;

  json report = {{"file", path},
                 {"file_bytes", header->bytes},
                 {"format_version", header->formatVersion},
                 {"scene_hash", hex64(f.sceneHash)},
                 {"field_version", f.version},
                 {"layout", header->layout},
                 {"settings", settingsJson(f.settings)},
                 {"probe_count", f.probeCount()},
                 {"slot_count", f.desc.probeCount},
                 {"atlas_tile_rows", f.desc.atlasTileRows},
                 {"cascades", json::array()}};
  for (int k = 0; k < f.cascadeCount(); ++k) {
    report["cascades"].push_back(cascadeJson(f, k, pc::inspect::summarizeCascade(f, k)));
  }

  std::vector<std::string> notes;
  if (!slicesDir.empty()) {
    std::error_code ec;
    fs::create_directories(slicesDir, ec);
    if (ec) return fail("cannot create the slices folder " + slicesDir + ": " + ec.message());
    report["slices"] = json::array();
    for (int k = 0; k < f.cascadeCount(); ++k) {
      const int layers = f.cascade(k).counts.y;
      const int y = sliceY >= 0 ? sliceY : layers / 2;
      if (y >= layers) {
        notes.push_back("cascade " + std::to_string(k) + " has no probe layer y " +
                        std::to_string(y) + " (0.." + std::to_string(layers - 1) +
                        "): no slice written");
        continue;
      }
      auto written = pc::inspect::writeSliceImages(f, k, y, slicesDir, slice);
      if (!written) return fail(written.error().message);
      json files = json::array();
      for (const fs::path& p : *written) {
        files.push_back(p.string());
        notes.push_back("wrote " + p.string());
      }
      report["slices"].push_back({{"cascade", k}, {"y", y}, {"files", files}});
    }
  }

  if (jsonPath == "-") {
    std::printf("%s\n", report.dump(2).c_str());
  } else {
    printTable(report);
    if (!notes.empty()) std::printf("\n");
    for (const std::string& n : notes) std::printf("%s\n", n.c_str());
  }
  if (!jsonPath.empty() && jsonPath != "-") {
    std::ofstream out(jsonPath);
    out << report.dump(2) << "\n";
    out.close();
    if (!out) return fail("cannot write the JSON report " + jsonPath);
    std::printf("wrote %s\n", jsonPath.c_str());
  }
  return 0;
}
