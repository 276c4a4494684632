#include "loopback_server.h"

#include "server/bake.h"

namespace pc::bench {

Result<std::unique_ptr<LoopbackServer>> LoopbackServer::start(const Scene& scene,
                                                              LoopbackServerOptions o) {
  std::unique_ptr<LoopbackServer> s(new LoopbackServer(scene));
  auto made = makeEmbreeTracer(scene);
  if (!made) return made.error();
  s->tracer_ = std::move(made).value();
  FieldSettings settings;
  settings.raysPerProbe = o.rays;
  s->field_ =
      Field::create(scene.volumes.empty() ? defaultVolumes(scene) : scene.volumes, settings);
  s->field_.sceneHash = scene.hash;
  if (Status st = s->tracer_->setState(evaluateScene(scene, 0.0)); !st) return st.error();
  BakeOptions bake;
  bake.updates = o.bakeUpdates;
  if (auto baked = bakeField(s->field_, *s->tracer_, bake); !baked)
    return Error{"bake: " + baked.error().message};

  s->keys_ = generateKeyPair();
  s->hub_ = std::make_unique<FieldHub>(s->field_);
  s->editor_ = std::make_unique<SceneEditor>(scene);
  NetServerOptions net;
  net.bindAddress = "127.0.0.1";
  net.port = 0;
  net.tokenKeys = {s->keys_.verify};
  net.tls.devSelfSigned = true;
  net.maxClients = std::size_t(o.clients) + 8;
  net.maxSessionsPerAddress = std::size_t(o.clients) + 8;
  net.handshakesPerSecondPerAddress = double(o.clients) + 8;
  SceneEditor* editor = s->editor_.get();
  net.edits = [editor](const SceneEdit& e) { return editor->submit(e); };
  (void)s->hub_->publish(s->field_, sceneStateMessage(evaluateScene(scene, 0.0)), steadySeconds());
  auto server = NetServer::create(*s->hub_, net);
  if (!server) return server.error();
  s->server_ = std::move(server).value();
  s->server_->start();
  o.loop.editor = editor;
  s->loop_ = std::make_unique<FieldLoop>(scene, *s->tracer_, s->field_, *s->hub_, o.loop);
  LoopbackServer* self = s.get();
  s->fieldThread_ = std::thread([self] { self->loop_->run(self->stop_, steadySeconds); });
  return s;
}

client::NetClientOptions LoopbackServer::clientOptions(const std::string& name,
                                                       TokenRole role) const {
  client::NetClientOptions c;
  c.host = "127.0.0.1";
  c.port = server_->port();
  c.serverFingerprint = server_->tlsFingerprint();
  auto t = issueToken(keys_.signing, newTokenClaims(name, "*", role, 1, unixSeconds(), 3600));
  c.token = t ? *t : std::string();
  c.name = name;
  return c;
}

void LoopbackServer::stop() {
  stop_ = true;
  if (fieldThread_.joinable()) fieldThread_.join();
  if (server_) server_->stop();
}

}  // namespace pc::bench
