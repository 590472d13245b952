#include "core/solvers/cholesky_factor.hpp"

#include "core/blas_threads.hpp"

#include <omp.h>

#include <algorithm>

namespace fiberfem::core::detail {

#ifdef FIBERFEM_HAVE_CHOLMOD
// The supernodal factorisation calls BLAS between the engine's OpenMP loops. A
// multithreaded OpenBLAS keeps its threads spinning after the call and slows those loops
// down (measured: the rotation phase 3x slower on two cores), so BLAS runs on one thread.
// Only when it is not on one thread already: OpenBLAS's setter starts its threads again
// when they have been stopped (service/app/main.cpp stops them).
void CholeskyFactor::single_threaded_blas() {
  if (blas::threads() != 1) blas::set_threads(1);
}
#endif
// CHOLMOD's own OpenMP loops (in the supernodal factorisation) ask for teams of
// CHOLMOD_OMP_NUM_THREADS threads, which Debian's build fixes at 4 whatever the machine.
// On two cores that oversubscribes them, and the engine's worker threads then wait in
// the kernel instead of spinning: the factorisation of the 5,760-tet benchmark beam took
// 20 ms instead of 5-6. A host teams region caps every parallel region inside it at the
// engine's thread count (its thread_limit). Not from inside a parallel region, where
// a teams construct may not nest (and CHOLMOD's regions are serialised anyway).
template <class F>
void CholeskyFactor::within_engine_threads(F&& f) {
  if (omp_in_parallel()) {
    f();
    return;
  }
  const int limit = std::max(1, std::min(omp_get_max_threads(), omp_get_num_procs()));
#pragma omp teams num_teams(1) thread_limit(limit)
  f();
}

CholeskyFactor::CholeskyFactor() {
#ifdef FIBERFEM_HAVE_CHOLMOD
  single_threaded_blas();
  // Fill-reducing ordering: CHOLMOD tries AMD and METIS at analysis and keeps the one
  // with the smaller factor. Its own default kept AMD on the 245,760-tet beam (nnz(L)
  // 127 M, 116 GFlop to factorise) where METIS gives 81 M and 104 GFlop; on the
  // slender 5,760-tet beam AMD stays best (418 k against 515 k).
  cholmod_common& c = llt_.cholmod();
  c.nmethods = 2;
  c.method[0].ordering = CHOLMOD_AMD;
  c.method[1].ordering = CHOLMOD_METIS;
  c.postorder = 1;
#endif
}

namespace {

// Whether P (a factor's last matrix) has A's pattern.
bool same_pattern(const Eigen::SparseMatrix<double, Eigen::ColMajor, int>& P, const SparseMatrix& A) {
  return P.rows() == A.rows() && P.nonZeros() == A.nonZeros() && P.isCompressed() && A.isCompressed() &&
         std::equal(A.outerIndexPtr(), A.outerIndexPtr() + A.rows() + 1, P.outerIndexPtr()) &&
         std::equal(A.innerIndexPtr(), A.innerIndexPtr() + A.nonZeros(), P.innerIndexPtr());
}

}  // namespace

bool CholeskyFactor::factorize(const SparseMatrix& A) {
  // The analysis is redone for another pattern, even of the same size.
  if (analysed_ && !same_pattern(Acol_, A)) analysed_ = false;
  Acol_ = Eigen::Map<const Eigen::SparseMatrix<double, Eigen::ColMajor, int>>(
      A.rows(), A.cols(), A.nonZeros(), A.outerIndexPtr(), A.innerIndexPtr(), A.valuePtr());
  within_engine_threads([&] {
    if (!analysed_ || Acol_.rows() != rows_) {
      llt_.analyzePattern(Acol_);
      analysed_ = true;
      rows_ = Acol_.rows();
    }
    llt_.factorize(Acol_);
  });
  ok_ = llt_.info() == Eigen::Success;
#ifdef FIBERFEM_HAVE_CHOLMOD
  if (ok_ && single_precision_) single_.build(llt_.factor());
#endif
  const FactorInfo i = info();
  cost_in_applications_ = i.nonzeros > 0 ? i.flops / (4 * i.nonzeros) : 0;
  return ok_;
}

void CholeskyFactor::adopt_analysis(const CholeskyFactor& other, const SparseMatrix& A) {
#ifdef FIBERFEM_HAVE_CHOLMOD
  // Already analysed (for A's pattern or another: factorize() then analyses afresh), or
  // other's analysis is of another pattern (its last matrix's).
  if (analysed_ || !other.analysed_ || !other.llt_.factor() || !same_pattern(other.Acol_, A)) return;
  llt_.adopt_analysis(other.llt_);
  Acol_ = other.Acol_;  // the pattern of the analysis (factorize() takes A's values)
  if (llt_.factor()) {
    analysed_ = true;
    rows_ = other.rows_;
  }
#else
  (void)other;
  (void)A;
#endif
}

FactorInfo CholeskyFactor::info() const {
  FactorInfo i;
  i.factored = ok_;
  if (!ok_) return i;
#ifdef FIBERFEM_HAVE_CHOLMOD
  const cholmod_common& c = const_cast<OpenCholmodSupernodalLLT<Eigen::SparseMatrix<double, Eigen::ColMajor, int>>&>(llt_).cholmod();
  i.nonzeros = c.lnz;
  i.flops = c.fl;
  const int ordering = c.selected >= 0 && c.selected < CHOLMOD_MAXMETHODS ? c.method[c.selected].ordering : -1;
  i.ordering = ordering == CHOLMOD_AMD ? "amd" : ordering == CHOLMOD_METIS ? "metis" : ordering == CHOLMOD_NESDIS ? "nesdis" : "other";
  i.solve_threads = single_precision_ && single_.ok() && single_.parallel() && omp_get_max_threads() >= 2 ? 2 : 1;
#else
  const auto& L = llt_.matrixL().nestedExpression();
  i.nonzeros = static_cast<double>(L.nonZeros());
  for (Eigen::Index j = 0; j < L.outerSize(); ++j) {  // sum of squared column counts
    const double c = static_cast<double>(L.outerIndexPtr()[j + 1] - L.outerIndexPtr()[j]);
    i.flops += c * c;
  }
  i.ordering = "amd";
#endif
  return i;
}

}  // namespace fiberfem::core::detail
