#include "core/linear_solver.hpp"

#include <Eigen/Dense>
#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseCholesky>
#ifdef FIBERFEM_HAVE_CHOLMOD
#include <Eigen/CholmodSupport>
#endif

#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

namespace fiberfem::core {

void SolverSettings::validate() const {
  if (!(tolerance > 0 && tolerance < 1))
    throw std::invalid_argument("solver: tolerance must be in (0, 1), got " + std::to_string(tolerance));
  if (max_iterations < 1)
    throw std::invalid_argument("solver: max_iterations must be >= 1, got " + std::to_string(max_iterations));
  if (!(failure_residual > 0 && std::isfinite(failure_residual)))
    throw std::invalid_argument("solver: failure_residual must be > 0, got " + std::to_string(failure_residual));
}

namespace {

double relative_residual(const SparseMatrix& A, const Eigen::VectorXd& b, const Eigen::VectorXd& x) {
  const double bn = b.norm();
  const double rn = (b - A * x).norm();
  return bn > 0 ? rn / bn : rn;
}

/// Block-Jacobi preconditioner: the inverse of each node's diagonal block over its free
/// components (1x1 to 3x3). Follows Eigen's preconditioner concept so ConjugateGradient
/// can use it. Blocks are given as CSR-like starts (rows start[k] .. start[k+1]-1); with
/// none given it is the plain (scalar) Jacobi preconditioner.
class BlockJacobiPreconditioner {
 public:
  using StorageIndex = int;
  enum { ColsAtCompileTime = Eigen::Dynamic, MaxColsAtCompileTime = Eigen::Dynamic };
  BlockJacobiPreconditioner() = default;
  template <class MatType>
  explicit BlockJacobiPreconditioner(const MatType& m) { compute(m); }
  void set_blocks(std::vector<int> starts) { starts_ = std::move(starts); }
  template <class MatType>
  BlockJacobiPreconditioner& analyzePattern(const MatType&) { return *this; }
  template <class MatType>
  BlockJacobiPreconditioner& factorize(const MatType& m) { return compute(m); }
  template <class MatType>
  BlockJacobiPreconditioner& compute(const MatType& m) {
    n_ = static_cast<int>(m.rows());
    if (starts_.empty() || starts_.back() != n_) {
      starts_.resize(static_cast<size_t>(n_) + 1);
      for (int i = 0; i <= n_; ++i) starts_[static_cast<size_t>(i)] = i;
    }
    const int nb = static_cast<int>(starts_.size()) - 1;
    inv_.resize(static_cast<size_t>(nb));
    for (int k = 0; k < nb; ++k) {
      const int r0 = starts_[static_cast<size_t>(k)], sz = starts_[static_cast<size_t>(k) + 1] - r0;
      Mat3 blk = Mat3::Identity();
      for (int i = 0; i < sz; ++i)
        for (typename MatType::InnerIterator it(m, r0 + i); it; ++it) {
          const int j = static_cast<int>(it.col()) - r0;
          if (j >= 0 && j < sz) blk(i, j) = it.value();
        }
      Mat3 inv = blk.inverse();
      if (!inv.allFinite()) inv = blk.diagonal().cwiseInverse().asDiagonal();
      inv_[static_cast<size_t>(k)] = inv;
    }
    return *this;
  }
  template <class Rhs, class Dest>
  void _solve_impl(const Rhs& b, Dest& x) const {
    const int nb = static_cast<int>(starts_.size()) - 1;
    for (int k = 0; k < nb; ++k) {
      const int r0 = starts_[static_cast<size_t>(k)], sz = starts_[static_cast<size_t>(k) + 1] - r0;
      const Mat3& M = inv_[static_cast<size_t>(k)];
      if (sz == 3) {
        x.template segment<3>(r0) = M * b.template segment<3>(r0);
      } else {
        for (int i = 0; i < sz; ++i) {
          double acc = 0;
          for (int j = 0; j < sz; ++j) acc += M(i, j) * b(r0 + j);
          x(r0 + i) = acc;
        }
      }
    }
  }
  template <class Rhs>
  inline const Eigen::Solve<BlockJacobiPreconditioner, Rhs> solve(const Eigen::MatrixBase<Rhs>& b) const {
    return Eigen::Solve<BlockJacobiPreconditioner, Rhs>(*this, b.derived());
  }
  Eigen::ComputationInfo info() { return Eigen::Success; }
  Eigen::Index rows() const { return n_; }
  Eigen::Index cols() const { return n_; }

 private:
  std::vector<int> starts_;
  std::vector<Mat3> inv_;
  int n_ = 0;
};

class PcgSolver final : public LinearSolver {
 public:
  explicit PcgSolver(const SolverSettings& s) : s_(s) {}
  SolveStats solve(const SparseMatrix& A, const Eigen::VectorXd& b, Eigen::VectorXd& x) override {
    cg_.setTolerance(s_.tolerance);
    cg_.setMaxIterations(s_.max_iterations);
    cg_.compute(A);
    if (!s_.warm_start || x.size() != b.size()) x = Eigen::VectorXd::Zero(b.size());
    x = cg_.solveWithGuess(b, x);
    SolveStats st;
    st.iterations = static_cast<int>(cg_.iterations());
    st.relative_residual = cg_.error();
    st.ok = x.allFinite() && std::isfinite(st.relative_residual) && cg_.info() == Eigen::Success;
    return st;
  }
  std::string name() const override { return "pcg"; }
  void set_blocks(std::vector<int> starts) override { cg_.preconditioner().set_blocks(std::move(starts)); }

 private:
  SolverSettings s_;
  Eigen::ConjugateGradient<SparseMatrix, Eigen::Lower | Eigen::Upper, BlockJacobiPreconditioner> cg_;
};

class DirectSolver final : public LinearSolver {
 public:
  SolveStats solve(const SparseMatrix& A, const Eigen::VectorXd& b, Eigen::VectorXd& x) override {
    // A is stored row-major with both triangles; being symmetric, the same arrays read as
    // column-major give the same matrix, so the copy below is a plain copy, not a transpose.
    Acol_ = Eigen::Map<const Eigen::SparseMatrix<double, Eigen::ColMajor, int>>(
        A.rows(), A.cols(), A.nonZeros(), A.outerIndexPtr(), A.innerIndexPtr(), A.valuePtr());
    if (!analysed_) {
      llt_.analyzePattern(Acol_);
      analysed_ = true;
    }
    llt_.factorize(Acol_);
    SolveStats st;
    st.iterations = 1;
    if (llt_.info() != Eigen::Success) {
      st.ok = false;
      st.relative_residual = std::numeric_limits<double>::infinity();
      return st;
    }
    x = llt_.solve(b);
    st.relative_residual = relative_residual(A, b, x);
    st.ok = x.allFinite() && std::isfinite(st.relative_residual);
    return st;
  }
  std::string name() const override { return direct_solver_uses_cholmod() ? "cholmod" : "ldlt"; }

 private:
  Eigen::SparseMatrix<double, Eigen::ColMajor, int> Acol_;
#ifdef FIBERFEM_HAVE_CHOLMOD
  Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double, Eigen::ColMajor, int>, Eigen::Lower> llt_;
#else
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double, Eigen::ColMajor, int>, Eigen::Lower> llt_;
#endif
  bool analysed_ = false;
};

}  // namespace

bool direct_solver_uses_cholmod() {
#ifdef FIBERFEM_HAVE_CHOLMOD
  return true;
#else
  return false;
#endif
}

std::unique_ptr<LinearSolver> make_linear_solver(const SolverSettings& settings) {
  settings.validate();
  if (settings.method == LinearSolverKind::direct) return std::make_unique<DirectSolver>();
  return std::make_unique<PcgSolver>(settings);
}

}  // namespace fiberfem::core
