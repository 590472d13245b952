#pragma once
/// @file The engine's loops on the OpenMP threads, with results that do not depend on the
/// thread count: work that sums is split into a fixed number of parts (never one per
/// thread), each part summed in order by one thread, and the parts added in order. A run
/// on 1 thread, on 2 or on 16 rounds identically, so the thread count can change between
/// steps (core/thread_governor.hpp) and a checkpoint resumes bit for bit on any machine.
///
/// On one thread no parallel region is opened: libgomp allocates a team for every region,
/// even a region of one thread (`if (false)` or `omp_set_num_threads(1)`), and the steady
/// step allocates nothing.

#include "core/team_affinity.hpp"

#include <omp.h>

#include <algorithm>
#include <array>

namespace fiberfem::core {

/// Whether loops started here would run on more than one thread: more than one thread is
/// set for this thread's regions and we are not already inside a parallel region.
inline bool threaded() { return omp_get_max_threads() > 1 && !omp_in_parallel(); }

/// body(i) for i in [0, n), on the threads when threaded() and `parallel` (static schedule;
/// the bodies must be independent).
template <class Body>
void parallel_for(int n, Body&& body, bool parallel = true) {
  if (parallel && threaded()) {
    const int cpu = current_cpu();
#pragma omp parallel
    {
      keep_team_apart(cpu);
#pragma omp for schedule(static)
      for (int i = 0; i < n; ++i) body(i);
    }
  } else {
    for (int i = 0; i < n; ++i) body(i);
  }
}

/// Parts of a fixed-partition sum (fixed_sum): the most threads a sum uses.
inline constexpr int kSumParts = 64;

/// Sum of body(i) over i in [0, n): rows in kSumParts contiguous parts, each summed in
/// order, the parts' sums added in order, on the threads when threaded() and `parallel`.
/// The same bits for any thread count.
template <class Body>
double fixed_sum(int n, bool parallel, Body&& body) {
  std::array<double, kSumParts> part{};
  const auto bound = [n](int p) { return static_cast<int>(static_cast<long>(n) * p / kSumParts); };
  parallel_for(
      kSumParts,
      [&](int p) {
        double s = 0;
        for (int i = bound(p); i < bound(p + 1); ++i) s += body(i);
        part[static_cast<size_t>(p)] = s;
      },
      parallel);
  double s = 0;
  for (double v : part) s += v;
  return s;
}

}  // namespace fiberfem::core
