// Writes the seed corpus of the generated targets: small valid inputs made with the encoders,
// so the seeds follow the wire formats as they change. Usage: make_seeds <dir>; writes
// <dir>/<target>/<name> for the messages, datagram, brick, baked, session, token and
// sealed_datagram targets (the sidecar seeds are checked-in JSON files).
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "common/scene.h"
#include "fuzz_support.h"
#include "net/load_probe.h"
#include "protocol/baked_file.h"
#include "protocol/brick_codec.h"
#include "protocol/connect_token.h"
#include "protocol/datagram.h"
#include "protocol/datagram_seal.h"
#include "protocol/resume_state.h"
#include "protocol/secure_io.h"
#include "protocol/session_messages.h"

namespace {

using namespace pc;
namespace fs = std::filesystem;

fs::path outDir;
int written = 0;

void write(const std::string& target, const std::string& name,
           const std::vector<std::uint8_t>& bytes) {
  const fs::path dir = outDir / target;
  fs::create_directories(dir);
  std::ofstream out(dir / name, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
  if (!out) {
    std::fprintf(stderr, "make_seeds: cannot write %s\n", (dir / name).c_str());
    std::exit(1);
  }
  ++written;
}

void messages() {
  const Field field = fuzz::smallField(3);
  write("messages", "hello",
        encodeMessage(HelloMsg{kProtocolVersion, "token", "client", true, 4000}));
  write("messages", "welcome", encodeMessage(WelcomeMsg{kProtocolVersion, 17}));
  write("messages", "reject", encodeMessage(RejectMsg{kProtocolVersion, "authentication failed"}));
  write("messages", "session-info", encodeMessage(sessionInfoFor(field)));
  const Scene scene = builtinScene();
  write("messages", "scene-state", encodeMessage(sceneStateMessage(evaluateScene(scene, 0.5))));
  write("messages", "viewer-pose",
        encodeMessage(ViewerPoseMsg{{0.5f, 1.0f, -2.0f}, {0.9f, 0.1f, 0.3f, 0.2f}, 12.5}));
  AckMsg ack;
  ack.full = true;
  ack.fieldVersion = 9;
  ack.ranges = {{0, 0, 8, 3}, {1, 2, 1, 5}};
  write("messages", "ack", encodeMessage(ack));
  AckMsg gaps;
  gaps.fieldVersion = 9;
  gaps.gaps = {{77, 0, 3, 9, 4, 30, {2, 17, 29}}, {78, 1, 0, 9, 0, 3, {0}}};
  write("messages", "ack-gaps", encodeMessage(gaps));
  RepairRequestMsg repair;
  repair.bricks = {{0, 1, 2}, {1, 0, 0}};
  write("messages", "repair", encodeMessage(repair));
  HeldBricks held(2);
  for (std::uint64_t b = 0; b < 8; ++b) held[0].push_back(HeldBrick{900 + b % 3, b == 2 ? 2 : 0});
  held[1].assign(4, HeldBrick{870, 0});
  write("messages", "resume", encodeMessage(resumeMessage(0x5eed, 0x1234567, held)));
  EditMsg edit;
  edit.editId = 3;
  edit.edit.op = EditOp::SetLight;
  edit.edit.fields = kEditPosition | kEditColor | kEditIntensity;
  edit.edit.position = {0.1f, 1.2f, 0.3f};
  edit.edit.color = {1.0f, 0.5f, 0.2f};
  edit.edit.intensity = 5.0f;
  write("messages", "edit", encodeMessage(edit));
  EditMsg move;
  move.edit.op = EditOp::MoveInstance;
  move.edit.target = 4;
  move.edit.transform[3] = {0.2f, 0.3f, 0.1f, 1.0f};
  write("messages", "edit-move", encodeMessage(move));
  write("messages", "edit-result", encodeMessage(EditResultMsg{3, false, "light 9", 0, 9}));
}

// Datagram seeds hold the body without its CRC: the target appends a valid one.
void datagrams() {
  auto body = [](std::vector<std::uint8_t> d) {
    d.resize(d.size() - 4);
    return d;
  };
  std::vector<std::uint8_t> payload(1500);
  for (std::size_t i = 0; i < payload.size(); ++i) payload[i] = std::uint8_t(i * 7 + 3);
  const std::span<const std::uint8_t> all(payload);
  UpdateHeader big{.updateId = 5,
                   .cascade = 0,
                   .brick = 3,
                   .version = 4,
                   .baseVersion = 2,
                   .codec = 1,
                   .totalSize = 1500};
  UpdateHeader small{.updateId = 6,
                     .cascade = 1,
                     .brick = 0,
                     .version = 1,
                     .baseVersion = 0,
                     .codec = 1,
                     .totalSize = 40};
  write("datagram", "empty", body(encodeDatagram(1, 1, 4, {})));
  const FragmentRef first[] = {{big, 0, all.first(kFragmentBytes)}};
  write("datagram", "first-fragment", body(encodeDatagram(1, 2, 4, first)));
  const FragmentRef last[] = {{big, 1, all.subspan(kFragmentBytes)}, {small, 0, all.first(40)}};
  write("datagram", "last-and-whole", body(encodeDatagram(1, 3, 4, last)));
}

// Brick seeds: a mode byte (see fuzz_brick.cpp), then the payload or raw planes.
void bricks() {
  const Field field = fuzz::smallField(3);
  auto withMode = [](std::uint8_t mode, const std::vector<std::uint8_t>& rest) {
    std::vector<std::uint8_t> out{mode};
    out.insert(out.end(), rest.begin(), rest.end());
    return out;
  };
  const QuantizedBrick fine = quantizeBrick(field, 0, 0), coarse = quantizeBrick(field, 1, 0);
  write("brick", "self-contained", withMode(0, encodeBrick(fine, nullptr)));
  write("brick", "residual", withMode(2, encodeBrick(fine, &fuzz::baseBrick())));
  write("brick", "coarse-self-contained", withMode(4, encodeBrick(coarse, nullptr)));
  write("brick", "same-as-base", withMode(2, encodeBrick(fuzz::baseBrick(), &fuzz::baseBrick())));
  // Raw residual planes: zeros are the base itself; a few small differences on top.
  std::vector<std::uint8_t> planes(256, 0);
  for (std::size_t i = 0; i < planes.size(); i += 5) planes[i] = 2;  // zigzag 2 = +1
  write("brick", "raw-residual", withMode(3, planes));
  write("brick", "raw-residual-coarse", withMode(7, std::vector<std::uint8_t>(16, 0)));
}

// One small cascade with mostly constant contents: compressed atlases stay a few hundred bytes.
Field tinyField(bool twoCascades) {
  std::vector<ProbeVolume> volumes(1);
  volumes[0].origin = glm::vec3(0.0f);
  volumes[0].spacing = 1.0f;
  volumes[0].counts = glm::ivec3(2, 1, 2);
  if (twoCascades) volumes.push_back(ProbeVolume{glm::vec3(-2.0f), 4.0f, glm::ivec3(1, 1, 1)});
  Field f = Field::create(volumes, FieldSettings{});
  for (float& v : f.irradiance.texels) v = 0.5f;
  for (std::size_t i = 0; i + 1 < f.depth.texels.size(); i += 2) {
    f.depth.texels[i] = 1.0f;
    f.depth.texels[i + 1] = 1.25f;
  }
  for (float& v : f.occlusion.texels) v = 0.75f;
  for (std::size_t i = 0; i < f.probes.size(); ++i) {
    f.probes[i].state = int(i % 4);
    f.probes[i].offset = glm::vec3(0.01f * float(i % 3));
  }
  f.version = 3;
  f.sceneHash = 0xabcdull;
  return f;
}

void baked() {
  auto encode = [](const Field& f, BakedWriteOptions options) {
    Result<std::vector<std::uint8_t>> bytes = encodeBakedField(f, options);
    if (!bytes) {
      std::fprintf(stderr, "make_seeds: %s\n", bytes.error().message.c_str());
      std::exit(1);
    }
    return bytes.value();
  };
  BakedWriteOptions half;
  half.halfPrecision = true;
  write("baked", "tiny", encode(tinyField(false), {}));
  write("baked", "tiny-half", encode(tinyField(false), half));
  write("baked", "two-cascades", encode(tinyField(true), {}));
  write("baked", "empty-layout",
        encode(Field::create({ProbeVolume{glm::vec3(0.0f), 1.0f, glm::ivec3(1)}}, FieldSettings{}),
               {}));
}

// Session seeds: records of fuzz_session.cpp (op, 16-bit length, bytes) that a server would
// send: the handshake, a scene state and a brick update in datagrams, time passing.
void sessions() {
  auto record = [](std::uint8_t op, const std::vector<std::uint8_t>& bytes) {
    std::vector<std::uint8_t> r = {op, std::uint8_t(bytes.size()), std::uint8_t(bytes.size() >> 8)};
    r.insert(r.end(), bytes.begin(), bytes.end());
    return r;
  };
  auto join = [](std::initializer_list<std::vector<std::uint8_t>> parts) {
    std::vector<std::uint8_t> out;
    for (const auto& p : parts) out.insert(out.end(), p.begin(), p.end());
    return out;
  };
  const Field field = fuzz::smallField(3);
  const std::vector<std::uint8_t> welcome = encodeMessage(WelcomeMsg{kProtocolVersion, 17});
  const std::vector<std::uint8_t> info = encodeMessage(sessionInfoFor(field));
  const Scene scene = builtinScene();
  const std::vector<std::uint8_t> state =
      encodeMessage(sceneStateMessage(evaluateScene(scene, 0.5)));
  // Brick 0 of cascade 0, self-contained, one fragment per datagram (CRC left for the target).
  const std::vector<std::uint8_t> payload = encodeBrick(quantizeBrick(field, 0, 0), nullptr);
  const UpdateHeader header{.updateId = 1,
                            .cascade = 0,
                            .brick = 0,
                            .version = field.brickVersions[0][0],
                            .baseVersion = 0,
                            .codec = kCodecQuantZstd,
                            .totalSize = std::uint32_t(payload.size())};
  std::vector<std::uint8_t> datagrams;
  const std::uint16_t count = fragmentCount(header.totalSize);
  for (std::uint16_t i = 0; i < count; ++i) {
    const std::size_t from = std::size_t(i) * kFragmentBytes;
    const std::size_t n = std::min(kFragmentBytes, payload.size() - from);
    const FragmentRef f[] = {{header, i, std::span<const std::uint8_t>(payload).subspan(from, n)}};
    std::vector<std::uint8_t> d = encodeDatagram(17, 1 + i, field.version, f);
    d.resize(d.size() - 4);
    const std::vector<std::uint8_t> r = record(1 | 4, d);
    datagrams.insert(datagrams.end(), r.begin(), r.end());
  }
  const std::vector<std::uint8_t> tick = record(2, {16});
  write("session", "handshake", join({record(0, welcome), record(0, info), tick}));
  write("session", "stream",
        join({record(0, welcome), record(0, info), record(0, state), datagrams, tick, tick}));
  write("session", "split-frames",
        join({record(0, std::vector<std::uint8_t>(welcome.begin(), welcome.begin() + 3)),
              record(0, std::vector<std::uint8_t>(welcome.begin() + 3, welcome.end())),
              record(0, info), tick}));
  write("session", "reject",
        record(0, encodeMessage(RejectMsg{kProtocolVersion, "authentication failed"})));
  write("session", "silence",
        join({record(0, welcome), record(0, info), record(2, {255}), record(2, {255}),
              record(3 | 4, {}), record(0, welcome)}));
}

// Token seeds: a mode byte (see fuzz_token.cpp; 128 = the text as given, scene "sponza", the
// clock at kTokenNow; 129 = the same with binary claims the target signs), then the token.
void tokens() {
  auto issue = [](TokenClaims claims) {
    Result<std::string> token = issueToken(fuzz::tokenKeys().signing, claims);
    if (!token) {
      std::fprintf(stderr, "make_seeds: %s\n", token.error().message.c_str());
      std::exit(1);
    }
    return token.value();
  };
  auto asText = [](const std::string& token) {
    std::vector<std::uint8_t> out{128};
    out.insert(out.end(), token.begin(), token.end());
    return out;
  };
  // The binary claims of a token: its middle part decoded.
  auto asClaims = [](const std::string& token) {
    const std::size_t from = kTokenPrefix.size(), to = token.rfind('.');
    auto claims = base64UrlDecode(std::string_view(token).substr(from, to - from), 1024);
    std::vector<std::uint8_t> out{129};
    out.insert(out.end(), claims->begin(), claims->end());
    return out;
  };
  const std::int64_t now = fuzz::kTokenNow;
  const std::string any = issue(newTokenClaims("alice", "*", TokenRole::Viewer, 1, now - 10, 3600));
  const std::string sponza =
      issue(newTokenClaims("render farm 7", "sponza", TokenRole::Editor, 16, now, 86400));
  const std::string expired =
      issue(newTokenClaims("bob", "*", TokenRole::Viewer, 2, now - 7200, 3600));
  TokenClaims revoked = newTokenClaims("carol", "cornell", TokenRole::Viewer, 1, now, 60);
  revoked.id.fill(0x0f);
  const std::string revokedToken = issue(revoked);
  write("token", "any-scene", asText(any));
  write("token", "sponza-editor", asText(sponza));
  write("token", "expired", asText(expired));
  write("token", "revoked", asText(revokedToken));
  write("token", "claims-any-scene", asClaims(any));
  write("token", "claims-sponza-editor", asClaims(sponza));
  write("token", "claims-revoked", asClaims(revokedToken));
}

// Sealed datagram seeds: records of fuzz_sealed_datagram.cpp (op, 16-bit length, bytes).
void sealedDatagrams() {
  auto record = [](std::uint8_t op, const std::vector<std::uint8_t>& bytes) {
    std::vector<std::uint8_t> r = {op, std::uint8_t(bytes.size()), std::uint8_t(bytes.size() >> 8)};
    r.insert(r.end(), bytes.begin(), bytes.end());
    return r;
  };
  // Op 1: the target seals a counter and a plain datagram.
  auto sealHere = [&](std::uint8_t op, std::uint64_t counter, std::size_t plainBytes) {
    std::vector<std::uint8_t> bytes;
    for (int i = 0; i < 8; ++i) bytes.push_back(std::uint8_t(counter >> (8 * i)));
    for (std::size_t i = 0; i < plainBytes; ++i) bytes.push_back(std::uint8_t(i * 7 + counter));
    return record(op, bytes);
  };
  auto join = [](std::initializer_list<std::vector<std::uint8_t>> parts) {
    std::vector<std::uint8_t> out;
    for (const auto& p : parts) out.insert(out.end(), p.begin(), p.end());
    return out;
  };
  write("sealed_datagram", "in-order",
        join({sealHere(1, 1, 20), sealHere(1, 2, 0), sealHere(1, 3, 200)}));
  write("sealed_datagram", "reordered-replayed-old",
        join({sealHere(1, 5, 8), sealHere(1, 3, 8), sealHere(9, 4, 8), sealHere(1, 5, 8),
              sealHere(1, 3000, 8), sealHere(1, 1977, 8), sealHere(1, 1976, 8)}));
  write("sealed_datagram", "forged-and-other-session",
        join({sealHere(1, 1, 16), sealHere(5, 2, 16), sealHere(3, 2, 16), sealHere(1, 2, 16)}));
  // Op 0: datagrams sealed by a DatagramSealer, opened as they are (the second twice).
  DatagramSealer sealer(fuzz::sealKey(), fuzz::kSealSession);
  std::vector<std::uint8_t> a, b;
  const std::vector<std::uint8_t> plain(100, 0x42);
  if (!sealer.seal(plain, a) || !sealer.seal(std::span(plain).first(10), b)) std::exit(1);
  write("sealed_datagram", "as-received", join({record(0, a), record(0, b), record(8, b)}));
}

}  // namespace

// A query, and replies of an idle, a busy, a full and a not-ready endpoint.
void loadQueries() {
  auto bytes = [](const net::LoadDatagram& d) {
    return std::vector<std::uint8_t>(d.begin(), d.end());
  };
  write("load_query", "query", bytes(net::encodeLoadQuery(0x0123456789abcdefull)));
  const struct {
    const char* name;
    std::uint32_t clients, max;
    bool ready;
  } replies[] = {{"idle", 0, 64, true},
                 {"busy", 1000, 0, true},
                 {"full", 64, 64, true},
                 {"catching-up", 3, 64, false}};
  for (const auto& r : replies) {
    net::EndpointLoad load;
    load.clients = r.clients;
    load.maxClients = r.max;
    load.ready = r.ready;
    write("load_query", std::string("reply-") + r.name, bytes(net::encodeLoadReply(7, load)));
  }
}

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: make_seeds <dir>\n");
    return 2;
  }
  outDir = argv[1];
  messages();
  datagrams();
  bricks();
  baked();
  sessions();
  tokens();
  sealedDatagrams();
  loadQueries();
  std::printf("make_seeds: %d seeds under %s\n", written, outDir.c_str());
  return 0;
}
