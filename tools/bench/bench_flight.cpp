// flight: a viewer flies low over a large height field while the field server's cascades follow
// it (common/field_scroll.h). An in-process server (Embree, the field thread and the network
// thread as probecast-server runs them, TLS on loopback) and one viewer client; the terrain is
// generated for the run (--size metres square, --cells quads a side, gentle hills under a
// low sun), the cascades nested around the viewer's start, each --ratio times coarser.
// The viewer hovers for --hover seconds, then flies straight at --speed for --seconds.
//   flight_bytes_ratio: bytes per second the client received while flying, over those while
//     hovering (the flight's first and last second left out). Scrolling itself re-sends nothing
//     the client holds: what it costs is the slab of new probes.
//   flight_frames_without_field: frames (at 30 per second, the flight's) in which some of
//     five ground points in the view had no probe data in the client's copy (sampleField's
//     coverage 0: the renderer's ambient fallback there).
//   flight_psnr_drop_db: at --checkpoints evenly spaced moments, the probe-lit image of the
//     client's copy against a path-traced reference, and the same for a field baked at that
//     spot (the cascades placed there and traced --bake-updates times): the largest
//     difference, baked minus streamed.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <thread>

#include "bench.h"
#include "bench_common.h"
#include "client/field_mirror.h"
#include "client/net_client.h"
#include "common/field_scroll.h"
#include "common/image.h"
#include "cpu/path_tracer.h"
#include "cpu/probe_lit_render.h"
#include "loopback_server.h"
#include "server/bake.h"

namespace pc::bench {

namespace {

struct FlightSetup {
  float size = 1500.0f;  // m, the terrain's side
  int cells = 200;       // quads per side
  float speed = 20.0f;   // m/s
  float height = 12.0f;  // m above the ground
  double hover = 10.0, seconds = 60.0;
  int cascades = 3;
  glm::ivec3 counts{8, 4, 8};
  float spacing = 4.0f, ratio = 3.0f;
  double rate = 10;
  int rays = 64, bakeUpdates = 24;
  int checkpoints = 3, width = 96, height8 = 64, spp = 64;
};

// Writes the terrain (OBJ, MTL) and its sidecar (sun, sky, following cascades) into `dir`.
Status writeTerrain(const std::filesystem::path& dir, const FlightSetup& o, glm::vec3 start) {
  std::ofstream obj(dir / "terrain.obj"), mtl(dir / "terrain.mtl"), side(dir / "terrain.json");
  if (!obj || !mtl || !side) return Error{"flight: cannot write the terrain into " + dir.string()};
  mtl << "newmtl ground\nKd 0.45 0.42 0.36\n";
  obj << "mtllib terrain.mtl\nusemtl ground\n";
  const int n = o.cells;
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) {
      const float x = (float(i) / float(n) - 0.5f) * o.size;
      const float z = (float(j) / float(n) - 0.5f) * o.size;
      obj << "v " << x << ' ' << groundHeight(x, z) << ' ' << z << '\n';
    }
  }
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i + 1, b = a + 1, c = a + n + 1;
      obj << "f " << a << ' ' << c << ' ' << b << "\nf " << b << ' ' << c << ' ' << c + 1 << '\n';
    }
  }
  side << "{\"lights\": [{\"type\": \"directional\", \"direction\": [-0.5, -0.45, -0.3], "
          "\"color\": [1, 0.95, 0.9], \"intensity\": 3}],\n"
          " \"sky\": {\"color\": [0.3, 0.4, 0.6]},\n \"volumes\": [";
  float spacing = o.spacing;
  for (int k = 0; k < o.cascades; ++k) {
    const glm::vec3 origin = start - glm::vec3(o.counts - 1) * (0.5f * spacing);
    side << (k ? ",\n  " : "\n  ") << "{\"origin\": [" << origin.x << ", " << origin.y << ", "
         << origin.z << "], \"spacing\": " << spacing << ", \"counts\": [" << o.counts.x << ", "
         << o.counts.y << ", " << o.counts.z << "], \"follow\": true}";
    spacing *= o.ratio;
  }
  side << "]}\n";
  if (!obj || !mtl || !side) return Error{"flight: writing the terrain failed"};
  return Status::success();
}

// The camera over the ground at (x, z), looking along +x and slightly down.
Camera cameraAt(float x, float z, float height) {
  Camera c;
  c.position = glm::vec3(x, groundHeight(x, z) + height, z);
  c.forward = glm::normalize(glm::vec3(1.0f, -0.35f, 0.0f));
  c.up = glm::vec3(0, 1, 0);
  c.yfov = 0.9f;
  return c;
}

// Whether the client's copy holds probe data at every one of five ground points in the view.
bool fieldInView(const Field& field, const Camera& camera) {
  const glm::vec2 ahead[] = {{15, 0}, {30, 0}, {60, 0}, {30, -15}, {30, 15}};
  for (glm::vec2 a : ahead) {
    const float x = camera.position.x + a.x, z = camera.position.z + a.y;
    const glm::vec3 P(x, groundHeight(x, z), z);
    float coverage = 0.0f;
    sampleField(field, P, groundNormal(x, z), glm::normalize(camera.position - P), 0, &coverage);
    if (!(coverage > 0.0f)) return false;
  }
  return true;
}

struct Checkpoint {
  Camera camera;
  Field field;  // the client's copy then
};

int runFlight(const FlightSetup& o) {
  const float startX = -0.5f * o.size + 0.1f * o.size, z0 = 0.0f;
  const float endX = startX + o.speed * float(o.seconds);
  if (endX > 0.5f * o.size - 60.0f)
    return std::fprintf(stderr, "flight: %.0f m of flight leave the %.0f m terrain\n",
                        o.speed * o.seconds, o.size),
           1;
  const Camera start = cameraAt(startX, z0, o.height);
  char pattern[] = "/tmp/probecast-flight-XXXXXX";
  if (!mkdtemp(pattern)) return std::fprintf(stderr, "flight: no temporary folder\n"), 1;
  const std::filesystem::path dir(pattern);
  struct Remove {
    std::filesystem::path p;
    ~Remove() {
      std::error_code ec;
      std::filesystem::remove_all(p, ec);
    }
  } remove{dir};
  if (Status w = writeTerrain(dir, o, start.position); !w)
    return std::fprintf(stderr, "%s\n", w.error().message.c_str()), 1;
  auto loaded = loadBenchScene((dir / "terrain.obj").string(), (dir / "terrain.json").string());
  if (!loaded) return std::fprintf(stderr, "flight: %s\n", loaded.error().message.c_str()), 1;
  Scene scene = std::move(loaded).value();

  LoopbackServerOptions serverOptions;
  serverOptions.rays = o.rays;
  serverOptions.bakeUpdates = o.bakeUpdates;
  serverOptions.clients = 1;
  serverOptions.loop.rate = o.rate;
  auto started = LoopbackServer::start(scene, serverOptions);
  if (!started) return std::fprintf(stderr, "flight: %s\n", started.error().message.c_str()), 1;
  LoopbackServer& server = **started;
  client::FieldMirror mirror;
  client::NetClient viewer(mirror, server.clientOptions("flyer", TokenRole::Viewer));
  viewer.setViewer(start.position, glm::quat(1, 0, 0, 0));
  viewer.start();
  const auto sleep = [](double s) {
    std::this_thread::sleep_for(std::chrono::duration<double>(s));
  };
  const double t0 = steadySeconds();
  while (!viewer.stats().synced && steadySeconds() - t0 < 120) sleep(0.05);
  if (!viewer.stats().synced) return std::fprintf(stderr, "flight: the viewer never synced\n"), 1;
  const auto bytes = [&] {
    const client::NetClientStats s = viewer.stats();
    return double(s.udpBytes + s.tcpBytes);
  };

  // Hover: the viewer stays at the start.
  const double hoverStart = steadySeconds();
  double hoverFrom = -1;
  while (steadySeconds() - hoverStart < o.hover) {
    const double t = steadySeconds() - hoverStart;
    if (hoverFrom < 0 && t >= 1.0) hoverFrom = bytes();
    sleep(0.05);
  }
  const double hoverTo = bytes();
  const double hoverRate = (hoverTo - hoverFrom) / std::max(1e-9, o.hover - 1.0);
  const std::uint64_t scrollsBefore = server.loop().stats().scrolls;

  // Flight: 30 frames a second; the pose goes to the server at the client's pose interval.
  std::vector<Checkpoint> checkpoints;
  int frames = 0, framesWithout = 0;
  double flyFrom = -1, flyTo = -1;
  const double flightStart = steadySeconds();
  int nextCheckpoint = 1;
  for (double t = 0; t < o.seconds; t = steadySeconds() - flightStart) {
    const Camera cam = cameraAt(startX + o.speed * float(t), z0, o.height);
    viewer.setViewer(cam.position, glm::quat(1, 0, 0, 0));
    bool covered = true;
    mirror.read([&](const Field& f) { covered = fieldInView(f, cam); });
    ++frames;
    framesWithout += covered ? 0 : 1;
    if (flyFrom < 0 && t >= 1.0) flyFrom = bytes();
    if (t <= o.seconds - 1.0) flyTo = bytes();
    if (nextCheckpoint <= o.checkpoints &&
        t >= o.seconds * double(nextCheckpoint) / double(o.checkpoints + 1)) {
      Checkpoint c{cam, {}};
      mirror.read([&](const Field& f) { c.field = f; });
      checkpoints.push_back(std::move(c));
      ++nextCheckpoint;
    }
    sleep(1.0 / 30.0);
  }
  const double flyRate = (flyTo - flyFrom) / std::max(1e-9, o.seconds - 2.0);
  const FieldLoopStats loopStats = server.loop().stats();
  server.stop();
  viewer.stop();

  // Checkpoints: the streamed copy against a field baked at the spot, both against the
  // reference.
  std::printf(
      "flight: %s; terrain %.0f m (%d triangles), %d cascades %dx%dx%d from %.0f m "
      "(x%.0f), %d rays, field at %.0f updates/s\n",
      machineDescription().c_str(), o.size, 2 * o.cells * o.cells, o.cascades, o.counts.x,
      o.counts.y, o.counts.z, o.spacing, o.ratio, o.rays, o.rate);
  std::printf(
      "  hover %.0f s: %.1f kB/s; flight %.0f s at %.0f m/s: %.1f kB/s, %llu cascade "
      "moves, %llu probes re-traced\n",
      o.hover, hoverRate / 1e3, o.seconds, o.speed, flyRate / 1e3,
      (unsigned long long)(loopStats.scrolls - scrollsBefore),
      (unsigned long long)loopStats.scrolledProbes);
  std::printf("  frames: %d, without probe data somewhere in view: %d\n", frames, framesWithout);
  auto made = makeEmbreeTracer(scene);
  if (!made) return std::fprintf(stderr, "flight: %s\n", made.error().message.c_str()), 1;
  std::unique_ptr<Tracer> tracer = std::move(made).value();
  double worstDrop = -1e9;
  std::printf("  checkpoint   x (m)   streamed dB   baked there dB   drop dB\n");
  for (std::size_t i = 0; i < checkpoints.size(); ++i) {
    const Checkpoint& c = checkpoints[i];
    // The same cascades, moved to where the server's were and traced from nothing.
    Field baked = Field::create(scene.volumes, FieldSettings{.raysPerProbe = o.rays});
    for (int k = 0; k < baked.cascadeCount(); ++k) {
      scrollCascade(baked, k,
                    originShift(baked.cascade(k).origin, c.field.cascade(k).origin,
                                baked.cascade(k).spacing));
    }
    if (Status s = tracer->setState(evaluateScene(scene, 0.0)); !s)
      return std::fprintf(stderr, "flight: %s\n", s.error().message.c_str()), 1;
    BakeOptions bake;
    bake.updates = o.bakeUpdates;
    if (auto b = bakeField(baked, *tracer, bake); !b)
      return std::fprintf(stderr, "flight: bake: %s\n", b.error().message.c_str()), 1;
    ProbeLitOptions lit;
    lit.width = o.width;
    lit.height = o.height8;
    lit.explicitCamera = c.camera;
    auto streamed = renderProbeLit(scene, c.field, lit);
    auto there = renderProbeLit(scene, baked, lit);
    PathTraceOptions pt;
    pt.width = o.width;
    pt.height = o.height8;
    pt.spp = o.spp;
    pt.explicitCamera = c.camera;
    auto reference = renderReference(scene, pt);
    if (!streamed || !there || !reference)
      return std::fprintf(stderr, "flight: a checkpoint's render failed\n"), 1;
    const Image8 ref = tonemap(reference->image, 1.0f);
    const double ps = psnr8(tonemap(*streamed, 1.0f), ref);
    const double pb = psnr8(tonemap(*there, 1.0f), ref);
    worstDrop = std::max(worstDrop, pb - ps);
    std::printf("  %10zu %7.0f %13.2f %16.2f %9.2f\n", i + 1, c.camera.position.x, ps, pb, pb - ps);
  }
  figure("flight_bytes_ratio", flyRate / std::max(1e-9, hoverRate), "ratio");
  figure("flight_frames_without_field", framesWithout, "count");
  if (!checkpoints.empty()) figure("flight_psnr_drop_db", worstDrop, "dB");
  return 0;
}

}  // namespace

Benchmark addFlight(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "flight", "a viewer flying over a large height field; the cascades follow it");
  static FlightSetup o;
  cmd->add_option("--size", o.size, "terrain side, m")->check(CLI::Range(200.0f, 20000.0f));
  cmd->add_option("--cells", o.cells, "terrain quads per side")->check(CLI::Range(8, 2000));
  cmd->add_option("--speed", o.speed, "m/s")->check(CLI::Range(0.1f, 1000.0f));
  cmd->add_option("--altitude", o.height, "m above the ground")->check(CLI::Range(1.0f, 500.0f));
  cmd->add_option("--hover", o.hover, "seconds hovering at the start")
      ->check(CLI::Range(2.0, 600.0));
  cmd->add_option("--seconds", o.seconds, "seconds of flight")->check(CLI::Range(3.0, 3600.0));
  cmd->add_option("--cascades", o.cascades, "nested cascades")->check(CLI::Range(1, 4));
  cmd->add_option("--counts", o.counts, "probes per axis in every cascade")
      ->check(CLI::Range(2, 64));
  cmd->add_option("--spacing", o.spacing, "finest cascade's spacing, m")
      ->check(CLI::Range(0.1f, 1000.0f));
  cmd->add_option("--ratio", o.ratio, "each cascade's spacing over the one before")
      ->check(CLI::Range(1.0f, 10.0f));
  cmd->add_option("--rate", o.rate, "field updates per second")->check(CLI::Range(1.0, 240.0));
  cmd->add_option("--rays", o.rays, "rays per probe per update")->check(CLI::Range(16, 1024));
  cmd->add_option("--bake-updates", o.bakeUpdates,
                  "updates of the fields baked before serving "
                  "and at the checkpoints")
      ->check(CLI::Range(1, 1000));
  cmd->add_option("--checkpoints", o.checkpoints, "images compared along the flight")
      ->check(CLI::Range(0, 20));
  cmd->add_option("--width", o.width, "checkpoint image width")->check(CLI::Range(16, 4096));
  cmd->add_option("--height", o.height8, "checkpoint image height")->check(CLI::Range(16, 4096));
  cmd->add_option("--spp", o.spp, "paths per pixel of the checkpoints' references")
      ->check(CLI::Range(1, 65536));
  return {cmd, [] { return runFlight(o); }};
}

}  // namespace pc::bench
