// An in-process field server on loopback for the benchmarks that need real sessions (edits,
// rest): Embree, the field thread and the network thread as probecast-server runs them, TLS with
// a certificate made for the run, runtime edits through a SceneEditor, and tokens signed with a
// key pair of the run's own.
#pragma once

#include <atomic>
#include <memory>
#include <string>
#include <thread>

#include "client/net_client.h"
#include "common/result.h"
#include "common/scene.h"
#include "protocol/connect_token.h"
#include "server/net_field_loop.h"
#include "server/net_server.h"
#include "server/scene_editor.h"
#include "server/tracer.h"

namespace pc::bench {

struct LoopbackServerOptions {
  int rays = 64, bakeUpdates = 16;
  int clients = 10;       // sessions the server must admit from this one address
  FieldLoopOptions loop;  // its editor is the server's own
};

class LoopbackServer {
 public:
  // Bakes the field, starts serving and starts the field thread; an error names what failed.
  static Result<std::unique_ptr<LoopbackServer>> start(const Scene& scene,
                                                       LoopbackServerOptions options);
  ~LoopbackServer() { stop(); }
  LoopbackServer(const LoopbackServer&) = delete;
  LoopbackServer& operator=(const LoopbackServer&) = delete;

  // A client's options for a session of `name` with a token of `role`.
  client::NetClientOptions clientOptions(const std::string& name, TokenRole role) const;
  SceneEditor& editor() { return *editor_; }
  FieldLoop& loop() { return *loop_; }
  NetServer& server() { return *server_; }
  // Stops the field thread and the server (also on destruction).
  void stop();

 private:
  explicit LoopbackServer(const Scene& scene) : scene_(scene) {}
  const Scene& scene_;
  std::unique_ptr<Tracer> tracer_;
  Field field_;
  std::unique_ptr<FieldHub> hub_;
  std::unique_ptr<SceneEditor> editor_;
  std::unique_ptr<NetServer> server_;
  std::unique_ptr<FieldLoop> loop_;
  KeyPair keys_;
  std::atomic<bool> stop_{false};
  std::thread fieldThread_;
};

}  // namespace pc::bench
