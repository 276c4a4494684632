// Load queries: how a client given several endpoints of one field (relays, the field server)
// learns which is least loaded before it opens a session (PROTOCOL.md, "Choosing an endpoint
// by load"). A query is one small UDP datagram to the session's port number; the server answers
// with one datagram of the same size naming its sessions, its cap and whether it takes clients.
// The answer is never larger than the query, so a forged source address gains an attacker
// nothing (no amplification), and the server caps its answers per second.
//
// The format, the server's answer and the client's probe (blocking, a few hundred milliseconds
// at most) and ranking are here; the server's socket is in server/net_server.cpp.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace pc::net {

// Both messages are exactly this long; a query may be longer (later formats), never shorter.
constexpr std::size_t kLoadQueryBytes = 32;
constexpr std::uint16_t kLoadQueryFormat = 1;

struct EndpointLoad {
  std::uint32_t clients = 0;     // sessions, established or in their handshake
  std::uint32_t maxClients = 0;  // the cap (0: none)
  bool ready = false;            // takes clients now (a relay: caught up and following)
  bool full() const { return maxClients != 0 && clients >= maxClients; }
  // clients / maxClients, or the clients where there is no cap.
  double share() const;
};

using LoadDatagram = std::array<std::uint8_t, kLoadQueryBytes>;

LoadDatagram encodeLoadQuery(std::uint64_t nonce);
// The query's nonce; nothing for bytes that are not a query (too short, another magic).
std::optional<std::uint64_t> decodeLoadQuery(std::span<const std::uint8_t> bytes);
LoadDatagram encodeLoadReply(std::uint64_t nonce, const EndpointLoad& load);
struct LoadReply {
  std::uint64_t nonce = 0;
  EndpointLoad load;
};
std::optional<LoadReply> decodeLoadReply(std::span<const std::uint8_t> bytes);

// An endpoint as given (a host name or address, and the session's TCP port).
struct LoadEndpoint {
  std::string host;
  std::uint16_t port = 0;
};

// One address of a given endpoint, and what it answered.
struct ProbedEndpoint {
  std::string host;     // as given: the name TLS checks
  std::string address;  // numeric, to connect to
  std::uint16_t port = 0;
  std::size_t given = 0;             // index of the endpoint it came from
  std::optional<EndpointLoad> load;  // nothing: no answer (an older server, lost, dead)
  bool refused = false;              // the host said nothing listens there (ICMP)
  std::string key() const { return address + ":" + std::to_string(port); }
};

// Every address of every endpoint (a DNS name with several records gives several, "localhost"
// its IPv6 and IPv4 ones), in the order given and the resolver's. Names that do not resolve are
// left out. Blocks for the resolver.
std::vector<ProbedEndpoint> resolveEndpoints(const std::vector<LoadEndpoint>& endpoints);

// Sends one query to each and waits up to `timeoutSeconds` for their answers (less once every
// one answered or was refused), filling `load` and `refused`.
void probeLoads(std::vector<ProbedEndpoint>& endpoints, double timeoutSeconds);

// The endpoint to try next: ready ones with room, least loaded first (share, then clients,
// `extraClients[i]` added to endpoint i's count where given: sessions this process opened since
// the probe); then full or not ready ones; then those that did not answer; refused ones last.
// Within a class the order given, starting after `avoid` (the key of the endpoint that just
// failed, which itself comes last of its class), so that endpoints that never answer are tried
// in turn. Nothing when `endpoints` is empty.
std::optional<std::size_t> chooseEndpoint(const std::vector<ProbedEndpoint>& endpoints,
                                          const std::string& avoid = "",
                                          std::span<const int> extraClients = {});

}  // namespace pc::net
