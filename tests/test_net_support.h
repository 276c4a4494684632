// Shared by the socket tests: an in-process server on the built-in scene (field thread plus
// network thread, as probecast-server runs them), a fault-injecting UDP relay, a raw TCP peer
// for misbehaving clients, and the convergence check of a client's mirror.
#pragma once

#include <gtest/gtest.h>
#include <poll.h>

#include <array>
#include <atomic>
#include <boost/asio.hpp>
#include <boost/asio/ssl.hpp>
#include <chrono>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>

#include "client/field_mirror.h"
#include "client/net_client.h"
#include "protocol/connect_token.h"
#include "protocol/fault_link.h"
#include "protocol/net_framing.h"
#include "protocol/session_messages.h"
#include "server/bake.h"
#include "server/net_field_loop.h"
#include "server/net_server.h"
#include "test_protocol_support.h"
#include "test_tracer_support.h"

namespace pc::nettest {

// The tests' token issuer (a fixed key pair: never for real keys) and a token of it.
inline const KeyPair& testKeys() {
  static const KeyPair keys = keyPairFromSeed({7, 7, 7, 7});
  return keys;
}
inline std::string issueTestToken(const std::string& client, std::int64_t ttlSeconds = 3600,
                                  std::int64_t issuedAgo = 0, TokenRole role = TokenRole::Viewer) {
  const std::int64_t now = unixSeconds();
  auto token = issueToken(testKeys().signing,
                          newTokenClaims(client, "*", role, 1, now - issuedAgo, ttlSeconds));
  EXPECT_TRUE(token.ok());
  return token ? *token : std::string();
}
inline const std::string kToken = issueTestToken("test");

inline void sleepFor(double seconds) {
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
}

// Waits until `done` holds or `limit` seconds pass; true when it held.
inline bool waitFor(const std::function<bool()>& done, double limit) {
  const double start = steadySeconds();
  while (!done()) {
    if (steadySeconds() - start > limit) return false;
    sleepFor(0.01);
  }
  return true;
}

// The built-in scene's field, traced by Embree at 10 updates per second with few rays (the
// tests run on two shared cores), frozen at `freezeAt` so that a client can match it exactly.
class TestServer {
 public:
  // `followViewers`: every cascade follows the clients' viewers (common/field_scroll.h).
  explicit TestServer(double freezeAt, NetServerOptions net = {}, std::uint16_t port = 0,
                      bool followViewers = false)
      : scene_(builtinScene()) {
    auto tracer = makeEmbreeTracer(scene_);
    EXPECT_TRUE(tracer.ok());
    tracer_ = std::move(tracer).value();
    FieldSettings settings;
    settings.raysPerProbe = 32;
    field_ =
        Field::create(scene_.volumes.empty() ? defaultVolumes(scene_) : scene_.volumes, settings);
    field_.sceneHash = scene_.hash;
    BakeOptions bake;
    bake.updates = 4;
    setStateOrFail(*tracer_, evaluateScene(scene_, 0.0));
    bakeOrFail(field_, *tracer_, bake);
    for (int k = 0; k < field_.cascadeCount() && followViewers; ++k)
      field_.desc.cascades[k].follows = 1;
    hub_ = std::make_unique<FieldHub>(field_);
    (void)hub_->publish(field_, sceneStateMessage(evaluateScene(scene_, 0.0)), steadySeconds());
    net.port = port;
    net.bindAddress = "127.0.0.1";
    if (net.tokenKeys.empty()) net.tokenKeys = {testKeys().verify};
    // TLS as in production, with a certificate made for the test; clients pin fingerprint().
    if (net.tls.enabled && net.tls.certificateFile.empty()) net.tls.devSelfSigned = true;
    // Runtime edits as probecast-server takes them (only editor tokens get one applied).
    editor_ = std::make_unique<SceneEditor>(scene_);
    if (!net.edits) net.edits = [this](const SceneEdit& e) { return editor_->submit(e); };
    auto server = NetServer::create(*hub_, net);
    EXPECT_TRUE(server.ok()) << (server ? "" : server.error().message);
    server_ = std::move(server).value();
    server_->start();
    FieldLoopOptions loop;
    loop.rate = 10;
    loop.freezeAt = freezeAt;
    loop.editor = editor_.get();
    loop_ = std::make_unique<FieldLoop>(scene_, *tracer_, field_, *hub_, loop);
    thread_ = std::thread([this] { loop_->run(stop_, steadySeconds); });
  }
  ~TestServer() { shutdown(); }

  void shutdown() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
    if (server_) server_->stop();
  }
  std::uint16_t port() const { return server_->port(); }
  const std::string& fingerprint() const { return server_->tlsFingerprint(); }
  NetServer& net() { return *server_; }
  const FieldHub& hub() const { return *hub_; }
  FieldHub& hub() { return *hub_; }
  bool frozen() const { return loop_->stats().frozen; }
  const FieldLoop& loop() const { return *loop_; }
  const SceneEditor& editor() const { return *editor_; }
  const Scene& scene() const { return scene_; }
  // Only once frozen() (the field thread no longer writes it).
  const Field& field() const { return field_; }

 private:
  Scene scene_;
  std::unique_ptr<Tracer> tracer_;
  Field field_;
  std::unique_ptr<FieldHub> hub_;
  std::unique_ptr<SceneEditor> editor_;
  std::unique_ptr<NetServer> server_;
  std::unique_ptr<FieldLoop> loop_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

// Bricks of the client's mirror that differ from the server's field through quantization
// (every brick present, atlases, offsets and states exact): 0 when the client has converged.
inline int mirrorDifference(const client::FieldMirror& mirror, const Field& server) {
  const Field quantized = test::quantizedCopy(server);
  int differing = -1;
  mirror.read([&](const Field& m) {
    Field copy = m;
    // The mirror counts its own versions; only the content is compared.
    copy.brickVersions = quantized.brickVersions;
    differing = test::differingBricks(copy, quantized);
  });
  return differing;
}

// A client of the server at `port` with TLS as in production: its certificate pinned
// (`fingerprint`), a token of its own.
inline client::NetClientOptions secureClientOptions(std::uint16_t port,
                                                    const std::string& fingerprint,
                                                    const std::string& name) {
  client::NetClientOptions o;
  o.host = "127.0.0.1";
  o.port = port;
  o.serverFingerprint = fingerprint;
  o.token = issueTestToken(name);
  o.name = name;
  return o;
}
inline client::NetClientOptions secureClientOptions(const TestServer& server,
                                                    const std::string& name) {
  return secureClientOptions(server.port(), server.fingerprint(), name);
}

// A UDP relay that passes datagrams through a FaultLink (loss, bursts, duplication,
// reordering, corruption, delay), from whoever sends to it on to the target port (datagrams
// are dropped until one is set).
class UdpRelay {
 public:
  explicit UdpRelay(std::uint64_t seed = 7)
      : socket_(io_, boost::asio::ip::udp::endpoint(boost::asio::ip::make_address("127.0.0.1"), 0)),
        timer_(io_),
        link_(seed) {
    receive();
    tick();
    thread_ = std::thread([this] { io_.run(); });
  }
  ~UdpRelay() {
    boost::asio::post(io_, [this] {
      stopped_ = true;
      boost::system::error_code ec;
      socket_.close(ec);
      timer_.cancel();
    });
    thread_.join();
  }
  std::uint16_t port() const { return socket_.local_endpoint().port(); }
  void setTarget(std::uint16_t port) {
    std::lock_guard lock(mutex_);
    target_ = boost::asio::ip::udp::endpoint(boost::asio::ip::make_address("127.0.0.1"), port);
  }
  void setProfile(const FaultProfile& p) {
    std::lock_guard lock(mutex_);
    link_.setProfile(p);
  }
  LinkStats stats() const {
    std::lock_guard lock(mutex_);
    return link_.stats();
  }
  // Every datagram that came in, as it came, from now on (an eavesdropper's view of the path).
  void capture(bool on) {
    std::lock_guard lock(mutex_);
    capturing_ = on;
  }
  std::vector<std::vector<std::uint8_t>> captured() const {
    std::lock_guard lock(mutex_);
    return captured_;
  }

 private:
  void receive() {
    socket_.async_receive_from(
        boost::asio::buffer(buffer_), from_, [this](boost::system::error_code ec, std::size_t n) {
          if (stopped_) return;
          if (!ec) {
            std::lock_guard lock(mutex_);
            if (capturing_) captured_.emplace_back(buffer_.begin(), buffer_.begin() + n);
            link_.send(std::vector<std::uint8_t>(buffer_.begin(), buffer_.begin() + n),
                       steadySeconds());
          }
          receive();
        });
  }
  void tick() {
    timer_.expires_after(std::chrono::milliseconds(1));
    timer_.async_wait([this](boost::system::error_code ec) {
      if (ec || stopped_) return;
      std::vector<std::vector<std::uint8_t>> out;
      boost::asio::ip::udp::endpoint target;
      {
        std::lock_guard lock(mutex_);
        out = link_.receive(steadySeconds());
        target = target_;
      }
      for (auto& d : out) {
        if (target.port() == 0) break;
        boost::system::error_code e;
        socket_.send_to(boost::asio::buffer(d), target, 0, e);
      }
      tick();
    });
  }

  boost::asio::io_context io_;
  boost::asio::ip::udp::socket socket_;
  boost::asio::steady_timer timer_;
  boost::asio::ip::udp::endpoint target_, from_;
  std::array<std::uint8_t, 2048> buffer_{};
  mutable std::mutex mutex_;
  FaultLink link_;
  bool capturing_ = false;
  std::vector<std::vector<std::uint8_t>> captured_;
  bool stopped_ = false;
  std::thread thread_;
};

// A hand-driven peer of the session port: sends whatever bytes a test wants and reads frames
// back, over TLS (as every client speaks to a server with TLS; the peer does not check the
// certificate) or over plain TCP (`tls` false: what a stranger without TLS sends).
class RawPeer {
 public:
  using tcp = boost::asio::ip::tcp;
  // `from`: the local address to connect from (on Linux all of 127/8 is loopback, so
  // "127.0.0.2" is another client address on the same host). `tls` false: plain TCP.
  explicit RawPeer(std::uint16_t port, int receiveBuffer = 0, const char* from = nullptr,
                   bool tls = true)
      : context_(boost::asio::ssl::context::tls_client), stream_(io_, context_) {
    boost::system::error_code ec;
    tcp::socket& socket = stream_.next_layer();
    socket.open(tcp::v4(), ec);
    if (receiveBuffer > 0)
      socket.set_option(boost::asio::socket_base::receive_buffer_size(receiveBuffer), ec);
    if (from) socket.bind({boost::asio::ip::make_address(from), 0}, ec);
    EXPECT_FALSE(ec) << ec.message();
    socket.connect({boost::asio::ip::make_address("127.0.0.1"), port}, ec);
    EXPECT_FALSE(ec) << ec.message();
    if (tls && !ec) {
      stream_.set_verify_mode(boost::asio::ssl::verify_none);
      stream_.handshake(boost::asio::ssl::stream_base::client, ec);
      EXPECT_FALSE(ec) << "TLS handshake: " << ec.message();
      tls_ = !ec;
    }
  }
  void send(const std::vector<std::uint8_t>& bytes) {
    boost::system::error_code ec;
    if (tls_) {
      boost::asio::write(stream_, boost::asio::buffer(bytes), ec);
    } else {
      boost::asio::write(stream_.next_layer(), boost::asio::buffer(bytes), ec);
    }
  }
  // The next frame, or nothing at end of stream / error / `timeout`.
  std::optional<std::vector<std::uint8_t>> readFrame(double timeout = 10.0) {
    std::array<std::uint8_t, 4> prefix{};
    if (!readExactly(prefix.data(), 4, timeout)) return std::nullopt;
    auto size = frameSize(prefix, 64u << 20);
    if (!size) return std::nullopt;
    std::vector<std::uint8_t> frame(prefix.begin(), prefix.end());
    frame.resize(*size);
    if (!readExactly(frame.data() + 4, *size - 4, timeout)) return std::nullopt;
    return frame;
  }
  // True when the server closed the connection within `timeout` (skipping what it still sends).
  bool closedByServer(double timeout = 10.0) { return bytesUntilClosed(timeout).has_value(); }
  // The bytes the server sent until it closed the connection; nothing when it did not close
  // it within `timeout`.
  std::optional<std::size_t> bytesUntilClosed(double timeout = 10.0) {
    const double start = steadySeconds();
    std::array<std::uint8_t, 4096> sink{};
    std::size_t total = 0;
    while (steadySeconds() - start < timeout) {
      if (!waitReadable(0.05)) continue;
      boost::system::error_code ec;
      const std::size_t n = readSome(sink.data(), sink.size(), ec);
      total += n;
      if (ec || n == 0) return total;
    }
    return std::nullopt;
  }
  // The TCP socket under the stream.
  tcp::socket& socket() { return stream_.next_layer(); }

 private:
  // Readable: bytes on the socket, or (TLS) a decrypted record already buffered.
  bool waitReadable(double seconds) {
    if (tls_ && SSL_pending(stream_.native_handle()) > 0) return true;
    pollfd p{stream_.next_layer().native_handle(), POLLIN, 0};
    return ::poll(&p, 1, int(seconds * 1000)) > 0;
  }
  std::size_t readSome(std::uint8_t* out, std::size_t n, boost::system::error_code& ec) {
    if (tls_) return stream_.read_some(boost::asio::buffer(out, n), ec);
    return stream_.next_layer().read_some(boost::asio::buffer(out, n), ec);
  }
  bool readExactly(std::uint8_t* out, std::size_t n, double timeout) {
    const double start = steadySeconds();
    std::size_t got = 0;
    while (got < n) {
      if (steadySeconds() - start > timeout) return false;
      if (!waitReadable(0.05)) continue;
      boost::system::error_code ec;
      const std::size_t r = readSome(out + got, n - got, ec);
      if (ec || r == 0) return false;
      got += r;
    }
    return true;
  }

  boost::asio::io_context io_;
  boost::asio::ssl::context context_;
  boost::asio::ssl::stream<tcp::socket> stream_;
  bool tls_ = false;
};

inline std::vector<std::uint8_t> helloFrame(const std::string& token, bool udp = false,
                                            std::uint32_t version = kProtocolVersion) {
  HelloMsg h;
  h.protocolVersion = version;
  h.authToken = token;
  h.clientName = "raw";
  h.wantsUdp = udp;
  return encodeMessage(h);
}

}  // namespace pc::nettest
