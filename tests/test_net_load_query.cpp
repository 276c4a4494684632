// Load queries (net/load_probe.h, PROTOCOL.md "Choosing an endpoint by load"): the format, how a
// client ranks endpoints by what they answer, and a real server's answers: the size of the
// query at most, its sessions counted, nothing for bytes that are not a query.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <unistd.h>

#include "net/load_probe.h"
#include "test_child_process.h"
#include "test_net_support.h"

namespace pc {
namespace {

using nettest::secureClientOptions;
using nettest::TestServer;
using nettest::waitFor;

net::ProbedEndpoint answered(const std::string& address, std::uint32_t clients,
                             std::uint32_t maxClients, bool ready = true) {
  net::ProbedEndpoint e{"host", address, 7450, 0, net::EndpointLoad{clients, maxClients, ready},
                        false};
  return e;
}

TEST(LoadQuery, FormatRoundTripsAndRefusesOtherBytes) {
  const net::LoadDatagram query = net::encodeLoadQuery(0x1122334455667788ull);
  EXPECT_EQ(net::decodeLoadQuery(query), 0x1122334455667788ull);
  EXPECT_FALSE(net::decodeLoadQuery(std::span(query.data(), query.size() - 1)));  // short
  EXPECT_FALSE(net::decodeLoadReply(query));                                      // a query
  const net::LoadDatagram reply = net::encodeLoadReply(42, {17, 64, true});
  EXPECT_EQ(reply.size(), query.size());  // never more than was asked
  auto back = net::decodeLoadReply(reply);
  ASSERT_TRUE(back);
  EXPECT_EQ(back->nonce, 42u);
  EXPECT_EQ(back->load.clients, 17u);
  EXPECT_EQ(back->load.maxClients, 64u);
  EXPECT_TRUE(back->load.ready);
  EXPECT_FALSE(net::decodeLoadQuery(reply));
  net::LoadDatagram otherFormat = query;
  otherFormat[4] = 2;
  EXPECT_FALSE(net::decodeLoadQuery(otherFormat));
}

TEST(LoadQuery, ClientsChooseTheLeastLoadedLiveEndpoint) {
  std::vector<net::ProbedEndpoint> e{answered("10.0.0.1", 60, 100), answered("10.0.0.2", 10, 100),
                                     answered("10.0.0.3", 10, 40)};
  EXPECT_EQ(net::chooseEndpoint(e), 1u);  // the smallest share of its cap
  // Sessions this process opened since the answers count: 31 more make the second busier.
  const std::vector<int> opened{0, 31, 0};
  EXPECT_EQ(net::chooseEndpoint(e, "", opened), 2u);
  e[1].load->ready = false;  // a relay that lost NATS: after every ready one
  EXPECT_EQ(net::chooseEndpoint(e), 2u);
  // The one that just failed goes after the others of its class, however light.
  EXPECT_EQ(net::chooseEndpoint(e, e[2].key()), 0u);
  e[2].load->clients = 40;  // full: with the not ready ones
  EXPECT_EQ(net::chooseEndpoint(e), 0u);
  e[0].load->ready = false;  // none ready: the least loaded of them
  EXPECT_EQ(net::chooseEndpoint(e), 1u);

  // No answers (servers without load queries): the order given, after the one that failed.
  std::vector<net::ProbedEndpoint> silent(3, answered("", 0, 0));
  for (int i = 0; i < 3; ++i) {
    silent[std::size_t(i)].address = "10.0.1." + std::to_string(i);
    silent[std::size_t(i)].load.reset();
  }
  EXPECT_EQ(net::chooseEndpoint(silent), 0u);
  EXPECT_EQ(net::chooseEndpoint(silent, silent[0].key()), 1u);
  EXPECT_EQ(net::chooseEndpoint(silent, silent[2].key()), 0u);
  silent[0].refused = true;  // nothing listens there: last
  EXPECT_EQ(net::chooseEndpoint(silent, silent[2].key()), 1u);
  // One that answers beats any that does not.
  silent[2].load = net::EndpointLoad{50, 64, true};
  EXPECT_EQ(net::chooseEndpoint(silent), 2u);
  EXPECT_FALSE(net::chooseEndpoint({}));
}

// A UDP socket connected to the server's session port number on loopback.
struct QuerySocket {
  explicit QuerySocket(std::uint16_t port) : fd(::socket(AF_INET, SOCK_DGRAM, 0)) {
    sockaddr_in to{};
    to.sin_family = AF_INET;
    to.sin_port = htons(port);
    to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    EXPECT_EQ(::connect(fd, reinterpret_cast<sockaddr*>(&to), sizeof to), 0);
    timeval wait{0, 300000};
    ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &wait, sizeof wait);
  }
  ~QuerySocket() { ::close(fd); }
  // The answer's bytes, empty when none came within 0.3 s.
  std::vector<std::uint8_t> ask(std::span<const std::uint8_t> bytes) {
    EXPECT_EQ(::send(fd, bytes.data(), bytes.size(), 0), ssize_t(bytes.size()));
    std::vector<std::uint8_t> in(512);
    const ssize_t n = ::recv(fd, in.data(), in.size(), 0);
    in.resize(n > 0 ? std::size_t(n) : 0);
    return in;
  }
  int fd;
};

TEST(NetLoadQuery, AServerAnswersWithItsSessionsAndNoMoreBytesThanAsked) {
  TestServer server(0.8);
  QuerySocket s(server.port());
  const net::LoadDatagram query = net::encodeLoadQuery(7);
  // Too short, or not a query: no answer at all.
  EXPECT_TRUE(s.ask(std::span(query.data(), query.size() - 1)).empty());
  std::vector<std::uint8_t> junk(64, 0x5A);
  EXPECT_TRUE(s.ask(junk).empty());

  auto first = s.ask(query);
  ASSERT_EQ(first.size(), net::kLoadQueryBytes) << "no answer, or not of the query's size";
  auto reply = net::decodeLoadReply(first);
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->nonce, 7u);
  EXPECT_EQ(reply->load.clients, 0u);
  EXPECT_EQ(reply->load.maxClients, NetServerOptions{}.maxClients);
  EXPECT_TRUE(reply->load.ready);

  client::FieldMirror mirror;
  client::NetClient c(mirror, secureClientOptions(server, "counted"));
  c.start();
  ASSERT_TRUE(waitFor([&] { return c.stats().connected; }, 20.0));
  reply = net::decodeLoadReply(s.ask(net::encodeLoadQuery(8)));
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->load.clients, 1u);
  // Counted (the stats are a snapshot taken every poll).
  EXPECT_TRUE(waitFor([&] { return server.net().stats().loadAnswered == 2; }, 2.0));
  EXPECT_EQ(server.net().stats().loadMalformed, 2u);

  // The probe a client runs: the live server answers, a port where nothing listens refuses.
  std::vector<net::ProbedEndpoint> endpoints =
      net::resolveEndpoints({{"127.0.0.1", test::freePort()}, {"127.0.0.1", server.port()}});
  ASSERT_EQ(endpoints.size(), 2u);
  net::probeLoads(endpoints, 1.0);
  EXPECT_TRUE(endpoints[0].refused);
  ASSERT_TRUE(endpoints[1].load);
  EXPECT_EQ(endpoints[1].load->clients, 1u);
  EXPECT_EQ(net::chooseEndpoint(endpoints), 1u);
}

// Containers publish one number for TCP and UDP (--udp-port the same as --port): the datagram
// socket answers the queries then, and still takes its clients' acks.
TEST(NetLoadQuery, TheDatagramSocketAnswersWhereItHasTheSessionPortsNumber) {
  const std::uint16_t port = test::freePort();
  NetServerOptions o;
  o.udpPort = port;
  TestServer server(0.8, o, port);
  ASSERT_EQ(server.net().udpPort(), port);
  QuerySocket s(port);
  auto reply = net::decodeLoadReply(s.ask(net::encodeLoadQuery(9)));
  ASSERT_TRUE(reply) << "no answer on the datagram socket";
  EXPECT_EQ(reply->nonce, 9u);
  client::FieldMirror mirror;
  client::NetClient c(mirror, secureClientOptions(server, "acks"));
  c.start();
  ASSERT_TRUE(waitFor([&] { return c.stats().synced; }, 30.0));
  EXPECT_TRUE(waitFor([&] { return server.net().stats().acksUdp > 0; }, 5.0));
  reply = net::decodeLoadReply(s.ask(net::encodeLoadQuery(10)));
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->load.clients, 1u);
}

}  // namespace
}  // namespace pc
