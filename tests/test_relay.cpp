// Field distribution through NATS JetStream: the field server's exporter puts its field into a
// key-value bucket, relays follow it and serve clients with the server's own network layer.
// Each test starts its own nats-server (JetStream in a temporary folder, a free loopback port)
// and skips where the nats-server binary is absent. The field server runs in the test's
// process (the built-in scene on Embree, as the socket tests run it); relays run in-process or
// as probecast-relay processes, and clients are the real client's network side (NetClient).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "loadgen/load_generator.h"
#include "net/tls_certificate.h"
#include "relay/field_bucket.h"
#include "relay/field_export.h"
#include "relay/relay.h"
#include "test_child_process.h"
#include "test_net_support.h"

namespace pc {
namespace {

namespace fs = std::filesystem;
using nettest::kToken;
using nettest::mirrorDifference;
using nettest::sleepFor;
using nettest::testKeys;
using nettest::TestServer;
using nettest::waitFor;

const std::string kBin = std::string(PC_BUILD_DIR) + "/bin/";
const char* const kNatsServer = "/usr/sbin/nats-server";

bool natsServerPresent() { return fs::exists(kNatsServer); }

// A nats-server with JetStream on a free loopback port, its store in `dir` (so a restart on
// the same port and folder finds the bucket again).
class NatsServer {
 public:
  // `config`: more of nats-server's configuration (users, say), written to a file beside.
  explicit NatsServer(const fs::path& dir, const std::string& config = "")
      : dir_(dir), port_(test::freePort()) {
    std::ofstream(dir_ / "nats.conf") << config;
    start();
  }
  void start() {
    fs::create_directories(dir_ / "store");
    child_ = std::make_unique<test::Child>(
        std::vector<std::string>{kNatsServer, "-c", (dir_ / "nats.conf").string(), "-a",
                                 "127.0.0.1", "-p", std::to_string(port_), "-js", "-sd",
                                 (dir_ / "store").string()},
        dir_ / "nats.log");
    EXPECT_TRUE(waitFor([&] { return test::canConnect(port_); }, 20.0))
        << "nats-server never listened";
  }
  void kill() { child_.reset(); }  // SIGKILL
  std::string url(const std::string& user = "") const {
    return "nats://" + user + (user.empty() ? "" : "@") + "127.0.0.1:" + std::to_string(port_);
  }

 private:
  fs::path dir_;
  std::uint16_t port_;
  std::unique_ptr<test::Child> child_;
};

fs::path testDir(const std::string& name) {
  const fs::path dir = fs::path(PC_BUILD_DIR) / ("test-relay-" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

std::unique_ptr<pc::relay::FieldExporter> startExporter(FieldHub& hub, const std::string& url) {
  pc::relay::ExportOptions o;
  o.nats.urls = url;
  auto exporter = pc::relay::FieldExporter::create(hub, o);
  EXPECT_TRUE(exporter.ok()) << (exporter ? "" : exporter.error().message);
  if (!exporter) return nullptr;
  (*exporter)->start();
  return std::move(exporter).value();
}

std::string readText(const fs::path& p) {
  std::ifstream in(p);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// A relay on loopback with a development certificate, not started.
std::unique_ptr<pc::relay::Relay> makeRelay(const std::string& url, const std::string& id) {
  pc::relay::RelayOptions o;
  o.nats.urls = url;
  o.relayId = id;
  o.net.bindAddress = "127.0.0.1";
  o.net.port = 0;
  o.net.tokenKeys = {testKeys().verify};
  o.net.tls.devSelfSigned = true;
  auto relay = pc::relay::Relay::create(o);
  EXPECT_TRUE(relay.ok()) << (relay ? "" : relay.error().message);
  return relay ? std::move(relay).value() : nullptr;
}

std::unique_ptr<pc::relay::Relay> startRelay(const std::string& url, const std::string& id) {
  auto relay = makeRelay(url, id);
  if (!relay) return nullptr;
  const Status started = relay->start(30.0);
  EXPECT_TRUE(started.ok()) << (started ? "" : started.error().message);
  return relay;
}

client::NetClientOptions clientOptions(std::uint16_t port, const std::string& fingerprint) {
  client::NetClientOptions o;
  o.host = "127.0.0.1";
  o.port = port;
  o.serverFingerprint = fingerprint;
  o.token = kToken;
  o.name = "relay-test";
  return o;
}

// Every brick's current version in a hub, [cascade][brick].
std::vector<std::vector<std::uint64_t>> versionsOf(const FieldHub& hub) {
  std::vector<std::vector<std::uint64_t>> v;
  const FieldPublisher& p = const_cast<FieldHub&>(hub).publisher();
  for (int k = 0; k < p.cascadeCount(); ++k) {
    v.emplace_back();
    for (int b = 0; b < p.brickCount(k); ++b) v.back().push_back(p.current(k, b).version);
  }
  return v;
}

// Two probecast-relay processes ("a" and "b") of one field, presenting one certificate
// (`cert`, which clients take as their CA file) and verifying the tests' token key, with the
// per-address and per-token caps off (every test client comes from 127.0.0.1 with one token).
struct RelayPair {
  RelayPair(const fs::path& dir, const std::string& natsUrl)
      : keyFile((dir / "issuer.pub").string()),
        cert((dir / "cert.pem").string()),
        key((dir / "key.pem").string()),
        portA(test::freePort()),
        portB(test::freePort()) {
    EXPECT_TRUE(writeKeyFile(keyFile, testKeys().verify).ok());
    auto dev = net::makeDevCertificate();
    EXPECT_TRUE(dev.ok());
    std::ofstream(cert) << dev->certificatePem;
    std::ofstream(key) << dev->keyPem;
    auto relay = [&](const std::string& id, std::uint16_t port) {
      return std::make_unique<test::Child>(
          std::vector<std::string>{kBin + "probecast-relay",
                                   "--nats",
                                   natsUrl,
                                   "--relay-id",
                                   id,
                                   "--bind",
                                   "127.0.0.1",
                                   "--port",
                                   std::to_string(port),
                                   "--token-key",
                                   keyFile,
                                   "--tls-cert",
                                   cert,
                                   "--tls-key",
                                   key,
                                   "--stats-interval",
                                   "0",
                                   "--max-clients",
                                   "256",
                                   "--max-sessions-per-address",
                                   "0",
                                   "--max-pending-per-address",
                                   "0",
                                   "--handshakes-per-second-per-address",
                                   "0",
                                   "--max-sessions-per-client",
                                   "0"},
          dir / ("relay-" + id + ".log"));
    };
    a = relay("a", portA);
    b = relay("b", portB);
  }
  bool listening() const {
    return waitFor([&] { return test::canConnect(portA) && test::canConnect(portB); }, 30.0);
  }
  std::string keyFile, cert, key;
  std::uint16_t portA, portB;
  std::unique_ptr<test::Child> a, b;
};

// A field server whose field freezes, exported through its own nats-server to a RelayPair.
struct FrozenFieldThroughTwoRelays {
  explicit FrozenFieldThroughTwoRelays(const std::string& name)
      : dir(testDir(name)),
        nats(dir),
        server(0.8),
        exporter(startExporter(server.hub(), nats.url())) {}
  // The field frozen and both relays listening; false, with a failure added, otherwise.
  bool start() {
    if (!exporter || !waitFor([&] { return server.frozen(); }, 60.0)) {
      ADD_FAILURE() << "no field exported";
      return false;
    }
    relays = std::make_unique<RelayPair>(dir, nats.url());
    if (relays->listening()) return true;
    ADD_FAILURE() << "the relays never listened (see " << dir.string() << ")";
    return false;
  }
  fs::path dir;
  NatsServer nats;
  TestServer server;
  std::unique_ptr<pc::relay::FieldExporter> exporter;  // goes before the hub it follows
  std::unique_ptr<RelayPair> relays;
};

TEST(FieldBucket, RecordsRoundTripAndRefuseOtherBytes) {
  pc::relay::BrickRecord b;
  b.epoch = 77;
  b.cascade = 2;
  b.brick = 513;
  b.version = 9;
  b.wallTime = 1.5e9;
  b.payload = {1, 2, 3, 4};
  auto back = pc::relay::decodeBrickRecord(pc::relay::encodeBrickRecord(b));
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->epoch, 77u);
  EXPECT_EQ(back->cascade, 2);
  EXPECT_EQ(back->brick, 513u);
  EXPECT_EQ(back->version, 9u);
  EXPECT_EQ(back->payload, b.payload);
  std::vector<std::uint8_t> bytes = pc::relay::encodeBrickRecord(b);
  bytes.resize(20);
  EXPECT_FALSE(pc::relay::decodeBrickRecord(bytes).ok());
  EXPECT_FALSE(pc::relay::decodeCatalogue(pc::relay::encodeBrickRecord(b)).ok());  // another kind
  EXPECT_EQ(pc::relay::parseBrickKey(pc::relay::brickKey(3, 70)),
            std::make_pair(3, std::uint32_t(70)));
  EXPECT_FALSE(pc::relay::parseBrickKey("brick.1.2.3").has_value());
  EXPECT_FALSE(pc::relay::parseBrickKey("state").has_value());

  pc::relay::PosesMessage poses;
  poses.relay = "r1";
  poses.positions = {{1, 2, 3}, {NAN, 0, 0}, {4, 5, 6}};
  poses.weights = {1, 1, 2};
  auto decoded = pc::relay::decodePoses(pc::relay::encodePoses(poses));
  ASSERT_TRUE(decoded.ok());
  ASSERT_EQ(decoded->positions.size(), 2u);  // the NaN position is left out
  EXPECT_EQ(decoded->positions[1], glm::vec3(4, 5, 6));
  EXPECT_EQ(decoded->weights[1], 2.0f);
  auto load = pc::relay::decodeLoad(pc::relay::encodeLoad({"r1", "10.0.0.1:7450", 12, 64}));
  ASSERT_TRUE(load.ok());
  EXPECT_EQ(load->clients, 12u);
  EXPECT_EQ(load->endpoint, "10.0.0.1:7450");
  EXPECT_FALSE(pc::relay::validToken("a.b"));
  EXPECT_FALSE(pc::relay::validToken("*"));
}

// A relay started after the field server has published (and frozen) its field catches up from
// the bucket, holds every brick at the server's version, and its client converges to the same
// field as a client of the server itself.
TEST(Relay, StartsLateCatchesUpAndServesTheServersField) {
  if (!natsServerPresent()) GTEST_SKIP() << "nats-server is not installed (" << kNatsServer << ")";
  const fs::path dir = testDir("catch-up");
  NatsServer nats(dir);
  TestServer server(0.8);
  auto exporter = startExporter(server.hub(), nats.url());
  ASSERT_TRUE(exporter);
  ASSERT_TRUE(waitFor([&] { return server.frozen(); }, 60.0));
  const std::uint64_t frozenVersion = server.field().version;
  ASSERT_TRUE(waitFor([&] { return exporter->stats().fieldVersion == frozenVersion; }, 20.0))
      << exporter->stats().lastError;

  auto relay = startRelay(nats.url(), "late");
  ASSERT_TRUE(relay);
  std::vector<std::vector<std::uint64_t>> relayVersions, serverVersions;
  ASSERT_TRUE(waitFor([&] { return relay->stats().fieldVersion == frozenVersion; }, 20.0));
  ASSERT_TRUE(relay->withHub([&](const FieldHub& h) { relayVersions = versionsOf(h); }));
  {
    auto lock = server.hub().lock();
    serverVersions = versionsOf(server.hub());
  }
  EXPECT_EQ(relayVersions, serverVersions);

  client::FieldMirror direct, relayed;
  client::NetClient directClient(direct, clientOptions(server.port(), server.fingerprint()));
  client::NetClient relayClient(relayed, clientOptions(relay->port(), relay->tlsFingerprint()));
  directClient.start();
  relayClient.start();
  EXPECT_TRUE(waitFor([&] { return mirrorDifference(direct, server.field()) == 0; }, 30.0));
  EXPECT_TRUE(waitFor([&] { return mirrorDifference(relayed, server.field()) == 0; }, 30.0))
      << mirrorDifference(relayed, server.field()) << " bricks differ";
  const client::NetClientStats d = directClient.stats(), r = relayClient.stats();
  EXPECT_TRUE(r.synced);
  EXPECT_EQ(r.serverFieldVersion, d.serverFieldVersion);
  EXPECT_EQ(r.sessions, 1u);
  const pc::relay::RelayStats rs = relay->stats();
  EXPECT_EQ(rs.badRecords, 0u);
  EXPECT_GT(rs.bricksApplied, 0u);
  std::printf("FIGURE relay_catch_up bricks=%llu nats_latency_ms=%.1f\n",
              (unsigned long long)rs.bricksApplied, rs.natsLatencyMs);
  // The relay's client's viewer reaches the field server's scheduler (through the relay's
  // pose messages); the direct client has none.
  const glm::vec3 eye(0.25f, 0.5f, 0.75f);
  relayClient.setViewer(eye, glm::quat(1, 0, 0, 0));
  EXPECT_TRUE(waitFor(
      [&] {
        const std::vector<glm::vec3> viewers = server.hub().viewers();
        return viewers.size() == 1 && viewers[0] == eye;
      },
      5.0));
  EXPECT_GT(exporter->stats().poseMessages, 0u);
}

// Two probecast-relay processes; clients given both endpoints are on the first when it is
// killed (SIGKILL: no goodbye). Each moves to the other relay and resyncs, and its mirror
// holds the server's field at every moment of the move.
TEST(Relay, ClientsOfAKilledRelayMoveToTheOtherAndKeepTheirField) {
  if (!natsServerPresent()) GTEST_SKIP() << "nats-server is not installed (" << kNatsServer << ")";
  ASSERT_TRUE(fs::exists(kBin + "probecast-relay")) << "probecast-relay is not built";
  FrozenFieldThroughTwoRelays setup("kill");
  ASSERT_TRUE(setup.start());
  const TestServer& server = setup.server;
  RelayPair& relays = *setup.relays;
  const std::string& cert = relays.cert;
  const std::uint16_t portA = relays.portA, portB = relays.portB;
  auto& relayA = relays.a;

  constexpr int kClients = 3;
  std::vector<std::unique_ptr<client::FieldMirror>> mirrors;
  std::vector<std::unique_ptr<client::NetClient>> clients;
  for (int i = 0; i < kClients; ++i) {
    client::NetClientOptions o = clientOptions(portA, "");
    o.caFile = cert;
    o.alternates = {{"127.0.0.1", portB}};
    // The endpoints in the order given, so that every client starts on a (choosing by load is
    // NewClientsGoToTheLessLoadedRelayAndLeaveAKilledOne's).
    o.loadProbeTimeout = 0;
    mirrors.push_back(std::make_unique<client::FieldMirror>());
    clients.push_back(std::make_unique<client::NetClient>(*mirrors.back(), o));
    clients.back()->start();
  }
  const std::string endpointB = "127.0.0.1:" + std::to_string(portB);
  for (int i = 0; i < kClients; ++i) {
    ASSERT_TRUE(waitFor([&] { return mirrorDifference(*mirrors[i], server.field()) == 0; }, 30.0))
        << "client " << i << " never converged through relay a";
    ASSERT_NE(clients[i]->stats().endpoint, endpointB);
  }

  // What each client received through relay a: the whole field, and a little since.
  auto received = [&](int i) {
    const client::NetClientStats st = clients[i]->stats();
    return double(st.tcpBytes + st.udpBytes);
  };
  std::vector<double> bytesAtKill(kClients);
  for (int i = 0; i < kClients; ++i) bytesAtKill[i] = received(i);
  relayA->kill(SIGKILL);
  const double killed = steadySeconds();
  std::vector<double> movedAfter(kClients, -1);
  int worstDifference = 0;
  while (steadySeconds() - killed < 30.0) {
    bool all = true;
    for (int i = 0; i < kClients; ++i) {
      // The mirror is what the client renders: it must hold the field throughout.
      worstDifference = std::max(worstDifference, mirrorDifference(*mirrors[i], server.field()));
      const client::NetClientStats st = clients[i]->stats();
      if (movedAfter[i] < 0 && st.synced && st.endpoint == endpointB)
        movedAfter[i] = steadySeconds() - killed;
      all &= movedAfter[i] >= 0;
    }
    if (all) break;
    sleepFor(0.01);
  }
  double failover = 0;
  for (int i = 0; i < kClients; ++i) {
    EXPECT_GE(movedAfter[i], 0.0) << "client " << i << " never resynced on relay b";
    failover = std::max(failover, movedAfter[i]);
    EXPECT_EQ(clients[i]->stats().sessions, 2u);
  }
  EXPECT_EQ(worstDifference, 0) << "a mirror lost bricks while its client moved";
  for (int i = 0; i < kClients; ++i)
    EXPECT_EQ(mirrorDifference(*mirrors[i], server.field()), 0) << "client " << i;
  // Relays of one field server share its epoch and versions: the clients resumed, and relay b
  // sent them nothing of the (frozen) field they held, where a new session sends it whole.
  sleepFor(0.5);
  for (int i = 0; i < kClients; ++i) {
    const double moved = received(i) - bytesAtKill[i];
    std::printf("client %d: %.0f bytes through relay a, %.0f from the kill on\n", i, bytesAtKill[i],
                moved);
    EXPECT_LT(moved, 0.25 * bytesAtKill[i]) << "client " << i << " was sent its field again";
  }
  std::printf("FIGURE relay_failover clients=%d failover_s=%.3f\n", kClients, failover);
}

// The NATS server is killed and started again (same port, same store) while the field moves:
// the relay keeps its client in session, serving what it holds, and follows the field again
// once NATS is back. With the bucket in memory (--nats-memory) the restart loses it: the field
// server makes it again and puts its whole field, and the relay catches up from it, the same
// run's field (no new epoch), its client still in the same session.
void natsRestartKeepsServing(const std::string& name, bool memoryBucket) {
  const fs::path dir = testDir(name);
  NatsServer nats(dir);
  TestServer server(-1.0);  // never frozen: new versions keep coming
  pc::relay::ExportOptions eo;
  eo.nats.urls = nats.url();
  eo.bucket.memoryStorage = memoryBucket;
  auto exporter = pc::relay::FieldExporter::create(server.hub(), eo);
  ASSERT_TRUE(exporter.ok()) << exporter.error().message;
  (*exporter)->start();
  auto relay = startRelay(nats.url(), "steady");
  ASSERT_TRUE(relay);
  client::FieldMirror mirror;
  client::NetClient client(mirror, clientOptions(relay->port(), relay->tlsFingerprint()));
  client.start();
  ASSERT_TRUE(waitFor([&] { return client.stats().synced; }, 30.0));

  const std::uint64_t republished = (*exporter)->stats().republishes;
  nats.kill();
  sleepFor(0.3);  // what the relay had received by the kill is committed by now
  const std::uint64_t before = relay->stats().fieldVersion;
  sleepFor(2.2);
  EXPECT_TRUE(client.stats().connected) << "the relay dropped its client while NATS was away";
  EXPECT_TRUE(relay->stats().serving);
  EXPECT_EQ(relay->serverStats().clients.size(), 1u);
  EXPECT_TRUE(mirror.present());
  // It serves the versions it held: nothing newer came, nothing was lost.
  EXPECT_EQ(relay->stats().fieldVersion, before);
  EXPECT_EQ(client.stats().serverFieldVersion, before);

  nats.start();
  ASSERT_TRUE(waitFor([&] { return relay->stats().fieldVersion > before + 2; }, 30.0))
      << "the relay never followed the field again: " << relay->stats().lastError;
  EXPECT_TRUE(waitFor([&] { return client.stats().serverFieldVersion > before + 2; }, 10.0));
  const client::NetClientStats c = client.stats();
  EXPECT_EQ(c.sessions, 1u) << "the client's session should have survived the NATS restart";
  EXPECT_TRUE(c.connected);
  EXPECT_TRUE((*exporter)->stats().connected);
  EXPECT_EQ(relay->stats().epochChanges, 0u);
  // The bucket was made again, and the whole field put into it.
  if (memoryBucket) {
    EXPECT_GT((*exporter)->stats().republishes, republished);
  }
  std::printf("FIGURE relay_nats_restart%s watch_restarts=%llu republishes=%llu\n",
              memoryBucket ? "_memory" : "", (unsigned long long)relay->stats().watchRestarts,
              (unsigned long long)(*exporter)->stats().republishes);
  relay.reset();
  exporter->reset();
}

TEST(Relay, KeepsServingThroughANatsRestartAndResumes) {
  if (!natsServerPresent()) GTEST_SKIP() << "nats-server is not installed (" << kNatsServer << ")";
  natsRestartKeepsServing("nats-restart", false);
}

TEST(Relay, KeepsServingThroughANatsRestartThatLosesAMemoryBucket) {
  if (!natsServerPresent()) GTEST_SKIP() << "nats-server is not installed (" << kNatsServer << ")";
  natsRestartKeepsServing("nats-restart-memory", true);
}

// The relay starts before the field server: first there is no bucket, then an empty one (the
// field server making it; longer than a watch's silence), then the field. The relay waits
// through both and serves the field once it comes, every brick at the server's version.
TEST(Relay, StartedBeforeTheFieldServerServesItsFieldOnceItComes) {
  if (!natsServerPresent()) GTEST_SKIP() << "nats-server is not installed (" << kNatsServer << ")";
  const fs::path dir = testDir("early");
  NatsServer nats(dir);
  auto relay = makeRelay(nats.url(), "early");
  ASSERT_TRUE(relay);
  Status started = Error{"not yet"};
  std::thread starter([&] { started = relay->start(60.0); });
  sleepFor(1.0);  // no bucket
  pc::relay::NatsOptions no;
  no.urls = nats.url();
  auto maker = pc::relay::NatsConnection::connect(no);
  ASSERT_TRUE(maker.ok()) << maker.error().message;
  ASSERT_TRUE(maker->createBucket(pc::relay::ExportOptions{}.bucket).ok());
  sleepFor(2.5);  // an empty bucket, watched
  EXPECT_FALSE(relay->stats().serving);

  TestServer server(0.8);
  auto exporter = startExporter(server.hub(), nats.url());
  ASSERT_TRUE(exporter);
  starter.join();
  ASSERT_TRUE(started.ok()) << started.error().message;
  ASSERT_TRUE(waitFor([&] { return server.frozen(); }, 60.0));
  const std::uint64_t frozenVersion = server.field().version;
  ASSERT_TRUE(waitFor([&] { return relay->stats().fieldVersion == frozenVersion; }, 20.0))
      << relay->stats().lastError;
  std::vector<std::vector<std::uint64_t>> relayVersions, serverVersions;
  ASSERT_TRUE(relay->withHub([&](const FieldHub& h) { relayVersions = versionsOf(h); }));
  {
    auto lock = server.hub().lock();
    serverVersions = versionsOf(server.hub());
  }
  EXPECT_EQ(relayVersions, serverVersions);
  client::FieldMirror mirror;
  client::NetClient c(mirror, clientOptions(relay->port(), relay->tlsFingerprint()));
  c.start();
  EXPECT_TRUE(waitFor([&] { return mirrorDifference(mirror, server.field()) == 0; }, 30.0))
      << mirrorDifference(mirror, server.field()) << " bricks differ";
  relay.reset();
  exporter.reset();
}

// The field server is stopped and another run starts (a new epoch, another field): the relay
// takes the new run's catalogue, makes its server again on the same port and certificate, and
// its client reconnects and converges to the new field.
TEST(Relay, FollowsARestartedFieldServer) {
  if (!natsServerPresent()) GTEST_SKIP() << "nats-server is not installed (" << kNatsServer << ")";
  const fs::path dir = testDir("server-restart");
  NatsServer nats(dir);
  auto first = std::make_unique<TestServer>(0.8);
  auto exporter = startExporter(first->hub(), nats.url());
  ASSERT_TRUE(exporter);
  ASSERT_TRUE(waitFor([&] { return first->frozen(); }, 60.0));
  auto relay = startRelay(nats.url(), "follower");
  ASSERT_TRUE(relay);
  const std::uint16_t port = relay->port();
  client::FieldMirror mirror;
  client::NetClient client(mirror, clientOptions(port, relay->tlsFingerprint()));
  client.start();
  ASSERT_TRUE(waitFor([&] { return mirrorDifference(mirror, first->field()) == 0; }, 30.0));
  const std::uint64_t held = relay->stats().fieldVersion;
  exporter.reset();
  first.reset();
  // No field server for longer than a watch's silence: the relay serves what it holds.
  sleepFor(2.5);
  EXPECT_TRUE(relay->stats().serving);
  EXPECT_EQ(relay->stats().fieldVersion, held);
  EXPECT_TRUE(client.stats().connected);
  EXPECT_EQ(client.stats().sessions, 1u);

  TestServer second(1.6);  // another moment of the animation: another field
  exporter = startExporter(second.hub(), nats.url());
  ASSERT_TRUE(exporter);
  ASSERT_TRUE(waitFor([&] { return second.frozen(); }, 60.0));
  ASSERT_NE(mirrorDifference(mirror, second.field()), 0) << "both runs made the same field";
  EXPECT_TRUE(waitFor([&] { return mirrorDifference(mirror, second.field()) == 0; }, 30.0))
      << "the relay's client never got the new run's field: " << relay->stats().lastError;
  const pc::relay::RelayStats rs = relay->stats();
  EXPECT_EQ(rs.epochChanges, 1u);
  EXPECT_EQ(rs.epoch, exporter->stats().epoch);
  EXPECT_EQ(relay->port(), port);
  EXPECT_EQ(client.stats().sessions, 2u);
  exporter.reset();  // before the hub it follows
}

// NATS users as deploy/local makes them: the field server's may do anything, a relay's has the
// permissions of deploy/nats-relay-permissions.conf. The relay catches up, serves and reports
// its viewers under them, and NATS refuses it anything else: writing into the field's bucket,
// making a bucket.
TEST(Relay, ARelaysNatsUserReadsTheFieldAndWritesNothingButPosesAndLoad) {
  if (!natsServerPresent()) GTEST_SKIP() << "nats-server is not installed (" << kNatsServer << ")";
  const fs::path dir = testDir("permissions");
  fs::copy_file(fs::path(PC_SOURCE_DIR) / "deploy/nats-relay-permissions.conf",
                dir / "nats-relay-permissions.conf");
  NatsServer nats(dir, R"(authorization {
  users = [
    { user: field, password: "field-secret" }
    { user: relay, password: "relay-secret", permissions: { include "nats-relay-permissions.conf" } }
  ]
})");
  TestServer server(0.8);
  auto exporter = startExporter(server.hub(), nats.url("field:field-secret"));
  ASSERT_TRUE(exporter);
  ASSERT_TRUE(waitFor([&] { return server.frozen(); }, 60.0));
  auto relay = startRelay(nats.url("relay:relay-secret"), "restricted");
  ASSERT_TRUE(relay);
  EXPECT_TRUE(waitFor([&] { return relay->stats().fieldVersion == server.field().version; }, 20.0));
  EXPECT_TRUE(waitFor([&] { return exporter->stats().poseMessages > 0; }, 5.0));
  EXPECT_TRUE(waitFor([&] { return !exporter->stats().relays.empty(); }, 5.0));
  EXPECT_EQ(readText(dir / "nats.log").find("Violation"), std::string::npos)
      << "NATS refused the relay something it needs:\n"
      << readText(dir / "nats.log");

  pc::relay::NatsOptions o;  // the relay's user again, its password from a file this time
  o.urls = nats.url();
  o.user = "relay";
  o.passwordFile = (dir / "relay.password").string();
  std::ofstream(o.passwordFile) << "relay-secret\n";
  auto intruder = pc::relay::NatsConnection::connect(o);
  ASSERT_TRUE(intruder.ok()) << intruder.error().message;
  auto bucket = intruder->openBucket("probecast-field");
  ASSERT_TRUE(bucket.ok()) << bucket.error().message;  // reading is allowed
  const std::vector<std::uint8_t> forged{1, 2, 3};
  EXPECT_FALSE(bucket->put(pc::relay::brickKey(0, 0), forged).ok());
  pc::relay::BucketOptions other;
  other.name = "another";
  EXPECT_FALSE(intruder->createBucket(other).ok());
  relay.reset();
  exporter.reset();
}

// A three-node NATS cluster with the bucket on every node (3 replicas); one node is killed
// while the field moves: the field server and the relay move to the other nodes and the relay
// goes on following the field, its client in session throughout.
TEST(Relay, GoesOnWhenOneNodeOfAThreeNodeNatsClusterIsLost) {
  if (!natsServerPresent()) GTEST_SKIP() << "nats-server is not installed (" << kNatsServer << ")";
  const fs::path dir = testDir("cluster");
  std::vector<std::uint16_t> clientPorts, routePorts;
  for (int i = 0; i < 3; ++i) {
    clientPorts.push_back(test::freePort());
    routePorts.push_back(test::freePort());
  }
  std::string urls;
  std::vector<std::unique_ptr<test::Child>> nodes;
  for (int i = 0; i < 3; ++i) {
    const fs::path node = dir / ("n" + std::to_string(i));
    fs::create_directories(node);
    std::string routes;
    for (int j = 0; j < 3; ++j)
      if (j != i)
        routes += std::string(routes.empty() ? "" : ", ") +
                  "nats-route://127.0.0.1:" + std::to_string(routePorts[std::size_t(j)]);
    std::ofstream(node / "nats.conf")
        << "server_name: n" << i << "\nlisten: 127.0.0.1:" << clientPorts[std::size_t(i)]
        << "\njetstream { store_dir: \"" << (node / "store").string() << "\" }\n"
        << "cluster { name: probecast, listen: 127.0.0.1:" << routePorts[std::size_t(i)]
        << ", routes: [" << routes << "] }\n";
    nodes.push_back(std::make_unique<test::Child>(
        std::vector<std::string>{kNatsServer, "-c", (node / "nats.conf").string()},
        node / "nats.log"));
    urls += (i ? "," : "") + std::string("nats://127.0.0.1:") +
            std::to_string(clientPorts[std::size_t(i)]);
  }
  for (std::uint16_t port : clientPorts)
    ASSERT_TRUE(waitFor([&] { return test::canConnect(port); }, 20.0)) << "a node never listened";

  TestServer server(-1.0);
  pc::relay::ExportOptions eo;
  eo.nats.urls = urls;
  eo.bucket.replicas = 3;
  auto exporter = pc::relay::FieldExporter::create(server.hub(), eo);
  ASSERT_TRUE(exporter.ok()) << exporter.error().message;
  (*exporter)->start();
  // The cluster elects its JetStream leader first; the exporter retries until the bucket exists.
  ASSERT_TRUE(waitFor([&] { return (*exporter)->stats().statesPut > 0; }, 60.0))
      << (*exporter)->stats().lastError;
  auto relay = startRelay(urls, "clustered");
  ASSERT_TRUE(relay);
  client::FieldMirror mirror;
  client::NetClient client(mirror, clientOptions(relay->port(), relay->tlsFingerprint()));
  client.start();
  ASSERT_TRUE(waitFor([&] { return client.stats().synced; }, 30.0));

  nodes[0].reset();  // SIGKILL
  const double killed = steadySeconds();
  const std::uint64_t before = relay->stats().fieldVersion;
  EXPECT_TRUE(waitFor([&] { return relay->stats().fieldVersion > before + 5; }, 40.0))
      << "the relay stopped following the field: " << relay->stats().lastError;
  const double recovered = steadySeconds() - killed;
  EXPECT_TRUE(waitFor([&] { return client.stats().serverFieldVersion > before + 5; }, 10.0));
  EXPECT_EQ(client.stats().sessions, 1u);
  EXPECT_TRUE(client.stats().connected);
  std::printf(
      "FIGURE relay_cluster_node_lost following_again_s=%.2f watch_restarts=%llu "
      "export_errors=%llu\n",
      recovered, (unsigned long long)relay->stats().watchRestarts,
      (unsigned long long)(*exporter)->stats().putErrors);
  relay.reset();
  exporter->reset();
}

// The load: a hundred load-generator clients (real sessions: TLS, sealed datagrams, acks)
// given both relays, on the first; it is killed under a moving field. Every client is served
// by the other relay again, and none starves in a window after the move.
TEST(Relay, AHundredLoadClientsOfAKilledRelayAreServedByTheOther) {
  if (!natsServerPresent()) GTEST_SKIP() << "nats-server is not installed (" << kNatsServer << ")";
  ASSERT_TRUE(fs::exists(kBin + "probecast-relay")) << "probecast-relay is not built";
  const fs::path dir = testDir("load");
  NatsServer nats(dir);
  TestServer server(-1.0);
  auto exporter = startExporter(server.hub(), nats.url());
  ASSERT_TRUE(exporter);
  RelayPair relays(dir, nats.url());
  ASSERT_TRUE(relays.listening()) << "the relays never listened (see " << dir.string() << ")";

  load::LoadOptions o;
  o.host = "127.0.0.1";
  o.port = relays.portA;
  o.alternates = {{"127.0.0.1", relays.portB}};
  o.loadProbeInterval = 0;  // all on a, in the order given, until it is killed
  o.caFile = relays.cert;
  o.token = kToken;
  o.clients = 100;
  o.rampSeconds = 2.0;
  // Starved means what versions say (no datagram, or behind the newest version, for 2 s): the
  // held field's bounds are not met on CI's two shared cores with the field changing 10 times
  // a second (test_loadgen, HundredClientsForTenSecondsAgainstRealServer, says why).
  o.minHeldPsnr = 0;
  o.maxChangeAge = 1e9;
  // And 5 s, not 2: here the field server traces in this process, on the same two cores as
  // the hundred clients and the relays, not at a lower priority as test_loadgen runs it.
  o.starveSeconds = 5.0;
  auto generator = load::LoadGenerator::create(o);
  ASSERT_TRUE(generator.ok()) << generator.error().message;
  load::LoadGenerator& g = **generator;
  g.start();
  const auto allSynced = [&] { return g.snapshot().synced == o.clients; };
  ASSERT_TRUE(waitFor(allSynced, 60.0)) << g.snapshot().synced << " of 100 synced on relay a";

  relays.a->kill(SIGKILL);
  const double killed = steadySeconds();
  ASSERT_TRUE(waitFor([&] { return g.snapshot().synced < o.clients; }, 5.0));
  ASSERT_TRUE(waitFor(allSynced, 30.0)) << g.snapshot().synced << " of 100 synced on relay b";
  const double failover = steadySeconds() - killed;

  sleepFor(2.0);  // relay b has just sent a hundred whole fields: the window starts after
  g.beginWindow();
  sleepFor(5.0);
  const load::LoadReport r = g.report();
  EXPECT_EQ(r.starvedClients, 0);
  for (const load::ClientReport& c : r.perClient) {
    if (!c.starved) continue;
    ADD_FAILURE() << "client " << c.index << " starved: " << c.starvedWhy;  // the first
    break;
  }
  EXPECT_EQ(r.errors, 0u);
  EXPECT_GT(r.bricksApplied, 0u);
  std::printf("FIGURE relay_failover_load clients=100 failover_s=%.3f p99_latency_ms=%.1f\n",
              failover, r.latencyMs.p99);
  g.stop();
  exporter.reset();
}

// Choosing by load: relay a serves twelve clients that know only it; clients given both relays
// (real clients and load-generator ones), a first, go to b, which answers with fewer. Then b is
// killed (SIGKILL) and every one of them moves to a, the live one.
TEST(Relay, NewClientsGoToTheLessLoadedRelayAndLeaveAKilledOne) {
  if (!natsServerPresent()) GTEST_SKIP() << "nats-server is not installed (" << kNatsServer << ")";
  ASSERT_TRUE(fs::exists(kBin + "probecast-relay")) << "probecast-relay is not built";
  FrozenFieldThroughTwoRelays setup("balance");
  ASSERT_TRUE(setup.start());
  RelayPair& relays = *setup.relays;
  const std::string endpointA = "127.0.0.1:" + std::to_string(relays.portA);
  const std::string endpointB = "127.0.0.1:" + std::to_string(relays.portB);

  auto loadOptions = [&](int clients) {
    load::LoadOptions o;
    o.host = "127.0.0.1";
    o.port = relays.portA;
    o.caFile = relays.cert;
    o.token = kToken;
    o.clients = clients;
    o.rampSeconds = 0.5;
    o.minHeldPsnr = 0;  // starving is not what this test is about
    o.maxChangeAge = 1e9;
    return o;
  };
  auto busy = load::LoadGenerator::create(loadOptions(12));
  ASSERT_TRUE(busy.ok()) << busy.error().message;
  (*busy)->start();
  ASSERT_TRUE(waitFor([&] { return (*busy)->snapshot().synced == 12; }, 60.0));

  constexpr int kReal = 3;
  std::vector<std::unique_ptr<client::FieldMirror>> mirrors;
  std::vector<std::unique_ptr<client::NetClient>> clients;
  for (int i = 0; i < kReal; ++i) {
    client::NetClientOptions o = clientOptions(relays.portA, "");
    o.caFile = relays.cert;
    o.alternates = {{"127.0.0.1", relays.portB}};
    mirrors.push_back(std::make_unique<client::FieldMirror>());
    clients.push_back(std::make_unique<client::NetClient>(*mirrors.back(), o));
    clients.back()->start();
  }
  load::LoadOptions spreadOptions = loadOptions(6);
  spreadOptions.alternates = {{"127.0.0.1", relays.portB}};
  auto spread = load::LoadGenerator::create(spreadOptions);
  ASSERT_TRUE(spread.ok()) << spread.error().message;
  (*spread)->start();
  auto on = [&](const std::string& endpoint) {
    for (auto& c : clients) {
      const client::NetClientStats st = c->stats();
      if (!st.synced || st.endpoint != endpoint) return false;
    }
    const load::LoadSnapshot snap = (*spread)->snapshot();
    for (const auto& [where, n] : snap.perEndpoint)
      if (n != (where == endpoint ? snap.clients : 0)) return false;
    return snap.synced == snap.clients;
  };
  EXPECT_TRUE(waitFor([&] { return on(endpointB); }, 30.0))
      << "clients given both relays did not all choose b, the less loaded";
  for (auto& c : clients) EXPECT_EQ(c->stats().endpoint, endpointB);

  relays.b->kill(SIGKILL);
  const double killed = steadySeconds();
  EXPECT_TRUE(waitFor([&] { return on(endpointA); }, 30.0))
      << "the clients of the killed relay did not all move to the live one";
  const double moved = steadySeconds() - killed;
  const load::LoadSnapshot snap = (*spread)->snapshot();
  std::printf("load clients: %d synced, %d in session\n", snap.synced, snap.inSession);
  for (const auto& [where, n] : snap.perEndpoint)
    std::printf("load clients on %s: %d\n", where.c_str(), n);
  for (auto& c : clients) {
    const client::NetClientStats st = c->stats();
    std::printf("client on %s, synced %d, sessions %llu: %s\n", st.endpoint.c_str(), int(st.synced),
                (unsigned long long)st.sessions, st.lastError.c_str());
  }
  std::printf("FIGURE relay_balance real=%d load=%d busy=12 moved_s=%.3f\n", kReal, 6, moved);
  (*spread)->stop();
  (*busy)->stop();
  for (auto& c : clients) c->stop();
}

}  // namespace
}  // namespace pc
