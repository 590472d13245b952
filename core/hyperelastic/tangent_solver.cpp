#include "core/hyperelastic/tangent_solver.hpp"

#include <Eigen/SparseLU>
#ifdef FIBERFEM_HAVE_UMFPACK
#include <Eigen/UmfPackSupport>
#endif

#include <algorithm>
#include <chrono>
#include <cmath>
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
// apply a lagged factor as GMRES's preconditioner: L by rows, U by columns, each
// substitution one pass over its values. UMFPACK's own solve walks its packed frontal
// form; on Land problem 2's shipped mesh (10,278 unknowns, 3.1 M entries in each of L and
// U) the copy applies in about half the time, and GMRES corrects the rounding.
//
// The factors are supernodal, so a row of L (a column of U) is a few runs of consecutive
// indices: about 78 entries a run on the Land meshes. Each run is kept as its first index
// and length, so a substitution reads 4 bytes an entry (not 8 with an index each) and its
// inner loops are dense dot products and updates, vectorised.
class FloatLU {
 public:
  bool build(const LU& lu, int n) {
    ok_ = false;
    using Long = SuiteSparse_long;
    Long lnz = 0, unz = 0, rows = 0, cols = 0, nz_udiag = 0;
    if (umfpack_dl_get_lunz(&lnz, &unz, &rows, &cols, &nz_udiag, lu.numeric()) != UMFPACK_OK || rows != n || cols != n)
      return false;
    // L, then U: UMFPACK hands each out in double with 64-bit indices (16 bytes an entry),
    // so only one factor's copy is alive at a time (on Land problem 3 at 155,559 unknowns
    // each is several GB).
    std::vector<Long> P(static_cast<size_t>(n)), Q(static_cast<size_t>(n));
    std::vector<double> Rs(static_cast<size_t>(n));
    {
      std::vector<Long> Lp(static_cast<size_t>(n) + 1), Lj(static_cast<size_t>(lnz));
      std::vector<double> Lx(static_cast<size_t>(lnz));
      Long do_recip = 0;
      if (umfpack_dl_get_numeric(Lp.data(), Lj.data(), Lx.data(), nullptr, nullptr, nullptr, P.data(), Q.data(), nullptr,
                                 &do_recip, Rs.data(), lu.numeric()) != UMFPACK_OK)
        return false;
      scale_.resize(static_cast<size_t>(n));
      for (int i = 0; i < n; ++i)
        scale_[static_cast<size_t>(i)] = do_recip ? Rs[static_cast<size_t>(i)] : 1.0 / Rs[static_cast<size_t>(i)];
      // Rows of L without their unit diagonal (stored last).
      l_.clear(n, static_cast<size_t>(lnz - n));
      for (int i = 0; i < n; ++i) {
        for (Long k = Lp[static_cast<size_t>(i)]; k < Lp[static_cast<size_t>(i) + 1] - 1; ++k)
          l_.add(static_cast<int>(Lj[static_cast<size_t>(k)]), static_cast<float>(Lx[static_cast<size_t>(k)]));
        l_.close_line();
      }
    }
    p_.assign(P.begin(), P.end());
    q_.assign(Q.begin(), Q.end());
    {
      std::vector<Long> Up(static_cast<size_t>(n) + 1), Ui(static_cast<size_t>(unz));
      std::vector<double> Ux(static_cast<size_t>(unz));
      if (umfpack_dl_get_numeric(nullptr, nullptr, nullptr, Up.data(), Ui.data(), Ux.data(), nullptr, nullptr, nullptr,
                                 nullptr, nullptr, lu.numeric()) != UMFPACK_OK)
        return false;
      // Columns of U with the diagonal (stored last) kept apart as its reciprocal.
      u_.clear(n, static_cast<size_t>(unz - n));
      inv_diag_.resize(static_cast<size_t>(n));
      for (int j = 0; j < n; ++j) {
        const Long last = Up[static_cast<size_t>(j) + 1] - 1;
        if (last < Up[static_cast<size_t>(j)] || Ui[static_cast<size_t>(last)] != j || Ux[static_cast<size_t>(last)] == 0.0)
          return false;  // a zero pivot: UMFPACK's own solve reports it
        for (Long k = Up[static_cast<size_t>(j)]; k < last; ++k)
          u_.add(static_cast<int>(Ui[static_cast<size_t>(k)]), static_cast<float>(Ux[static_cast<size_t>(k)]));
        u_.close_line();
        inv_diag_[static_cast<size_t>(j)] = static_cast<float>(1.0 / Ux[static_cast<size_t>(last)]);
      }
    }
    w_.resize(static_cast<size_t>(n));
    ok_ = true;
    return true;
  }
  bool ok() const { return ok_; }
  template <typename Rhs>
  Eigen::VectorXd solve(const Rhs& b) const {
    using Span = Eigen::Map<Eigen::VectorXf>;
    using ConstSpan = Eigen::Map<const Eigen::VectorXf>;
    const int n = static_cast<int>(p_.size());
    float* w = w_.data();
    // L y = P R b, by rows.
    for (int k = 0; k < n; ++k) {
      const int i = p_[static_cast<size_t>(k)];
      float s = static_cast<float>(scale_[static_cast<size_t>(i)] * b(i));
      const float* x = l_.x.data() + l_.first_value[static_cast<size_t>(k)];
      for (size_t r = l_.first_run[static_cast<size_t>(k)]; r < l_.first_run[static_cast<size_t>(k) + 1]; ++r) {
        const int len = l_.run_length[r];
        s -= ConstSpan(x, len).dot(ConstSpan(w + l_.run_start[r], len));
        x += len;
      }
      w[k] = s;
    }
    // U z = y, by columns from the last.
    for (int j = n - 1; j >= 0; --j) {
      const float z = w[j] * inv_diag_[static_cast<size_t>(j)];
      w[j] = z;
      const float* x = u_.x.data() + u_.first_value[static_cast<size_t>(j)];
      for (size_t r = u_.first_run[static_cast<size_t>(j)]; r < u_.first_run[static_cast<size_t>(j) + 1]; ++r) {
        const int len = u_.run_length[r];
        Span(w + u_.run_start[r], len) -= z * ConstSpan(x, len);
        x += len;
      }
    }
    Eigen::VectorXd x(n);
    for (int k = 0; k < n; ++k) x(q_[static_cast<size_t>(k)]) = static_cast<double>(w[k]);
    return x;
  }

 private:
  // Sparse lines (rows of L, columns of U) as runs of consecutive indices.
  struct Runs {
    std::vector<size_t> first_run, first_value;  // per line; may pass 2^31
    std::vector<int> run_start, run_length;      // per run
    std::vector<float> x;                        // the values, line after line
    int last_index = -2;
    void clear(int lines, size_t values) {
      first_run.assign(1, 0);
      first_value.assign(1, 0);
      first_run.reserve(static_cast<size_t>(lines) + 1);
      first_value.reserve(static_cast<size_t>(lines) + 1);
      run_start.clear();
      run_length.clear();
      x.clear();
      x.reserve(values);
      last_index = -2;
    }
    void add(int index, float value) {
      if (index == last_index + 1)  // close_line resets last_index: no run crosses lines
        ++run_length.back();
      else {
        run_start.push_back(index);
        run_length.push_back(1);
      }
      last_index = index;
      x.push_back(value);
    }
    void close_line() {
      first_run.push_back(run_start.size());
      first_value.push_back(x.size());
      last_index = -2;
    }
  };
  bool ok_ = false;
  std::vector<int> p_, q_;  // permutations
  Runs l_, u_;
  std::vector<float> inv_diag_;
  std::vector<double> scale_;
  mutable std::vector<float> w_;
};
#else
using LU = Eigen::SparseLU<SparseMatrix>;
#endif

// GMRES preconditioned on the right by a lagged factor M, the preconditioned directions
// z = M^-1 v kept (flexible GMRES, so a factor applied in single precision still gives an
// exact residual): x = Z y minimises |K x - b| over the directions found, and that norm
// is known at each iteration from the Hessenberg system. One application of the factor
// and one product with K an iteration, where BiCGSTAB makes two of each, and the stopping
// test is on the true residual, as Newton's forcing asks. No restart: the caller factorises
// afresh when `max_iterations` do not suffice. @return whether |K x - b| <= tol |b|.
template <class Factor>
bool lagged_gmres(const SparseMatrix& K, const Eigen::VectorXd& b, const Factor& M, double tol, int max_iterations,
                  Eigen::VectorXd& x, int& iterations) {
  const Eigen::Index n = b.size();
  const int m = max_iterations;
  iterations = 0;
  const double b_norm = b.norm();
  if (!(b_norm > 0.0)) {
    x.setZero(n);
    return b_norm == 0.0;
  }
  Eigen::MatrixXd V(n, m + 1), Z(n, m);
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(m + 1, m);
  Eigen::VectorXd g = Eigen::VectorXd::Zero(m + 1), cs(m), sn(m);
  V.col(0) = b / b_norm;
  g(0) = b_norm;
  Eigen::VectorXd w(n);
  for (int j = 0; j < m; ++j) {
    Z.col(j) = M.solve(V.col(j));
    w.noalias() = K * Z.col(j);
    for (int i = 0; i <= j; ++i) {  // modified Gram-Schmidt
      H(i, j) = V.col(i).dot(w);
      w.noalias() -= H(i, j) * V.col(i);
    }
    H(j + 1, j) = w.norm();
    for (int i = 0; i < j; ++i) {  // the earlier rotations on the new column
      const double t = cs(i) * H(i, j) + sn(i) * H(i + 1, j);
      H(i + 1, j) = -sn(i) * H(i, j) + cs(i) * H(i + 1, j);
      H(i, j) = t;
    }
    const double r = std::hypot(H(j, j), H(j + 1, j));
    if (!(r > 0.0) || !std::isfinite(r)) break;  // breakdown or a NaN: no solution from here
    cs(j) = H(j, j) / r;
    sn(j) = H(j + 1, j) / r;
    const double h_next = H(j + 1, j);
    H(j, j) = r;
    H(j + 1, j) = 0.0;
    g(j + 1) = -sn(j) * g(j);
    g(j) = cs(j) * g(j);
    iterations = j + 1;
    if (std::abs(g(j + 1)) <= tol * b_norm || h_next == 0.0) {
      const Eigen::VectorXd y =
          H.topLeftCorner(j + 1, j + 1).triangularView<Eigen::Upper>().solve(g.head(j + 1));
      x.noalias() = Z.leftCols(j + 1) * y;
      return x.allFinite();
    }
    V.col(j + 1) = w / h_next;
  }
  return false;
}
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
  // No iterative refinement inside a solve: GMRES refines (against the current tangent,
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
    int iterations = 0;
#ifdef FIBERFEM_HAVE_UMFPACK
    if (factor_->lagged.ok())
      ok = lagged_gmres(K, R, factor_->lagged, forcing, kMaxKrylovIterations, delta, iterations);
    else
      ok = lagged_gmres(K, R, factor_->lu, forcing, kMaxKrylovIterations, delta, iterations);
#else
    ok = lagged_gmres(K, R, factor_->lu, forcing, kMaxKrylovIterations, delta, iterations);
#endif
    krylov_iterations_ += iterations;
  }
  if (!ok && factorise(K)) {
    delta = factor_->lu.solve(R);
    ok = delta.allFinite();
  }
  seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return ok;
}

}  // namespace fiberfem::core::hyperelastic
