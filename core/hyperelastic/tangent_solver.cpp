#include "core/hyperelastic/tangent_solver.hpp"

#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseLU>
#ifdef FIBERFEM_HAVE_UMFPACK
#include <Eigen/UmfPackSupport>
#endif

#include <chrono>
#include <stdexcept>

namespace fiberfem::core::hyperelastic {

namespace {

#ifdef FIBERFEM_HAVE_UMFPACK
using LU = Eigen::UmfPackLU<SparseMatrix>;
#else
using LU = Eigen::SparseLU<SparseMatrix>;
#endif

// An LU held elsewhere as BiCGSTAB's preconditioner (Eigen's preconditioner interface).
class LaggedLU {
 public:
  LaggedLU() = default;
  template <typename M>
  explicit LaggedLU(const M&) {}
  template <typename M>
  LaggedLU& analyzePattern(const M&) { return *this; }
  template <typename M>
  LaggedLU& factorize(const M&) { return *this; }
  template <typename M>
  LaggedLU& compute(const M&) { return *this; }
  void set(const LU* lu) { lu_ = lu; }
  template <typename Rhs>
  Eigen::VectorXd solve(const Rhs& b) const { return lu_->solve(b); }
  Eigen::ComputationInfo info() const { return Eigen::Success; }

 private:
  const LU* lu_ = nullptr;
};

}  // namespace

struct TangentSolver::Factor {
  Factor();
  LU lu;
  bool analysed = false;
};

TangentSolver::Factor::Factor() {
#ifdef FIBERFEM_HAVE_UMFPACK
  // The tangent is symmetric in pattern (in value but for a follower load's stiffness):
  // UMFPACK's symmetric strategy orders A + A^T by nested dissection (METIS) instead of its
  // unsymmetric column ordering, which filled about twice as much on the Land beam.
  lu.umfpackControl()(UMFPACK_STRATEGY) = UMFPACK_STRATEGY_SYMMETRIC;
  lu.umfpackControl()(UMFPACK_ORDERING) = UMFPACK_ORDERING_METIS;
  // No iterative refinement inside a solve: BiCGSTAB refines (against the current tangent,
  // which a lagged factor's refinement would not), and Newton's forcing sets the accuracy.
  lu.umfpackControl()(UMFPACK_IRSTEP) = 0;
#endif
}

TangentSolver::TangentSolver(bool keeps_state) : factor_(std::make_unique<Factor>()), keeps_state_(keeps_state) {}

TangentSolver::~TangentSolver() = default;

bool TangentSolver::factorise(const SparseMatrix& K) {
  if (!factor_->analysed) {
    factor_->lu.analyzePattern(K);
    factor_->analysed = true;
    if (keeps_state_) analysed_ = K;
  }
  factor_->lu.factorize(K);
  ++factorisations_;
  have_factor_ = factor_->lu.info() == Eigen::Success;
  if (keeps_state_) factored_ = have_factor_ ? K : SparseMatrix();
  return have_factor_;
}

void TangentSolver::take_memory(TangentSolver& other) {
  std::swap(factor_, other.factor_);
  std::swap(have_factor_, other.have_factor_);
  std::swap(analysed_, other.analysed_);
  std::swap(factored_, other.factored_);
  other.factor_ = std::make_unique<Factor>();
  other.have_factor_ = false;
  other.analysed_ = SparseMatrix();
  other.factored_ = SparseMatrix();
}

// The symbolic analysis reads the values too (UMFPACK's pivot preferences), so it is made
// again from the very matrix it was made from, then the factor from its own.
void TangentSolver::restore(const State& state) {
  auto factor = std::make_unique<Factor>();
  bool have = false;
  if (state.analysed.rows() > 0) {
    factor->lu.analyzePattern(state.analysed);
    factor->analysed = true;
  }
  if (state.factored.rows() > 0) {
    if (!factor->analysed) throw std::invalid_argument("tangent solver state: a factor without its analysis");
    factor->lu.factorize(state.factored);
    if (factor->lu.info() != Eigen::Success) throw std::invalid_argument("tangent solver state: its matrix does not factorise");
    have = true;
  }
  factor_ = std::move(factor);
  have_factor_ = have;
  analysed_ = state.analysed;
  factored_ = state.factored;
}

bool TangentSolver::solve(const SparseMatrix& K, const Eigen::VectorXd& R, double forcing, bool fresh, Eigen::VectorXd& delta) {
  const auto t0 = std::chrono::steady_clock::now();
  bool ok = false;
  if (have_factor_ && !fresh) {
    Eigen::BiCGSTAB<SparseMatrix, LaggedLU> krylov;
    krylov.preconditioner().set(&factor_->lu);
    krylov.compute(K);
    krylov.setTolerance(forcing);
    krylov.setMaxIterations(kMaxKrylovIterations);
    delta = krylov.solveWithGuess(R, factor_->lu.solve(R));
    krylov_iterations_ += static_cast<int>(krylov.iterations());
    ok = krylov.info() == Eigen::Success && delta.allFinite();
  }
  if (!ok && factorise(K)) {
    delta = factor_->lu.solve(R);
    ok = delta.allFinite();
  }
  seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return ok;
}

}  // namespace fiberfem::core::hyperelastic
