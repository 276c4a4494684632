// Comparing secrets (tokens) without revealing through timing how much of them matched.
#pragma once

#include <algorithm>
#include <cstddef>
#include <string_view>

namespace pc {

// True when `got` equals `expected`. Runs over the longer of the two whatever the first
// difference, so timing does not reveal a matching prefix.
inline bool sameSecret(std::string_view got, std::string_view expected) {
  const std::size_t n = std::max(got.size(), expected.size());
  unsigned diff = got.size() == expected.size() ? 0u : 1u;
  for (std::size_t i = 0; i < n; ++i) {
    const unsigned a = i < got.size() ? static_cast<unsigned char>(got[i]) : 0u;
    const unsigned b = i < expected.size() ? static_cast<unsigned char>(expected[i]) : 0u;
    diff |= a ^ b;
  }
  return diff == 0;
}

}  // namespace pc
