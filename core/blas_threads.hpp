#pragma once
/// @file OpenBLAS's thread count, looked up at run time.
///
/// The engine keeps BLAS on one thread (a multithreaded OpenBLAS spins after each call
/// beside the engine's OpenMP loops, core/solvers/cholesky_factor.cpp) and opens it to the
/// engine's threads only around a large factorisation (core/hyperelastic/tangent_solver.cpp).
/// The functions are found with dlsym, so each is a no-op when the BLAS linked is not
/// OpenBLAS (the reference BLAS, or an OpenBLAS without the symbol).

namespace fiberfem::core::blas {

/// OpenBLAS's thread count now; 0 without OpenBLAS.
int threads();
/// Sets OpenBLAS's thread count (OpenBLAS starts its threads again when they were stopped).
void set_threads(int n);
/// Stops OpenBLAS's threads (they sleep until a later set_threads above one).
void stop_threads();

/// Runs `f` with OpenBLAS on `n` threads (at most the processors there are), then sets the
/// count it had back. Only raises: with the count already at `n` or above, or without
/// OpenBLAS, just runs `f`.
template <class F>
void with_threads(int n, F&& f);

// Implementation detail of with_threads: the raised count, or 0 for none.
int raise_threads(int n);

template <class F>
void with_threads(int n, F&& f) {
  const int before = threads();
  if (raise_threads(n) == 0) {
    f();
    return;
  }
  struct Restore {
    int before;
    ~Restore() { set_threads(before); }
  } restore{before};
  f();
}

}  // namespace fiberfem::core::blas
