#include "load_probe.h"

#include <arpa/inet.h>
#include <netdb.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <random>
#include <utility>

namespace pc::net {

namespace {

constexpr std::array<std::uint8_t, 4> kQueryMagic{'P', 'C', 'L', 'Q'};
constexpr std::array<std::uint8_t, 4> kReplyMagic{'P', 'C', 'L', 'R'};
constexpr std::uint16_t kReady = 1;

void put16(LoadDatagram& d, std::size_t at, std::uint16_t v) {
  for (int i = 0; i < 2; ++i) d[at + std::size_t(i)] = std::uint8_t(v >> (8 * i));
}
void put32(LoadDatagram& d, std::size_t at, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) d[at + std::size_t(i)] = std::uint8_t(v >> (8 * i));
}
void put64(LoadDatagram& d, std::size_t at, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) d[at + std::size_t(i)] = std::uint8_t(v >> (8 * i));
}
std::uint64_t get(std::span<const std::uint8_t> b, std::size_t at, int bytes) {
  std::uint64_t v = 0;
  for (int i = 0; i < bytes; ++i) v |= std::uint64_t(b[at + std::size_t(i)]) << (8 * i);
  return v;
}

// Magic (4 bytes), format (u16), then the kind's fields: a datagram of the right size, magic
// and format, or nothing.
bool framed(std::span<const std::uint8_t> b, const std::array<std::uint8_t, 4>& magic) {
  return b.size() >= kLoadQueryBytes && std::equal(magic.begin(), magic.end(), b.begin()) &&
         get(b, 4, 2) == kLoadQueryFormat;
}

LoadDatagram header(const std::array<std::uint8_t, 4>& magic) {
  LoadDatagram d{};
  std::copy(magic.begin(), magic.end(), d.begin());
  put16(d, 4, kLoadQueryFormat);
  return d;
}

// Socket file descriptor, closed when it goes.
struct Fd {
  int fd = -1;
  explicit Fd(int f) : fd(f) {}
  Fd(Fd&& o) noexcept : fd(std::exchange(o.fd, -1)) {}
  Fd& operator=(Fd&&) = delete;
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
};

// The class an endpoint ranks in (lower first): answered ready with room, answered but full or
// not ready, no answer, refused.
int rankClass(const ProbedEndpoint& e, int extra) {
  if (e.refused) return 3;
  if (!e.load) return 2;
  EndpointLoad l = *e.load;
  l.clients += std::uint32_t(std::max(0, extra));
  return l.ready && !l.full() ? 0 : 1;
}

}  // namespace

double EndpointLoad::share() const {
  return maxClients ? double(clients) / double(maxClients) : double(clients);
}

LoadDatagram encodeLoadQuery(std::uint64_t nonce) {
  LoadDatagram d = header(kQueryMagic);
  put64(d, 8, nonce);
  return d;
}

std::optional<std::uint64_t> decodeLoadQuery(std::span<const std::uint8_t> bytes) {
  if (!framed(bytes, kQueryMagic)) return std::nullopt;
  return get(bytes, 8, 8);
}

LoadDatagram encodeLoadReply(std::uint64_t nonce, const EndpointLoad& load) {
  LoadDatagram d = header(kReplyMagic);
  put16(d, 6, load.ready ? kReady : 0);
  put64(d, 8, nonce);
  put32(d, 16, load.clients);
  put32(d, 20, load.maxClients);
  return d;
}

std::optional<LoadReply> decodeLoadReply(std::span<const std::uint8_t> bytes) {
  if (!framed(bytes, kReplyMagic) || bytes.size() != kLoadQueryBytes) return std::nullopt;
  LoadReply r;
  r.load.ready = (get(bytes, 6, 2) & kReady) != 0;
  r.nonce = get(bytes, 8, 8);
  r.load.clients = std::uint32_t(get(bytes, 16, 4));
  r.load.maxClients = std::uint32_t(get(bytes, 20, 4));
  return r;
}

std::vector<ProbedEndpoint> resolveEndpoints(const std::vector<LoadEndpoint>& endpoints) {
  std::vector<ProbedEndpoint> out;
  for (std::size_t i = 0; i < endpoints.size(); ++i) {
    const LoadEndpoint& e = endpoints[i];
    addrinfo hints{};
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_DGRAM;
    addrinfo* found = nullptr;
    if (::getaddrinfo(e.host.c_str(), std::to_string(e.port).c_str(), &hints, &found) != 0)
      continue;
    for (const addrinfo* a = found; a; a = a->ai_next) {
      const int family = a->ai_family;
      if (family != AF_INET && family != AF_INET6) continue;
      char text[INET6_ADDRSTRLEN] = {};
      const void* raw =
          family == AF_INET
              ? static_cast<const void*>(&reinterpret_cast<sockaddr_in*>(a->ai_addr)->sin_addr)
              : static_cast<const void*>(&reinterpret_cast<sockaddr_in6*>(a->ai_addr)->sin6_addr);
      if (!::inet_ntop(family, raw, text, sizeof text)) continue;
      ProbedEndpoint p{e.host, text, e.port, i, std::nullopt, false};
      const bool seen = std::any_of(out.begin(), out.end(),
                                    [&](const ProbedEndpoint& q) { return q.key() == p.key(); });
      if (!seen) out.push_back(std::move(p));
    }
    ::freeaddrinfo(found);
  }
  return out;
}

void probeLoads(std::vector<ProbedEndpoint>& endpoints, double timeoutSeconds) {
  // One connected socket per endpoint: its answer can come only from there, and a "port
  // unreachable" from the host shows as a refusal at once instead of a silent timeout.
  std::vector<Fd> sockets;
  std::vector<pollfd> waiting;
  std::vector<std::size_t> owner;
  std::vector<std::uint64_t> nonces;
  std::mt19937_64 rng{std::random_device{}()};
  for (std::size_t i = 0; i < endpoints.size(); ++i) {
    ProbedEndpoint& e = endpoints[i];
    e.load.reset();
    e.refused = false;
    sockaddr_storage to{};
    socklen_t length = 0;
    int family = AF_INET;
    if (auto* v4 = reinterpret_cast<sockaddr_in*>(&to);
        ::inet_pton(AF_INET, e.address.c_str(), &v4->sin_addr) == 1) {
      v4->sin_family = AF_INET;
      v4->sin_port = htons(e.port);
      length = sizeof(sockaddr_in);
    } else if (auto* v6 = reinterpret_cast<sockaddr_in6*>(&to);
               ::inet_pton(AF_INET6, e.address.c_str(), &v6->sin6_addr) == 1) {
      v6->sin6_family = AF_INET6;
      v6->sin6_port = htons(e.port);
      length = sizeof(sockaddr_in6);
      family = AF_INET6;
    } else {
      continue;
    }
    Fd s(::socket(family, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0));
    if (s.fd < 0 || ::connect(s.fd, reinterpret_cast<sockaddr*>(&to), length) != 0) continue;
    const std::uint64_t nonce = rng();
    const LoadDatagram query = encodeLoadQuery(nonce);
    if (::send(s.fd, query.data(), query.size(), 0) != ssize_t(query.size())) {
      e.refused = errno == ECONNREFUSED;
      continue;
    }
    waiting.push_back(pollfd{s.fd, POLLIN, 0});
    owner.push_back(i);
    nonces.push_back(nonce);
    sockets.push_back(std::move(s));
  }
  using Clock = std::chrono::steady_clock;
  const auto until = Clock::now() + std::chrono::duration<double>(timeoutSeconds);
  std::size_t open = waiting.size();
  while (open > 0) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(until - Clock::now());
    if (left.count() <= 0) break;
    const int n = ::poll(waiting.data(), waiting.size(), int(left.count()) + 1);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    for (std::size_t j = 0; j < waiting.size(); ++j) {
      if (waiting[j].fd < 0 || waiting[j].revents == 0) continue;
      LoadDatagram in{};
      const ssize_t got = ::recv(waiting[j].fd, in.data(), in.size(), 0);
      ProbedEndpoint& e = endpoints[owner[j]];
      if (got < 0 && errno == EAGAIN) continue;
      if (got < 0) {
        e.refused = errno == ECONNREFUSED;
      } else if (auto reply = decodeLoadReply(std::span(in.data(), std::size_t(got)));
                 reply && reply->nonce == nonces[j]) {
        e.load = reply->load;
      } else {
        continue;  // not the answer to this query: keep waiting for it
      }
      waiting[j].fd = -1;  // poll skips it from now on
      --open;
    }
  }
}

std::optional<std::size_t> chooseEndpoint(const std::vector<ProbedEndpoint>& endpoints,
                                          const std::string& avoid,
                                          std::span<const int> extraClients) {
  if (endpoints.empty()) return std::nullopt;
  const std::size_t n = endpoints.size();
  std::size_t start = 0;
  for (std::size_t i = 0; i < n; ++i)
    if (endpoints[i].key() == avoid) start = i + 1;
  auto extra = [&](std::size_t i) { return i < extraClients.size() ? extraClients[i] : 0; };
  std::optional<std::size_t> best;
  auto better = [&](std::size_t a, std::size_t b) {  // is a to be tried before b?
    // The endpoint that just failed goes after the others of its class: one that answers but
    // keeps failing sessions is not taken again and again while others serve.
    const int ca = 2 * rankClass(endpoints[a], extra(a)) + (endpoints[a].key() == avoid);
    const int cb = 2 * rankClass(endpoints[b], extra(b)) + (endpoints[b].key() == avoid);
    if (ca != cb) return ca < cb;
    if (ca <= 3) {
      EndpointLoad la = *endpoints[a].load, lb = *endpoints[b].load;
      la.clients += std::uint32_t(std::max(0, extra(a)));
      lb.clients += std::uint32_t(std::max(0, extra(b)));
      if (la.share() != lb.share()) return la.share() < lb.share();
      if (la.clients != lb.clients) return la.clients < lb.clients;
    }
    return false;  // equal: the earlier in the rotation
  };
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t i = (start + k) % n;
    if (!best || better(i, *best)) best = i;
  }
  return best;
}

}  // namespace pc::net
