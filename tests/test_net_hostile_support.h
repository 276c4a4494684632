// Shared by the tests of hostile peers (test_net_hostile.cpp, test_net_limits.cpp): a real
// server with one well-behaved client synced before the abuse starts, and a fake server for
// the client's side.
#pragma once

#include <functional>

#include "test_net_support.h"

namespace pc::nettest {

// A client of the server whose certificate has `fingerprint`; without one, a client without
// TLS (for the plain fake servers below).
inline client::NetClientOptions goodOptions(std::uint16_t port,
                                            const std::string& fingerprint = {}) {
  client::NetClientOptions o;
  o.host = "127.0.0.1";
  o.port = port;
  o.serverFingerprint = fingerprint;
  o.tls = !fingerprint.empty();
  o.token = issueTestToken("good");  // the server knows a client by its token's name
  o.name = "good";
  return o;
}

// A server whose field never freezes (updates keep flowing) with one well-behaved client,
// synced before the abuse starts.
class HostileFixture {
 public:
  explicit HostileFixture(NetServerOptions options = {})
      : server_(-1.0, options), good_(mirror_, goodOptions(server_.port(), server_.fingerprint())) {
    good_.start();
    EXPECT_TRUE(waitFor([&] { return good_.stats().synced; }, 20.0))
        << "the good client never synced";
  }

  TestServer& server() { return server_; }
  NetServerStats stats() { return server_.net().stats(); }
  std::uint16_t port() { return server_.port(); }

  // Waits until `cause` has been counted `n` times; then no other cause may have been counted
  // (every connection of the test but the good client's is an abuser's).
  void expectOnlyCause(DisconnectCause cause, std::uint64_t n) {
    EXPECT_TRUE(waitFor([&] { return stats().disconnectsBy(cause) >= n; }, 10.0))
        << "cause " << causeName(cause) << " counted " << stats().disconnectsBy(cause)
        << " times, expected " << n;
    const NetServerStats s = stats();
    for (std::size_t c = 0; c < kDisconnectCauses; ++c) {
      const std::uint64_t expected = DisconnectCause(c) == cause ? n : 0;
      EXPECT_EQ(s.disconnects[c], expected) << "cause " << causeName(DisconnectCause(c));
    }
  }

  // The good client noticed nothing: still its first session, synced, and receiving.
  void expectGoodClientUnaffected() {
    const std::uint64_t before = good_.stats().udpDatagrams;
    EXPECT_TRUE(waitFor([&] { return good_.stats().udpDatagrams > before + 5; }, 5.0))
        << "the good client stopped receiving";
    const client::NetClientStats s = good_.stats();
    EXPECT_TRUE(s.connected);
    EXPECT_TRUE(s.synced);
    EXPECT_EQ(s.sessions, 1u);
    const NetServerStats ss = stats();
    ASSERT_EQ(ss.clients.size(), 1u);
    EXPECT_EQ(ss.clients[0].name, "good");
  }

 private:
  TestServer server_;
  client::FieldMirror mirror_;
  client::NetClient good_;
};

inline SessionInfoMsg builtinInfo() {
  const Scene scene = builtinScene();
  // The layout TestServer serves.
  const Field field =
      Field::create(scene.volumes.empty() ? defaultVolumes(scene) : scene.volumes, FieldSettings{});
  return sessionInfoFor(field);
}

// A fake server: accepts one connection at a time, reads the Hello, answers what `reply` says
// for that connection (0, 1, ...; by default Welcome of session 7 and the given SessionInfo),
// then holds the connection open (sending nothing) until the next accept.
class FakeServer {
 public:
  using Reply = std::function<std::vector<std::uint8_t>(int connection)>;
  explicit FakeServer(SessionInfoMsg info) : FakeServer(welcomeWith(std::move(info))) {}
  explicit FakeServer(Reply reply)
      : acceptor_(io_, {boost::asio::ip::make_address("127.0.0.1"), 0}), reply_(std::move(reply)) {
    thread_ = std::thread([this] { run(); });
  }
  static Reply welcomeWith(SessionInfoMsg info) {
    return [info = std::move(info)](int) {
      std::vector<std::uint8_t> out = encodeMessage(WelcomeMsg{kProtocolVersion, 7});
      const std::vector<std::uint8_t> encoded = encodeMessage(info);
      out.insert(out.end(), encoded.begin(), encoded.end());
      return out;
    };
  }
  int connections() const { return connections_; }
  ~FakeServer() {
    // A blocking accept does not return when another thread closes the acceptor: wake it
    // with one more connection, which it sees after the stop flag.
    stop_ = true;
    boost::asio::io_context io;
    boost::asio::ip::tcp::socket wake(io);
    boost::system::error_code ec;
    wake.connect({boost::asio::ip::make_address("127.0.0.1"), port()}, ec);
    thread_.join();
  }
  std::uint16_t port() const { return acceptor_.local_endpoint().port(); }

 private:
  void run() {
    std::vector<boost::asio::ip::tcp::socket> held;
    while (!stop_) {
      boost::system::error_code ec;
      boost::asio::ip::tcp::socket socket(io_);
      acceptor_.accept(socket, ec);
      if (ec || stop_) return;
      std::array<std::uint8_t, 4> prefix{};
      boost::asio::read(socket, boost::asio::buffer(prefix), ec);
      auto size = frameSize(prefix, 4096);
      if (ec || !size) continue;
      std::vector<std::uint8_t> rest(*size - 4);
      boost::asio::read(socket, boost::asio::buffer(rest), ec);
      const std::vector<std::uint8_t> out = reply_(connections_++);
      boost::asio::write(socket, boost::asio::buffer(out), ec);
      held.push_back(std::move(socket));
    }
  }

  boost::asio::io_context io_;
  boost::asio::ip::tcp::acceptor acceptor_;
  Reply reply_;
  std::atomic<int> connections_{0};
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace pc::nettest
