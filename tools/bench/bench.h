// probecast-bench: every figure the project claims comes from here. Each benchmark prints a
// readable table, then one line per figure: `FIGURE <name> <value> <unit>`.
#pragma once

#include <CLI/CLI.hpp>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

#include "common/result.h"
#include "common/scene.h"
#include "tools/command_line.h"

namespace pc::bench {

void figure(const std::string& name, double value, const std::string& unit);
// One-line description of this machine (CPU model, cores) for the tables.
std::string machineDescription();
// Loads --scene PATH (or the built-in scene when PATH is "builtin"), with --sidecar.
// What the subcommands' --allow-outside-paths and --max-* options set (addSceneLoadOptions),
// for every scene loadBenchScene loads.
SceneLoadOptions& sceneLoadOptions();
Result<Scene> loadBenchScene(const std::string& path, const std::string& sidecar);

// Each benchmark registers its subcommand; `run` is called when it was chosen.
struct Benchmark {
  CLI::App* command = nullptr;
  std::function<int()> run;
};
Benchmark addEnergy(CLI::App& app);
Benchmark addTrace(CLI::App& app);
Benchmark addQuality(CLI::App& app);
Benchmark addLeak(CLI::App& app);
Benchmark addClient(CLI::App& app);
Benchmark addGpuTrace(CLI::App& app);
Benchmark addFaults(CLI::App& app);
Benchmark addStream(CLI::App& app);
Benchmark addLoad(CLI::App& app);
Benchmark addContact(CLI::App& app);
Benchmark addScale(CLI::App& app);
Benchmark addEdits(CLI::App& app);
Benchmark addRest(CLI::App& app);
Benchmark addFlight(CLI::App& app);
Benchmark addSpecular(CLI::App& app);
Benchmark addSdf(CLI::App& app);
Benchmark addLdm(CLI::App& app);

}  // namespace pc::bench
