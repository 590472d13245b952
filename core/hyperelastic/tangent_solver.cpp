#include "core/hyperelastic/tangent_solver.hpp"

#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseLU>
#ifdef FIBERFEM_HAVE_UMFPACK
#include <Eigen/UmfPackSupport>
#endif

#include <algorithm>
#include <chrono>
#include <vector>
#include <stdexcept>

namespace fiberfem::core::hyperelastic {

namespace {

#ifdef FIBERFEM_HAVE_UMFPACK
// UMFPACK's LU with its numeric object in reach (for FloatLU), in its 64-bit-index form
// (umfpack_dl; the matrix copied to 64-bit indices at each factorisation): the 32-bit form
// runs out of its int-indexed workspace on mixed problems of about 150,000 unknowns (Land
// problem 3 on lv_ellipsoid 60 / 25 / 5 failed to factorise at the rest state).
using LongMatrix = Eigen::SparseMatrix<double, Eigen::ColMajor, SuiteSparse_long>;
class LU : public Eigen::UmfPackLU<LongMatrix> {
  using Base = Eigen::UmfPackLU<LongMatrix>;

 public:
  void* numeric() const { return m_numeric; }
  void analyzePattern(const SparseMatrix& A) {
    a_ = A;
    Base::analyzePattern(a_);
  }
  void factorize(const SparseMatrix& A) {  // A with the pattern analysed (UMFPACK's rule): its values copied
    if (A.isCompressed() && A.nonZeros() == a_.nonZeros() && A.rows() == a_.rows())
      std::copy(A.valuePtr(), A.valuePtr() + A.nonZeros(), a_.valuePtr());
    else
      a_ = A;
    Base::factorize(a_);
  }

 private:
  LongMatrix a_;  // the matrix in 64-bit indices; UMFPACK's solve reads it too
};

// A single-precision copy of UMFPACK's factors, P (R A) Q = L U (R the row scaling), to
// apply a lagged factor as BiCGSTAB's preconditioner: L by rows, U by columns, each
// substitution one pass over its values. UMFPACK's own solve walks its packed frontal
// form; on Land problem 2's shipped mesh (10,278 unknowns, 3.1 M entries in each of L and
// U) the copy applies in about half the time, and BiCGSTAB corrects the rounding.
class FloatLU {
 public:
  bool build(const LU& lu, int n) {
    ok_ = false;
    using Long = SuiteSparse_long;
    Long lnz = 0, unz = 0, rows = 0, cols = 0, nz_udiag = 0;
    if (umfpack_dl_get_lunz(&lnz, &unz, &rows, &cols, &nz_udiag, lu.numeric()) != UMFPACK_OK || rows != n || cols != n)
      return false;
    std::vector<Long> Lp(static_cast<size_t>(n) + 1), Lj(static_cast<size_t>(lnz)), Up(static_cast<size_t>(n) + 1),
        Ui(static_cast<size_t>(unz)), P(static_cast<size_t>(n)), Q(static_cast<size_t>(n));
    std::vector<double> Lx(static_cast<size_t>(lnz)), Ux(static_cast<size_t>(unz)), Rs(static_cast<size_t>(n));
    Long do_recip = 0;
    if (umfpack_dl_get_numeric(Lp.data(), Lj.data(), Lx.data(), Up.data(), Ui.data(), Ux.data(), P.data(), Q.data(),
                               nullptr, &do_recip, Rs.data(), lu.numeric()) != UMFPACK_OK)
      return false;
    p_.assign(P.begin(), P.end());
    q_.assign(Q.begin(), Q.end());
    // Rows of L without their unit diagonal (stored last); columns of U with the diagonal
    // kept apart as its reciprocal (stored last).
    lp_.assign(static_cast<size_t>(n) + 1, 0);
    lj_.clear();
    lx_.clear();
    lj_.reserve(static_cast<size_t>(lnz - n));
    lx_.reserve(static_cast<size_t>(lnz - n));
    for (int i = 0; i < n; ++i) {
      for (Long k = Lp[static_cast<size_t>(i)]; k < Lp[static_cast<size_t>(i) + 1] - 1; ++k) {
        lj_.push_back(static_cast<int>(Lj[static_cast<size_t>(k)]));
        lx_.push_back(static_cast<float>(Lx[static_cast<size_t>(k)]));
      }
      lp_[static_cast<size_t>(i) + 1] = lj_.size();
    }
    up_.assign(static_cast<size_t>(n) + 1, 0);
    ui_.clear();
    ux_.clear();
    ui_.reserve(static_cast<size_t>(unz - n));
    ux_.reserve(static_cast<size_t>(unz - n));
    inv_diag_.resize(static_cast<size_t>(n));
    for (int j = 0; j < n; ++j) {
      const Long last = Up[static_cast<size_t>(j) + 1] - 1;
      if (last < Up[static_cast<size_t>(j)] || Ui[static_cast<size_t>(last)] != j || Ux[static_cast<size_t>(last)] == 0.0)
        return false;  // a zero pivot: UMFPACK's own solve reports it
      for (Long k = Up[static_cast<size_t>(j)]; k < last; ++k) {
        ui_.push_back(static_cast<int>(Ui[static_cast<size_t>(k)]));
        ux_.push_back(static_cast<float>(Ux[static_cast<size_t>(k)]));
      }
      up_[static_cast<size_t>(j) + 1] = ui_.size();
      inv_diag_[static_cast<size_t>(j)] = static_cast<float>(1.0 / Ux[static_cast<size_t>(last)]);
    }
    scale_.resize(static_cast<size_t>(n));
    for (int i = 0; i < n; ++i)
      scale_[static_cast<size_t>(i)] = do_recip ? Rs[static_cast<size_t>(i)] : 1.0 / Rs[static_cast<size_t>(i)];
    w_.resize(static_cast<size_t>(n));
    ok_ = true;
    return true;
  }
  bool ok() const { return ok_; }
  template <typename Rhs>
  Eigen::VectorXd solve(const Rhs& b) const {
    const int n = static_cast<int>(p_.size());
    float* w = w_.data();
    // L y = P R b, by rows.
    for (int k = 0; k < n; ++k) {
      const int i = p_[static_cast<size_t>(k)];
      float s = static_cast<float>(scale_[static_cast<size_t>(i)] * b(i));
      for (size_t p = lp_[static_cast<size_t>(k)]; p < lp_[static_cast<size_t>(k) + 1]; ++p)
        s -= lx_[p] * w[lj_[p]];
      w[k] = s;
    }
    // U z = y, by columns from the last.
    for (int j = n - 1; j >= 0; --j) {
      const float z = w[j] * inv_diag_[static_cast<size_t>(j)];
      w[j] = z;
      for (size_t p = up_[static_cast<size_t>(j)]; p < up_[static_cast<size_t>(j) + 1]; ++p) w[ui_[p]] -= ux_[p] * z;
    }
    Eigen::VectorXd x(n);
    for (int k = 0; k < n; ++k) x(q_[static_cast<size_t>(k)]) = static_cast<double>(w[k]);
    return x;
  }

 private:
  bool ok_ = false;
  std::vector<int> p_, q_, lj_, ui_;  // permutations; column (L) and row (U) indices < n
  std::vector<size_t> lp_, up_;       // row (L) and column (U) starts: may pass 2^31
  std::vector<float> lx_, ux_, inv_diag_;
  std::vector<double> scale_;
  mutable std::vector<float> w_;
};
#else
using LU = Eigen::SparseLU<SparseMatrix>;
#endif

// A factor held elsewhere as BiCGSTAB's preconditioner (Eigen's preconditioner interface).
template <class Factor>
class Lagged {
 public:
  Lagged() = default;
  template <typename M>
  explicit Lagged(const M&) {}
  template <typename M>
  Lagged& analyzePattern(const M&) { return *this; }
  template <typename M>
  Lagged& factorize(const M&) { return *this; }
  template <typename M>
  Lagged& compute(const M&) { return *this; }
  void set(const Factor* f) { f_ = f; }
  template <typename Rhs>
  Eigen::VectorXd solve(const Rhs& b) const { return f_->solve(b); }
  Eigen::ComputationInfo info() const { return Eigen::Success; }

 private:
  const Factor* f_ = nullptr;
};

}  // namespace

struct TangentSolver::Factor {
  Factor();
  LU lu;
#ifdef FIBERFEM_HAVE_UMFPACK
  FloatLU lagged;  // lu's factors in single precision, for the lagged solves
#endif
  bool analysed = false;
  /// After lu.factorize: the single-precision copy (where there is one).
  void copy_factor(int n) {
#ifdef FIBERFEM_HAVE_UMFPACK
    if (lu.info() != Eigen::Success || !lagged.build(lu, n)) lagged = FloatLU();  // none: UMFPACK's own solve
#else
    (void)n;
#endif
  }
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
  factor_->copy_factor(static_cast<int>(K.rows()));
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
    factor->copy_factor(static_cast<int>(state.factored.rows()));
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
    const auto lagged = [&](auto& krylov, const auto& factor) {
      krylov.preconditioner().set(&factor);
      krylov.compute(K);
      krylov.setTolerance(forcing);
      krylov.setMaxIterations(kMaxKrylovIterations);
      delta = krylov.solveWithGuess(R, factor.solve(R));
      krylov_iterations_ += static_cast<int>(krylov.iterations());
      ok = krylov.info() == Eigen::Success && delta.allFinite();
    };
#ifdef FIBERFEM_HAVE_UMFPACK
    if (factor_->lagged.ok()) {
      Eigen::BiCGSTAB<SparseMatrix, Lagged<FloatLU>> krylov;
      lagged(krylov, factor_->lagged);
    } else {
      Eigen::BiCGSTAB<SparseMatrix, Lagged<LU>> krylov;
      lagged(krylov, factor_->lu);
    }
#else
    Eigen::BiCGSTAB<SparseMatrix, Lagged<LU>> krylov;
    lagged(krylov, factor_->lu);
#endif
  }
  if (!ok && factorise(K)) {
    delta = factor_->lu.solve(R);
    ok = delta.allFinite();
  }
  seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return ok;
}

}  // namespace fiberfem::core::hyperelastic
