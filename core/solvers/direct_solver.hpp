#pragma once
/// @file The direct solver (LinearSolverKind::direct): a sparse Cholesky factorisation of
/// every matrix.

#include "core/linear_solver.hpp"
#include "core/solvers/cholesky_factor.hpp"

namespace fiberfem::core::detail {

class DirectSolver final : public LinearSolver {
 public:
  SolveStats solve(const SparseMatrix& A, const Eigen::VectorXd& b, Eigen::VectorXd& x) override;
  SolveStats solve_same_matrix(const SparseMatrix& A, const Eigen::VectorXd& b, Eigen::VectorXd& x) override;
  std::string name() const override { return direct_solver_uses_cholmod() ? "cholmod" : "llt"; }
  FactorInfo factor_info() const override {
    FactorInfo i = factor_.info();
    i.solve_threads = 1;  // CHOLMOD's double solve
    return i;
  }

 private:
  CholeskyFactor factor_;
};

}  // namespace fiberfem::core::detail
