// An application that embeds probecast's client side from an installed package, as an engine
// with its own renderer would: it reads a baked field (probecast::protocol), then holds a
// server's stream in a FieldMirror through a NetClient (probecast::client) and samples the
// field it holds. No Vulkan, no window system.
//   consumer FIELD.probes [HOST PORT TOKEN-FILE SERVER-FINGERPRINT]
// Exit 0 when the file was read and its field holds light (and, with a server, the stream
// brought every brick of a field of the same probes within 60 s), else 1; 2 usage error.
#include <chrono>
#include <cstdio>
#include <fstream>
#include <string>
#include <thread>

#include "client/field_mirror.h"
#include "client/net_client.h"
#include "common/field.h"
#include "protocol/baked_file.h"

namespace {

// Irradiance at the middle of the finest cascade, on a surface facing the floor, seen from
// below: the light the floor sends up.
glm::vec3 irradianceAtCentre(const pc::Field& field) {
  const pc::gpu::CascadeDesc& c = field.cascade(0);
  const glm::vec3 centre = c.origin + c.spacing * glm::vec3(c.counts - 1) * 0.5f;
  const glm::vec3 down(0, -1, 0);
  return glm::vec3(pc::sampleField(field, centre, down, down, 0));
}

std::string firstLine(const char* path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  return line;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2 && argc != 6) {
    std::fprintf(stderr, "usage: consumer FIELD.probes [HOST PORT TOKEN-FILE FINGERPRINT]\n");
    return 2;
  }
  auto baked = pc::readBakedField(argv[1], 0);
  if (!baked) return std::fprintf(stderr, "%s\n", baked.error().message.c_str()), 1;
  const glm::vec3 e = irradianceAtCentre(*baked);
  std::printf("baked: %d probes in %d cascades, version %llu, irradiance %.4f %.4f %.4f\n",
              baked->probeCount(), baked->cascadeCount(),
              static_cast<unsigned long long>(baked->version), e.x, e.y, e.z);
  if (!(e.x + e.y + e.z > 0)) return std::fprintf(stderr, "the baked field holds no light\n"), 1;
  if (argc == 2) return 0;

  pc::client::FieldMirror mirror;
  pc::client::NetClientOptions options;
  options.host = argv[2];
  options.port = static_cast<std::uint16_t>(std::stoi(argv[3]));
  options.token = firstLine(argv[4]);
  options.serverFingerprint = argv[5];
  options.name = "consumer";
  pc::client::NetClient client(mirror, options);
  client.start();
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (!client.stats().synced && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  const pc::client::NetClientStats stats = client.stats();
  client.stop();
  if (!stats.synced)
    return std::fprintf(stderr, "no field within 60 s: %s\n", stats.lastError.c_str()), 1;

  int probes = 0;
  glm::vec3 s(0);
  mirror.read([&](const pc::Field& field) {
    probes = field.probeCount();
    s = irradianceAtCentre(field);
  });
  std::printf("stream: %d/%d bricks held, %d probes, version %llu, irradiance %.4f %.4f %.4f\n",
              stats.bricksHeld, stats.bricksTotal, probes,
              static_cast<unsigned long long>(stats.serverFieldVersion), s.x, s.y, s.z);
  if (probes != baked->probeCount())
    return std::fprintf(stderr, "the stream's field has %d probes, the file %d\n", probes,
                        baked->probeCount()),
           1;
  if (!(s.x + s.y + s.z > 0)) return std::fprintf(stderr, "the streamed field holds no light\n"), 1;
  return 0;
}
