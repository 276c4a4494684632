// Command-line parsing shared by the probecast tools (CLI11).
#pragma once

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "common/scene.h"
#include "protocol/stream_limits.h"
#include "tools/build_info.h"

namespace pc {

// What --version prints: the tool, the release, the git revision and build type it was built
// from, and the protocol versions it speaks, so that a report names what ran
// ("probecast-server 0.1.0 (git 5bd65b5-dirty, RelWithDebInfo; protocol 4, accepts 4 and later)").
inline std::string versionText(const char* argv0) {
  const std::string tool = std::filesystem::path(argv0 ? argv0 : "probecast").filename().string();
  return tool + " " + PC_VERSION + " (git " + gitRevision() + ", " + buildType() + "; protocol " +
         std::to_string(kProtocolVersion) + ", accepts " + std::to_string(kMinProtocolVersion) +
         " and later)";
}

// Records every option's value as it stands (the tool's default) for --help to show, in this
// app and its subcommands.
inline void captureDefaults(CLI::App& app) {
  for (CLI::Option* option : app.get_options([](CLI::Option*) { return true; })) {
    if (option->get_default_str().empty()) option->capture_default_str();
  }
  for (CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; })) captureDefaults(*sub);
}

// Parses the command line. --help prints the options with their defaults and --version the
// tool's version, and the tool exits 0; any other problem (an unknown option, a bad value, an
// option given twice) prints CLI11's message and the tool exits 1, its code for bad input,
// whatever CLI11's own code for that kind of error.
// Use: if (auto code = pc::parseCommandLine(app, argc, argv)) return *code;
inline std::optional<int> parseCommandLine(CLI::App& app, int argc, char** argv) {
  captureDefaults(app);
  app.set_version_flag(
      "--version", versionText(argc > 0 ? argv[0] : nullptr),
      "print the tool's version, git revision, build type and protocol version, and exit");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 1;
  }
  return std::nullopt;
}

// The options that bound what a scene file may read and make the tool allocate
// (SceneLoadOptions), for every tool and subcommand that loads scenes.
inline void addSceneLoadOptions(CLI::App& app, SceneLoadOptions& o) {
  app.add_flag("--allow-outside-paths", o.allowOutsidePaths,
               "let the scene read files outside its folder (glTF buffers and images, OBJ "
               "material libraries and texture maps)");
  app.add_option("--max-texture-size", o.maxTextureSize, "texels per side of one texture, at most")
      ->check(CLI::Range(1, 1 << 24));
  app.add_option("--max-scene-texels", o.maxSceneTexels,
                 "texels of all the scene's textures together, at most");
  app.add_option("--max-triangles", o.maxTriangles,
                 "triangles the scene's meshes hold, and draw over all instances, at most");
}

// One HOST:PORT: the host and a port in 1..65535, or nullopt.
inline std::optional<std::pair<std::string, std::uint16_t>> parseEndpoint(const std::string& text) {
  const std::size_t colon = text.rfind(':');
  int value = 0;
  std::size_t used = 0;
  try {
    if (colon != std::string::npos) value = std::stoi(text.substr(colon + 1), &used);
  } catch (const std::exception&) {
  }
  if (colon == std::string::npos || colon == 0 || used == 0 || colon + 1 + used != text.size() ||
      value <= 0 || value > 65535)
    return std::nullopt;
  return std::pair{text.substr(0, colon), static_cast<std::uint16_t>(value)};
}

// HOST:PORT[,HOST:PORT...]: one endpoint or several (relays of one field), or nullopt naming
// nothing; `bad` is set to the first part that is not an endpoint.
inline std::optional<std::vector<std::pair<std::string, std::uint16_t>>> parseEndpoints(
    const std::string& text, std::string& bad) {
  std::vector<std::pair<std::string, std::uint16_t>> endpoints;
  for (std::size_t start = 0; start <= text.size();) {
    const std::size_t comma = std::min(text.find(',', start), text.size());
    const std::string one = text.substr(start, comma - start);
    start = comma + 1;
    const auto endpoint = parseEndpoint(one);
    if (!endpoint) {
      bad = one;
      return std::nullopt;
    }
    endpoints.push_back(*endpoint);
  }
  return endpoints;
}

// --connect HOST:PORT[,HOST:PORT...], the server a tool connects to (probecast-loadgen): sets
// `host` and `port` to the first, `alternates` to the others (relays of one field, chosen by
// load). Given again, the endpoints add up. A part without a port in 1..65535 is a usage
// error.
inline CLI::Option* addConnectOption(CLI::App& app, std::string& host, std::uint16_t& port,
                                     std::vector<std::pair<std::string, std::uint16_t>>& alternates,
                                     const std::string& description) {
  auto parse = [&host, &port, &alternates](const std::vector<std::string>& texts) {
    std::vector<std::pair<std::string, std::uint16_t>> all;
    for (const std::string& text : texts) {
      std::string bad;
      auto endpoints = parseEndpoints(text, bad);
      if (!endpoints)
        throw CLI::ValidationError("--connect",
                                   "expected HOST:PORT[,HOST:PORT...], got '" + bad + "'");
      all.insert(all.end(), endpoints->begin(), endpoints->end());
    }
    if (all.empty()) return;
    std::tie(host, port) = all.front();
    alternates.assign(all.begin() + 1, all.end());
  };
  return app.add_option_function<std::vector<std::string>>("--connect", parse, description)
      ->type_name("HOST:PORT[,HOST:PORT...]");
}

// A finite number: CLI11 reads "nan" and "inf" as numbers, which no option here means.
inline const CLI::Validator kFinite(
    [](std::string& text) -> std::string {
      try {
        std::size_t used = 0;
        const double v = std::stod(text, &used);
        if (used == text.size() && std::isfinite(v)) return {};
      } catch (const std::exception&) {
      }
      return "expected a finite number, got '" + text + "'";
    },
    "FINITE");

}  // namespace pc
