#include "core/sparse_system.hpp"

#include <boost/sort/spreadsort/integer_sort.hpp>

namespace fiberfem::core::detail {

void sort_keyed(std::vector<std::pair<std::uint64_t, int>>& pairs) {
  using Pair = std::pair<std::uint64_t, int>;
  boost::sort::spreadsort::integer_sort(
      pairs.begin(), pairs.end(), [](const Pair& p, unsigned shift) { return p.first >> shift; },
      [](const Pair& a, const Pair& b) { return a < b; });
}

}  // namespace fiberfem::core::detail
