// probecast-bench <name> [options]: see tools/bench/bench.h and docs/BENCHMARKS.md.
#include <fstream>
#include <thread>

#include "bench/bench.h"
#include "tools/command_line.h"

namespace pc::bench {

void figure(const std::string& name, double value, const std::string& unit) {
  std::printf("FIGURE %s %.6g %s\n", name.c_str(), value, unit.c_str());
  std::fflush(stdout);
}

std::string machineDescription() {
  std::ifstream cpuinfo("/proc/cpuinfo");
  std::string line, model = "unknown CPU";
  while (std::getline(cpuinfo, line)) {
    if (line.rfind("model name", 0) == 0) {
      model = line.substr(line.find(':') + 2);
      break;
    }
  }
  return model + ", " + std::to_string(std::thread::hardware_concurrency()) + " hardware threads";
}

SceneLoadOptions& sceneLoadOptions() {
  static SceneLoadOptions options;
  return options;
}

Result<Scene> loadBenchScene(const std::string& path, const std::string& sidecar) {
  if (path.empty() || path == "builtin") return builtinScene();
  return loadScene(path, sidecar, sceneLoadOptions());
}

}  // namespace pc::bench

int main(int argc, char** argv) {
  CLI::App app{"probecast benchmarks: prints a table, then FIGURE <name> <value> <unit> lines"};
  app.require_subcommand(1);
  std::vector<pc::bench::Benchmark> benches = {
      pc::bench::addEnergy(app),  pc::bench::addTrace(app),  pc::bench::addQuality(app),
      pc::bench::addLeak(app),    pc::bench::addClient(app), pc::bench::addGpuTrace(app),
      pc::bench::addFaults(app),  pc::bench::addStream(app), pc::bench::addLoad(app),
      pc::bench::addContact(app), pc::bench::addScale(app),  pc::bench::addEdits(app),
      pc::bench::addRest(app),    pc::bench::addFlight(app), pc::bench::addSpecular(app),
      pc::bench::addSdf(app),     pc::bench::addLdm(app)};
  if (auto code = pc::parseCommandLine(app, argc, argv)) return *code;
  for (auto& b : benches) {
    if (b.command->parsed()) return b.run();
  }
  return 1;
}
