#pragma once
// Order statistics the gtests assert on.
#include <algorithm>
#include <limits>
#include <vector>

namespace dynaorb::test {

// The upper median (the element at size / 2 once sorted); NaN when empty.
inline double median(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

// The element at p * size once sorted (clamped to the last); NaN when empty.
inline double percentile(std::vector<double> v, double p) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(p * v.size()));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[k];
}

}  // namespace dynaorb::test
