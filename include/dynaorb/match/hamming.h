#pragma once
// Hamming distance between two 256-bit ORB descriptors.
#include <cstdint>
#include <cstring>

namespace dynaorb::match {

inline int hamming(const std::uint8_t* a, const std::uint8_t* b) {
  int d = 0;
  for (int i = 0; i < 4; ++i) {
    std::uint64_t x, y;
    std::memcpy(&x, a + 8 * i, 8);
    std::memcpy(&y, b + 8 * i, 8);
    d += __builtin_popcountll(x ^ y);
  }
  return d;
}

}  // namespace dynaorb::match
