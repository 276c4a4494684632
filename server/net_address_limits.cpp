#include "net_address_limits.h"

#include <algorithm>

namespace pc {

std::string addressKey(const boost::asio::ip::address& address) {
  if (address.is_v6()) {
    const auto v6 = address.to_v6();
    if (v6.is_v4_mapped()) {
      return boost::asio::ip::make_address_v4(boost::asio::ip::v4_mapped, v6).to_string();
    }
    auto bytes = v6.to_bytes();
    std::fill(bytes.begin() + 8, bytes.end(), 0);  // the /64
    return boost::asio::ip::address_v6(bytes).to_string() + "/64";
  }
  return address.to_string();
}

std::optional<std::string> AddressLimits::admit(const std::string& key, double now) {
  prune(now);
  auto [it, added] = addresses_.try_emplace(key);
  PerAddress& a = it->second;
  if (added) {
    a.tokens = options_.handshakeBurst;
    a.tokensAt = now;
  }
  if (options_.maxPendingPerAddress != 0 && a.pending >= options_.maxPendingPerAddress) {
    return std::to_string(a.pending) +
           " connections from this address await their Hello, the cap is " +
           std::to_string(options_.maxPendingPerAddress);
  }
  if (options_.maxSessionsPerAddress != 0 && a.sessions >= options_.maxSessionsPerAddress) {
    return std::to_string(a.sessions) + " sessions from this address, the cap is " +
           std::to_string(options_.maxSessionsPerAddress);
  }
  if (options_.handshakesPerSecond > 0) {
    a.tokens = std::min(options_.handshakeBurst,
                        a.tokens + (now - a.tokensAt) * options_.handshakesPerSecond);
    a.tokensAt = now;
    if (a.tokens < 1) {
      return "more than " + std::to_string(options_.handshakesPerSecond) +
             " handshakes per second from this address";
    }
    a.tokens -= 1;
  }
  ++a.pending;
  return std::nullopt;
}

std::optional<std::string> AddressLimits::promote(const std::string& key) {
  PerAddress& a = addresses_[key];
  if (options_.maxSessionsPerAddress != 0 && a.sessions >= options_.maxSessionsPerAddress) {
    return std::to_string(a.sessions) + " sessions from this address, the cap is " +
           std::to_string(options_.maxSessionsPerAddress);
  }
  if (a.pending > 0) --a.pending;
  ++a.sessions;
  return std::nullopt;
}

void AddressLimits::release(const std::string& key, bool session) {
  auto it = addresses_.find(key);
  if (it == addresses_.end()) return;
  std::size_t& count = session ? it->second.sessions : it->second.pending;
  if (count > 0) --count;
}

std::optional<std::string> AddressLimits::admitClient(const std::string& client) {
  std::size_t& n = clients_[client];
  if (options_.maxSessionsPerClient != 0 && n >= options_.maxSessionsPerClient) {
    return "cap " + std::to_string(options_.maxSessionsPerClient);
  }
  ++n;
  return std::nullopt;
}

void AddressLimits::releaseClient(const std::string& client) {
  auto it = clients_.find(client);
  if (it == clients_.end()) return;
  if (--it->second == 0) clients_.erase(it);
}

bool AddressLimits::shouldLog(const std::string& key, double now, std::uint64_t& suppressed) {
  PerAddress& a = addresses_[key];
  if (now - a.loggedAt < options_.logInterval) {
    ++a.unlogged;
    return false;
  }
  a.loggedAt = now;
  suppressed = a.unlogged;
  a.unlogged = 0;
  return true;
}

void AddressLimits::prune(double now) {
  if (now - prunedAt_ < options_.logInterval) return;
  prunedAt_ = now;
  const double refill =
      options_.handshakesPerSecond > 0 ? options_.handshakeBurst / options_.handshakesPerSecond : 0;
  std::erase_if(addresses_, [&](const auto& entry) {
    const PerAddress& a = entry.second;
    return a.pending == 0 && a.sessions == 0 && now - a.tokensAt >= refill &&
           now - a.loggedAt >= options_.logInterval;
  });
}

}  // namespace pc
