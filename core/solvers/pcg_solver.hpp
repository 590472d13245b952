#pragma once
/// @file The PCG solver (LinearSolverKind::pcg): scaling, the choice between the block
/// store and the CSR values, solution recycling, and the preconditioner with its lagged
/// factors around the conjugate-gradient iteration.

#include "core/linear_solver.hpp"
#include "core/solvers/block_jacobi.hpp"
#include "core/solvers/lagged_factors.hpp"
#include "core/solvers/pcg.hpp"
#include "core/solvers/solution_recycler.hpp"
#include "core/solvers/warp_preconditioner.hpp"

namespace fiberfem::core::detail {

class PcgSolver final : public LinearSolver {
 public:
  explicit PcgSolver(const SolverSettings& s)
      : s_(s), recycler_(s.recycled_solutions), lagged_(s),
        jacobi_first_(s.preconditioner == PreconditionerKind::cholesky && s.jacobi_first != 0) {
    warp_pre_.set_state(&lagged_.warp());
  }
  SolveStats solve(const SparseMatrix& A, const Eigen::VectorXd& b, Eigen::VectorXd& x) override;
  /// Starts from `x` itself (no projection on the recycled solutions, which belong to
  /// another right-hand side, and none remembered).
  SolveStats solve_same_matrix(const SparseMatrix& A, const Eigen::VectorXd& b, Eigen::VectorXd& x) override;
  std::string name() const override { return std::string("pcg/") + to_string(s_.preconditioner); }
  FactorInfo factor_info() const override { return lagged_.info(); }
  int threads_beside() const override { return lagged_.threads_beside(); }
  void set_blocks(std::vector<int> starts) override {
    lagged_.warp().starts = starts;
    jacobi_pre_.set_blocks(std::move(starts));
  }
  /// Not while block Jacobi runs first (jacobi_first): a solve that switches to the factor
  /// takes them from the rotation source then.
  bool uses_block_rotations() const override {
    return s_.preconditioner != PreconditionerKind::block_jacobi && !jacobi_first_;
  }
  void set_block_rotations(const std::vector<Mat3>& rotations) override {
    lagged_.warp().current = rotations;
    rotations_given_ = true;
  }
  void set_block_rotation_source(std::function<const std::vector<Mat3>&()> source) override {
    rotation_source_ = std::move(source);
  }
  bool uses_block_positions() const override { return s_.preconditioner == PreconditionerKind::amg; }
  void set_block_positions(const Eigen::VectorXd& positions) override { lagged_.set_block_positions(positions); }
  void invalidate() override { lagged_.invalidate(); }
  void set_matrix_key(double key) override { lagged_.set_key(key); }
  void set_system(SparseSystem* system) override { system_ = system; }
  bool reads_blocks() const override { return true; }
  void forget_solutions() override { recycler_.forget(); }
  bool takes_guess() const override { return s_.warm_start && s_.recycled_solutions > 0 && recycler_.empty(); }
  LinearSolverState save_state() const override;
  void load_state(const LinearSolverState& st, const SparseMatrix& pattern) override;

 private:
  SolveStats solve_scaled(const SparseMatrix& A, const Eigen::VectorXd& b, Eigen::VectorXd& x,
                          const Eigen::VectorXd* Ax0);
  SolveStats solve_factored(const SparseMatrix& A, const Eigen::VectorXd& b, Eigen::VectorXd& x,
                            const Eigen::VectorXd* Ax0);
  SolveStats solve_lagged(FactorSlot& slot, const SparseMatrix& A, const Eigen::VectorXd& b, Eigen::VectorXd& x,
                          const Eigen::VectorXd* Ax0, SolveStats& st);
  template <class Preconditioner>
  SolveStats run(Preconditioner& pre, const SparseMatrix& A, const Eigen::VectorXd& b, Eigen::VectorXd& x,
                 const Eigen::VectorXd* Ax0, int max_iterations = -1);
  /// SolverSettings::jacobi_first: a solve with block Jacobi, cut off where the run's
  /// iterations beyond the break-even would pass the allowance (jacobi_first_allowance);
  /// false (x back at its guess) when cut off or failed, and the run goes on with the factor.
  bool jacobi_first_solve(const SparseMatrix& A, const Eigen::VectorXd& b, Eigen::VectorXd& x,
                          const Eigen::VectorXd* Ax0, SolveStats& cg);
  static SolveStats failed(SolveStats st);
  /// The node rotations from the source when the caller gave none for this solve.
  void ensure_rotations();
  /// SolverSettings::jacobi_first's break-even for A, iterations.
  double jacobi_first_even(const SparseMatrix& A) const;

  SolverSettings s_;
  Pcg pcg_;
  SolutionRecycler recycler_;
  LaggedFactors lagged_;
  BlockJacobiPreconditioner jacobi_pre_;
  WarpCholeskyPreconditioner warp_pre_;
  SparseSystem* system_ = nullptr;
  bool use_blocks_ = false;
  bool jacobi_first_ = false;     // still on block Jacobi (SolverSettings::jacobi_first)
  double jacobi_excess_ = 0;      // its iterations beyond the break-even, summed (>= 0)
  std::function<const std::vector<Mat3>&()> rotation_source_;
  bool rotations_given_ = false;  // set_block_rotations since the last solve()
  Eigen::VectorXd scaled_b_, first_guess_;  // solve()'s b / |b| and solve_scaled()'s x0 (kept: no allocation)
};

}  // namespace fiberfem::core::detail
