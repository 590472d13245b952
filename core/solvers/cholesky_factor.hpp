#pragma once
/// @file The sparse Cholesky factor of the engine's SPD matrix (CHOLMOD supernodal, or
/// Eigen's simplicial LLT without CHOLMOD), for the direct solver and the lagged
/// preconditioner.

#include "core/linear_solver.hpp"
#include "core/solvers/single_precision_solve.hpp"

#include <Eigen/SparseCholesky>
#ifdef FIBERFEM_HAVE_CHOLMOD
#include <Eigen/CholmodSupport>
#endif

namespace fiberfem::core::detail {

#ifdef FIBERFEM_HAVE_CHOLMOD
/// Eigen's CHOLMOD wrapper with its factor exposed (for the single-precision copy).
template <class Matrix>
class OpenCholmodSupernodalLLT : public Eigen::CholmodSupernodalLLT<Matrix, Eigen::Lower> {
 public:
  const cholmod_factor* factor() const { return this->m_cholmodFactor; }
  /// Takes a copy of `other`'s factor as this one's symbolic analysis (and its analysis
  /// statistics), as analyzePattern() of the same pattern would make it.
  void adopt_analysis(const OpenCholmodSupernodalLLT& other) {
    cholmod_common& c = this->cholmod();
    const cholmod_common& from = const_cast<OpenCholmodSupernodalLLT&>(other).cholmod();
    if (this->m_cholmodFactor) cholmod_free_factor(&this->m_cholmodFactor, &c);
    this->m_cholmodFactor = cholmod_copy_factor(other.m_cholmodFactor, &c);
    c.lnz = from.lnz;
    c.fl = from.fl;
    c.selected = from.selected;
    this->m_isInitialized = true;
    this->m_info = this->m_cholmodFactor ? Eigen::Success : Eigen::NumericalIssue;
    this->m_analysisIsOk = this->m_cholmodFactor != nullptr;
    this->m_factorizationIsOk = false;
  }
};
#endif

/// A sparse Cholesky factorisation of the engine's SPD matrix (stored row-major with both
/// triangles; being symmetric, the same arrays read as column-major give the same matrix).
/// CHOLMOD supernodal when built with it, else Eigen's simplicial LLT. The symbolic
/// analysis is done once per pattern.
class CholeskyFactor {
 public:
  CholeskyFactor();
  /// Factorises A (the symbolic analysis once per pattern); false when A is not positive definite.
  bool factorize(const SparseMatrix& A);
  /// Before this factor's first factorize(A): takes `other`'s symbolic analysis when it was
  /// made for A's pattern (the fill-reducing ordering, AMD and METIS tried, is most of a
  /// first factorisation's time on small systems). Nothing otherwise, or without CHOLMOD.
  void adopt_analysis(const CholeskyFactor& other, const SparseMatrix& A);
  bool ok() const { return ok_; }
  /// What a factorisation costs in applications of the factor: its flops over 4 nnz(L)
  /// (one forward and one backward substitution, a multiply and an add per entry); set by
  /// factorize().
  double iterations_per_factorisation() const { return cost_in_applications_; }
  FactorInfo info() const;
  /// The matrix of the last factorize() (column-major copy of its arrays).
  const Eigen::SparseMatrix<double, Eigen::ColMajor, int>& matrix() const { return Acol_; }
  template <class Rhs>
  Eigen::VectorXd solve(const Rhs& b) const { return llt_.solve(b); }
  /// Keep a single-precision copy of the factor for `precondition` (CHOLMOD only).
  void set_single_precision(bool on) { single_precision_ = on; }
  /// x ~ A^-1 b for preconditioning: the single-precision copy when there is one.
  template <class Rhs, class Dest>
  void precondition(const Rhs& b, Dest& x) const {
#ifdef FIBERFEM_HAVE_CHOLMOD
    if (single_precision_ && single_.ok()) {
      single_.solve(b, x);
      return;
    }
#endif
    x = llt_.solve(b);
  }

 private:
#ifdef FIBERFEM_HAVE_CHOLMOD
  static void single_threaded_blas();
#endif
  template <class F>
  static void within_engine_threads(F&& f);
  Eigen::SparseMatrix<double, Eigen::ColMajor, int> Acol_;
  bool single_precision_ = false;
#ifdef FIBERFEM_HAVE_CHOLMOD
  OpenCholmodSupernodalLLT<Eigen::SparseMatrix<double, Eigen::ColMajor, int>> llt_;
  SinglePrecisionSupernodalSolve single_;
#else
  Eigen::SimplicialLLT<Eigen::SparseMatrix<double, Eigen::ColMajor, int>, Eigen::Lower> llt_;
#endif
  bool analysed_ = false;
  double cost_in_applications_ = 0;
  bool ok_ = false;
  Eigen::Index rows_ = -1;
};

}  // namespace fiberfem::core::detail
