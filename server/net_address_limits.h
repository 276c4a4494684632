// Limits per remote address and per client identity (internal to the server's network layer):
// what one address may hold (connections before their Hello, sessions), how fast it may start
// handshakes, and how many sessions one client identity may hold. A stranger with one address
// (or one IPv6 /64, what one host is commonly given) then cannot take the places every other
// client needs, and one token holder cannot take every session. Network thread only.
#pragma once

#include <boost/asio/ip/address.hpp>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <unordered_map>

namespace pc {

struct AddressLimitOptions {
  // 0 turns a limit off (a load generator's hundred clients come from one address).
  std::size_t maxPendingPerAddress = 8;
  std::size_t maxSessionsPerAddress = 16;
  double handshakesPerSecond = 4;  // token bucket per address, holding `handshakeBurst`
  double handshakeBurst = 8;
  std::size_t maxSessionsPerClient = 4;
  // Refusals are logged at most once per address per this many seconds (with a count of
  // those left out), so that refused connections cannot turn into a flood of log lines.
  double logInterval = 5.0;
};

// The key an address is counted under: the IPv4 address, or the /64 of an IPv6 one (an
// IPv4-mapped IPv6 address counts as its IPv4 address).
std::string addressKey(const boost::asio::ip::address& address);

class AddressLimits {
 public:
  explicit AddressLimits(AddressLimitOptions options) : options_(options) {}

  // A connection from `key` was accepted: nothing when it may go on (it is then counted as
  // pending until released or promoted), else why it must be closed at once.
  std::optional<std::string> admit(const std::string& key, double now);
  // Its Hello was accepted: pending becomes session. Why not, when the address already holds
  // its cap of sessions (the connection is still pending then).
  std::optional<std::string> promote(const std::string& key);
  // The connection ended, pending or past its handshake.
  void release(const std::string& key, bool session);

  // A client identity (the Hello's client name) takes a session: why not, when it holds its
  // cap already (short: it goes into a Reject, which must fit in the bytes of the Hello).
  // releaseClient when that session ends.
  std::optional<std::string> admitClient(const std::string& client);
  void releaseClient(const std::string& client);

  // Whether a refusal for `key` may be logged now; `suppressed` is set to the refusals of
  // `key` not logged since its previous line.
  bool shouldLog(const std::string& key, double now, std::uint64_t& suppressed);

  std::size_t trackedAddresses() const { return addresses_.size(); }

 private:
  struct PerAddress {
    std::size_t pending = 0, sessions = 0;
    double tokens = 0, tokensAt = 0;
    double loggedAt = -1e300;
    std::uint64_t unlogged = 0;
  };
  // Drops addresses that hold nothing and whose bucket is full again: the table stays as
  // large as the addresses connected lately, not every address ever seen.
  void prune(double now);

  AddressLimitOptions options_;
  std::unordered_map<std::string, PerAddress> addresses_;
  std::unordered_map<std::string, std::size_t> clients_;
  double prunedAt_ = 0;
};

}  // namespace pc
