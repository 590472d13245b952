#include "core/solvers/direct_solver.hpp"

#include <cmath>
#include <limits>

namespace fiberfem::core::detail {
namespace {

double relative_residual(const SparseMatrix& A, const Eigen::VectorXd& b, const Eigen::VectorXd& x) {
  const double bn = b.norm();
  const double rn = (b - A * x).norm();
  return bn > 0 ? rn / bn : rn;
}

}  // namespace

SolveStats DirectSolver::solve(const SparseMatrix& A, const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  SolveStats st;
  st.iterations = 1;
  st.factorizations = 1;
  if (!factor_.factorize(A)) {
    st.ok = false;
    st.relative_residual = std::numeric_limits<double>::infinity();
    return st;
  }
  x = factor_.solve(b);
  st.relative_residual = relative_residual(A, b, x);
  st.ok = x.allFinite() && std::isfinite(st.relative_residual);
  return st;
}

SolveStats DirectSolver::solve_same_matrix(const SparseMatrix& A, const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  SolveStats st;
  st.iterations = 1;
  x = factor_.solve(b);
  st.relative_residual = relative_residual(A, b, x);
  st.ok = x.allFinite() && std::isfinite(st.relative_residual);
  return st;
}

}  // namespace fiberfem::core::detail
