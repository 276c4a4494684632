// probecast-client: renders a scene lit directly and by the probe field it holds (the baked
// fallback file here; the server's stream later), headless to PNG/EXR files or in a window.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "client/client_app.h"
#include "client/net_app.h"
#include "common/log.h"
#include "net/tls_context.h"
#include "tools/command_line.h"
#include "tools/token_input.h"

namespace {

// "x,y,z" -> vec3; false on bad text.
bool parseVec3(const std::string& text, glm::vec3& out) {
  float x, y, z;
  char tail;
  if (std::sscanf(text.c_str(), "%f,%f,%f%c", &x, &y, &z, &tail) != 3) return false;
  out = glm::vec3(x, y, z);
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"probecast client: Vulkan raster lit directly and by the probe cascades"};
  pc::client::ClientConfig c;
  std::string pos, dir, target, resize;
  float fov = 0.0f;
  bool noOverlay = false, noExr = false;
  app.add_option("--scene", c.scene, "scene file (.gltf/.glb/.obj) or 'builtin'")->required();
  app.add_option("--sidecar", c.sidecar, "scene.json sidecar");
  app.add_option("--probes", c.probes, "baked field (.probes): the fallback indirect light");
  pc::addSceneLoadOptions(app, c.sceneLoad);
  app.add_option("--out", c.outDir, "headless: output folder");
  app.add_option("--prefix", c.prefix, "headless: file name prefix");
  app.add_option("--width", c.width, "render width")->check(CLI::Range(1, 16384));
  app.add_option("--height", c.height, "render height")->check(CLI::Range(1, 16384));
  app.add_option("--frames", c.frames, "frames to render (windowed: 0 runs until closed)")
      ->check(CLI::Range(0, 1 << 30));
  app.add_option("--time", c.startTime, "animation time of the first frame, seconds")
      ->check(pc::kFinite);
  app.add_option("--dt", c.dt, "seconds per frame (windowed: negative follows the clock)")
      ->check(pc::kFinite);
  app.add_option("--camera", c.camera, "scene camera index")->check(CLI::NonNegativeNumber);
  app.add_option("--pos", pos, "camera position x,y,z");
  app.add_option("--dir", dir, "camera direction x,y,z");
  app.add_option("--target", target, "camera target x,y,z");
  app.add_option("--fov", fov, "vertical field of view, degrees")->check(CLI::Range(1.0, 179.0));
  app.add_flag("--stereo", c.stereo, "render both eyes in one pass (multiview)");
  app.add_option("--ipd", c.ipd, "interpupillary distance, scene units")
      ->check(pc::kFinite & CLI::NonNegativeNumber);
  app.add_flag("--window", c.windowed, "open a window (GLFW) instead of writing files");
  app.add_flag("--validation", c.validation, "Vulkan validation layer; errors fail the run");
  app.add_flag("--no-overlay", noOverlay, "windowed: no text overlay");
  app.add_flag("--no-exr", noExr, "headless: PNG only");
  app.add_option("--msaa", c.msaa, "samples per pixel (2, 4, 8)")->check(CLI::IsMember({2, 4, 8}));
  std::string raster = "auto";
  app.add_option("--raster", raster,
                 "visibility buffer: auto, fixed (fixed-function, multiview) or compute");
  bool noMipmaps = false;
  app.add_flag("--no-mipmaps", noMipmaps, "textures: one level-0 tap per sample (aliases)");
  app.add_option("--shadow-size", c.shadows.largeSize, "sun and spot shadow maps, texels");
  app.add_option("--point-shadow-size", c.shadows.pointSize, "point-light cube faces, texels");
  app.add_option("--area-shadow-size", c.shadows.smallSize, "emitter light shadow maps, texels");
  app.add_option("--area-lights", c.shadows.areaLights, "virtual point lights for emitters");
  app.add_option("--sample-flags", c.sampleFlags, "field sampling flags (1: no visibility)");
  app.add_option("--ao-radius", c.aoRadius,
                 "ambient occlusion of the indirect light (GTAO): radius in probe spacings, 0 off")
      ->check(pc::kFinite & CLI::NonNegativeNumber);
  app.add_option("--fovea", c.foveaRadius,
                 "foveated field sampling: outside this radius (fraction of the half view, about "
                 "its centre) one field sample per 2x2 pixels, shared on matching surfaces; 0 off")
      ->check(pc::kFinite & CLI::NonNegativeNumber)
      ->capture_default_str();
  std::string probeView = "off";
  app.add_option("--probe-view", probeView,
                 "probe debug view: off, irradiance (spheres lit by their probes) or state");
  app.add_option("--probe-cascade", c.probeView.cascade,
                 "probe view: the only cascade drawn (-1: all)")
      ->check(CLI::Range(-1, pc::gpu::PC_MAX_CASCADES - 1));
  bool noProbeLines = false;
  app.add_flag("--no-probe-lines", noProbeLines, "probe view: no relocation lines");
  app.add_option("--ready-file", c.readyFile, "windowed: written after half the frames");
  app.add_option("--test-resize", resize, "windowed: resize the window to WxH after 2 frames");
  // Network mode: the field comes from a server (the baked file stays the fallback).
  pc::client::NetRunConfig net;
  std::vector<std::string> connect;
  app.add_option("--connect", connect,
                 "stream the field from a server at HOST:PORT; several (relays of one field), "
                 "comma-separated or the flag again: the least loaded is taken, and another "
                 "when one fails")
      ->type_name("HOST:PORT[,HOST:PORT...]");
  std::string tokenFile;
  app.add_option("--token-file", tokenFile,
                 "--connect: connect token file (else $PROBECAST_TOKEN_FILE or $PROBECAST_TOKEN)");
  app.add_option("--name", net.net.name, "--connect: client name the server logs");
  app.add_flag("--tcp-only", net.net.tcpOnly, "--connect: datagrams over TCP");
  app.add_option("--server-fingerprint", net.net.serverFingerprint,
                 "--connect: trust the server whose TLS certificate has this SHA-256 "
                 "(sha256:<hex>, as the server prints it)");
  app.add_option("--ca-file", net.net.caFile,
                 "--connect: trust server certificates from this CA file (PEM) and check the "
                 "host name (default: the system's trust store)");
  app.add_flag("--no-tls{false}", net.net.tls,
               "--connect: plain TCP, for a server run with --no-tls (nothing is encrypted)");
  app.add_option("--udp-advertise-port", net.net.udpAdvertisePort,
                 "--connect: UDP port the server sends to (a relay in front of this client)");
  app.add_option("--duration", net.duration, "--connect: seconds to run (instead of --frames)")
      ->check(pc::kFinite & CLI::NonNegativeNumber);
  app.add_option("--max-fps", net.maxFps, "--connect: frames per second at most")
      ->check(pc::kFinite & CLI::NonNegativeNumber);
  app.add_option("--save-every", net.saveEvery, "--connect: write every Nth frame (0: last only)");
  app.add_option("--summary", net.summary,
                 "--connect: write a JSON summary here (and, without --series, the per-second "
                 "series beside it: SUMMARY's name with .series.csv)");
  app.add_option("--series", net.series,
                 "--connect, headless: write one CSV row about every second here (bytes and "
                 "kbit/s received, update latency, staleness, field version lag, frame time, "
                 "fps; docs/BENCHMARKS.md)");
  if (auto code = pc::parseCommandLine(app, argc, argv)) return *code;
  c.textureMipmaps = !noMipmaps;
  if (auto m = pc::client::parseProbeViewMode(probeView)) {
    c.probeView.mode = *m;
  } else {
    return pc::logError("--probe-view: expected off, irradiance or state"), 1;
  }
  c.probeView.offsets = !noProbeLines;
  if (net.series.empty() && !net.summary.empty())
    net.series = std::filesystem::path(net.summary).replace_extension(".series.csv").string();
  if (auto r = pc::client::parseRasterizer(raster)) {
    c.rasterizer = *r;
  } else {
    return pc::logError("--raster: expected auto, fixed or compute"), 1;
  }

  glm::vec3 v;
  if (!pos.empty()) {
    if (!parseVec3(pos, v)) return pc::logError("--pos: expected x,y,z"), 1;
    c.position = v;
  }
  if (!dir.empty()) {
    if (!parseVec3(dir, v)) return pc::logError("--dir: expected x,y,z"), 1;
    c.direction = v;
  }
  if (!target.empty()) {
    if (!parseVec3(target, v)) return pc::logError("--target: expected x,y,z"), 1;
    c.target = v;
  }
  if (fov > 0.0f) c.fovDegrees = fov;
  if (!resize.empty()) {
    int w = 0, h = 0;
    if (std::sscanf(resize.c_str(), "%dx%d", &w, &h) != 2 || w <= 0 || h <= 0)
      return pc::logError("--test-resize: expected WxH"), 1;
    c.testResize = glm::ivec2(w, h);
  }
  c.overlay = !noOverlay;
  c.writeExr = !noExr;
  if (!connect.empty()) {
    // HOST:PORT, or several (relays of one field) separated by commas.
    std::vector<pc::client::NetEndpoint> endpoints;
    for (const std::string& text : connect) {
      std::string bad;
      const auto parsed = pc::parseEndpoints(text, bad);
      if (!parsed)
        return pc::logError("--connect: expected HOST:PORT[,HOST:PORT...], got '" + bad + "'"), 1;
      for (const auto& [host, port] : *parsed) endpoints.push_back({host, port});
    }
    net.net.host = endpoints.front().host;
    net.net.port = endpoints.front().port;
    net.net.alternates.assign(endpoints.begin() + 1, endpoints.end());
    auto token = pc::connectToken(tokenFile);
    if (!token) return pc::logError(token.error().message), 1;
    net.net.token = *token;
    if (net.net.tls) {
      // Settings that cannot work stop the client now, not at every reconnect.
      auto tls = pc::net::TlsClient::create({net.net.serverFingerprint, net.net.caFile});
      if (!tls) return pc::logError("TLS: " + tls.error().message), 1;
    }
    return c.windowed ? pc::client::runNetWindowed(c, net) : pc::client::runNetHeadless(c, net);
  }
  return c.windowed ? pc::client::runWindowed(c) : pc::client::runHeadless(c);
}
