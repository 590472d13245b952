#include "core/blas_threads.hpp"

#include <dlfcn.h>
#include <omp.h>

#include <algorithm>

namespace fiberfem::core::blas {
namespace {

template <class Fn>
Fn lookup(const char* name) {
  return reinterpret_cast<Fn>(dlsym(RTLD_DEFAULT, name));
}

using GetThreads = int (*)();
using SetThreads = void (*)(int);
using Shutdown = int (*)();

}  // namespace

int threads() {
  static const auto get = lookup<GetThreads>("openblas_get_num_threads");
  return get ? get() : 0;
}

void set_threads(int n) {
  static const auto set = lookup<SetThreads>("openblas_set_num_threads");
  if (set) set(n);
}

void stop_threads() {
  static const auto stop = lookup<Shutdown>("blas_thread_shutdown_");
  if (stop) stop();
}

int raise_threads(int n) {
  const int before = threads();
  const int wanted = std::min(n, omp_get_num_procs());
  if (before == 0 || wanted <= before) return 0;
  set_threads(wanted);
  return wanted;
}

}  // namespace fiberfem::core::blas
