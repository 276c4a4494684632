// probecast-edit: an operator's runtime edit of a running server's scene (PROTOCOL.md "Runtime
// edits"), seen by every client. It opens a session with an editor's connect token, sends one
// edit, prints the server's answer and exits: 0 when the edit was applied, 1 when it was
// refused (the reason printed) or no answer came.
//
//   probecast-edit --connect 127.0.0.1:7450 --token-file ed.token
//       --server-fingerprint sha256:... light 0 --intensity 5 --color 1 0.5 0.2
#include <CLI/CLI.hpp>
#include <array>
#include <chrono>
#include <cstdio>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "client/field_mirror.h"
#include "client/net_client.h"
#include "common/log.h"
#include "common/scene_edits.h"
#include "net/tls_context.h"
#include "tools/command_line.h"
#include "tools/token_input.h"

namespace {

struct LightArgs {
  std::uint32_t id = 0;
  std::vector<float> position, direction, color;
  std::optional<float> intensity, range;
};

glm::vec3 vec3Of(const std::vector<float>& v) { return glm::vec3(v[0], v[1], v[2]); }

// The fields a light subcommand names, into `edit`.
void lightFields(const LightArgs& a, pc::SceneEdit& edit) {
  if (!a.position.empty()) edit.fields |= pc::kEditPosition, edit.position = vec3Of(a.position);
  if (!a.direction.empty()) edit.fields |= pc::kEditDirection, edit.direction = vec3Of(a.direction);
  if (!a.color.empty()) edit.fields |= pc::kEditColor, edit.color = vec3Of(a.color);
  if (a.intensity) edit.fields |= pc::kEditIntensity, edit.intensity = *a.intensity;
  if (a.range) edit.fields |= pc::kEditRange, edit.range = *a.range;
}

void addLightOptions(CLI::App& cmd, LightArgs& a) {
  cmd.add_option("--position", a.position, "world position X Y Z")->expected(3);
  cmd.add_option("--direction", a.direction, "direction the light travels X Y Z (spot)")
      ->expected(3);
  cmd.add_option("--color", a.color, "linear colour R G B")->expected(3);
  cmd.add_option("--intensity", a.intensity, "intensity");
  cmd.add_option("--range", a.range, "range in world units (0: unlimited)");
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "Runtime edit of a running server's scene: move, recolour, dim, add or remove a light, "
      "move an animated instance, switch an emitter's emission. Needs a connect token with the "
      "editor role (probecast-token issue --role editor); every client sees the edit. Exits 0 "
      "when the server applied it, 1 when it refused it (the reason is printed)."};
  app.require_subcommand(1);
  std::string connect, tokenFile, name = "probecast-edit", fingerprint, caFile;
  bool noTls = false;
  double timeout = 5.0;
  app.add_option("--connect", connect, "the server, HOST:PORT")->required();
  app.add_option("--token-file", tokenFile,
                 "editor's connect token file (else $PROBECAST_TOKEN_FILE or $PROBECAST_TOKEN)");
  app.add_option("--name", name, "client name the server logs");
  app.add_option("--server-fingerprint", fingerprint,
                 "trust the server whose TLS certificate has this SHA-256 fingerprint "
                 "(sha256:<hex>, as the server prints it)");
  app.add_option("--ca-file", caFile,
                 "trust server certificates from this CA file (PEM) and check the host name "
                 "(else the system's trust store)");
  app.add_flag("--no-tls", noTls, "plain TCP, for a server run with --no-tls");
  app.add_option("--timeout", timeout, "seconds to wait for the server's answer")
      ->check(CLI::Range(0.1, 600.0));

  pc::SceneEdit edit;
  LightArgs light, added;
  CLI::App* lightCmd = app.add_subcommand("light", "change a light's position, colour, ...");
  lightCmd->add_option("id", light.id, "the light: the scene's, then added ones")->required();
  addLightOptions(*lightCmd, light);
  CLI::App* addCmd = app.add_subcommand("add-light", "add a point light (prints its id)");
  addLightOptions(*addCmd, added);
  std::uint32_t removeId = 0;
  CLI::App* removeCmd = app.add_subcommand("remove-light", "a light gives no light from now on");
  removeCmd->add_option("id", removeId, "the light")->required();
  std::uint32_t instanceId = 0;
  std::vector<float> matrix, translate;
  float scale = 1.0f;
  CLI::App* instanceCmd =
      app.add_subcommand("instance", "move an animated instance (its object-to-world transform)");
  instanceCmd->add_option("id", instanceId, "the instance")->required();
  auto* matrixOpt =
      instanceCmd->add_option("--matrix", matrix, "16 numbers, column by column")->expected(16);
  instanceCmd->add_option("--translate", translate, "a translation X Y Z (with --scale)")
      ->expected(3)
      ->excludes(matrixOpt);
  instanceCmd->add_option("--scale", scale, "uniform scale, with --translate");
  std::uint32_t materialId = 0;
  float factor = 1.0f;
  CLI::App* emissionCmd =
      app.add_subcommand("emission", "switch an emitter: a factor on a material's emission");
  emissionCmd->add_option("material", materialId, "the emissive material")->required();
  emissionCmd->add_option("--factor", factor, "0: off, 1: as the scene has it")->required();
  if (auto code = pc::parseCommandLine(app, argc, argv)) return *code;

  if (lightCmd->parsed()) {
    edit.op = pc::EditOp::SetLight;
    edit.target = light.id;
    lightFields(light, edit);
    if (edit.fields == 0) return pc::logError("light: name a field to change"), 1;
  } else if (addCmd->parsed()) {
    edit.op = pc::EditOp::AddLight;
    lightFields(added, edit);
    if (!(edit.fields & pc::kEditPosition)) return pc::logError("add-light: --position"), 1;
  } else if (removeCmd->parsed()) {
    edit.op = pc::EditOp::RemoveLight;
    edit.target = removeId;
  } else if (instanceCmd->parsed()) {
    edit.op = pc::EditOp::MoveInstance;
    edit.target = instanceId;
    if (matrix.size() == 16) {
      std::copy(matrix.begin(), matrix.end(), &edit.transform[0][0]);
    } else if (translate.size() == 3) {
      edit.transform = glm::mat4(scale);
      edit.transform[3] = glm::vec4(vec3Of(translate), 1.0f);
    } else {
      return pc::logError("instance: --matrix or --translate"), 1;
    }
  } else {
    edit.op = pc::EditOp::SetEmission;
    edit.target = materialId;
    edit.emission = factor;
  }

  const auto endpoint = pc::parseEndpoint(connect);
  if (!endpoint) return pc::logError("--connect: expected HOST:PORT, got '" + connect + "'"), 1;
  auto token = pc::connectToken(tokenFile);
  if (!token) return pc::logError(token.error().message), 1;
  pc::client::NetClientOptions options;
  options.host = endpoint->first;
  options.port = endpoint->second;
  options.token = *token;
  options.name = name;
  options.tls = !noTls;
  options.serverFingerprint = fingerprint;
  options.caFile = caFile;
  options.tcpOnly = true;  // one message and its answer: no datagrams needed
  options.resume = false;
  if (options.tls) {
    auto tls = pc::net::TlsClient::create({fingerprint, caFile});
    if (!tls) return pc::logError("TLS: " + tls.error().message), 1;
  }

  pc::client::FieldMirror mirror;
  pc::client::NetClient client(mirror, options);
  client.start();
  const auto start = std::chrono::steady_clock::now();
  const auto elapsed = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  while (!client.stats().connected && elapsed() < timeout)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  if (!client.stats().connected) {
    const std::string why = client.stats().lastError;
    return pc::logError("no session with " + connect + " within " + std::to_string(timeout) + " s" +
                        (why.empty() ? "" : ": " + why)),
           1;
  }
  client.sendEdit(pc::EditMsg{1, edit});
  while (elapsed() < timeout) {
    for (const pc::EditResultMsg& r : client.takeEditResults()) {
      if (!r.accepted) {
        return pc::logError(std::string(pc::editOpName(edit.op)) + " refused: " + r.reason), 1;
      }
      std::printf("%s %u applied: edit version %llu\n", pc::editOpName(edit.op), r.target,
                  static_cast<unsigned long long>(r.editVersion));
      return 0;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return pc::logError("no answer to the edit within " + std::to_string(timeout) + " s"), 1;
}
