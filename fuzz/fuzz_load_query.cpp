// Load queries and their replies (net/load_probe.h): the one message a server answers before a
// session exists, so anyone can send it. Any bytes go to both decoders. Checked: nothing
// shorter than the fixed size decodes; what decodes encodes again to a message that decodes to
// the same fields; the endpoint choice over replies made from the input stays within the
// endpoints given. (Query and reply are both fixed-size arrays, so a reply cannot outgrow a
// query by construction.)
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <span>
#include <vector>

#include "net/load_probe.h"

namespace {

void check(bool ok) {
  if (!ok) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace pc::net;
  const std::span<const std::uint8_t> bytes(data, size);

  if (const auto nonce = decodeLoadQuery(bytes)) {
    check(size >= kLoadQueryBytes);
    const LoadDatagram again = encodeLoadQuery(*nonce);
    check(decodeLoadQuery(again) == nonce);
  }
  std::vector<ProbedEndpoint> endpoints;
  if (const auto reply = decodeLoadReply(bytes)) {
    check(size >= kLoadQueryBytes);
    const LoadDatagram again = encodeLoadReply(reply->nonce, reply->load);
    const auto back = decodeLoadReply(again);
    check(back.has_value() && back->nonce == reply->nonce &&
          back->load.clients == reply->load.clients &&
          back->load.maxClients == reply->load.maxClients && back->load.ready == reply->load.ready);
    ProbedEndpoint e;
    e.address = "10.0.0.1";
    e.port = 7000;
    e.load = reply->load;
    endpoints.push_back(e);
  }
  // The input's bytes as several endpoints' answers, some silent, one refused.
  for (std::size_t at = 0; at + 9 <= size && endpoints.size() < 8; at += 9) {
    ProbedEndpoint e;
    e.address = "10.0.1." + std::to_string(endpoints.size());
    e.port = 7000;
    const std::uint8_t kind = data[at] % 3;
    if (kind == 0) {
      EndpointLoad load;
      load.clients = std::uint32_t(data[at + 1]) << 24 | std::uint32_t(data[at + 2]) << 16 |
                     std::uint32_t(data[at + 3]) << 8 | data[at + 4];
      load.maxClients = std::uint32_t(data[at + 5]) << 8 | data[at + 6];
      load.ready = data[at + 7] & 1;
      e.load = load;
    } else if (kind == 1) {
      e.refused = true;
    }
    endpoints.push_back(e);
  }
  std::vector<int> extra(endpoints.size());
  for (std::size_t i = 0; i < extra.size() && i < size; ++i) extra[i] = data[i] % 50;
  const auto chosen = chooseEndpoint(endpoints, endpoints.empty() ? "" : endpoints[0].key(), extra);
  check(chosen.has_value() == !endpoints.empty());
  if (chosen) check(*chosen < endpoints.size());
  return 0;
}
