#pragma once
/// @file The median of a sample of timings (batch reports and service status: a step's
/// typical time, robust to the odd slow one).

#include <algorithm>
#include <cstddef>
#include <vector>

namespace fiberfem::service::detail {

/// The upper median of `v` (the element at size/2 in order); 0 for an empty sample.
inline double median(std::vector<double> v) {
  if (v.empty()) return 0;
  const size_t m = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(m), v.end());
  return v[m];
}

}  // namespace fiberfem::service::detail
