#pragma once
/// @file Solution recycling of the PCG solver (SolverSettings::recycled_solutions): the
/// initial guess as the best combination of the last solutions.

#include "core/linear_solver.hpp"

#include <Eigen/Dense>

#include <array>

namespace fiberfem::core::detail {

/// The last solutions of a PCG solver and the projection of a new solve's guess onto them.
/// Allocates nothing after the first solve of a size.
class SolutionRecycler {
 public:
  /// Keeps up to `capacity` solutions, in [0, 64] (0: recycling off).
  explicit SolutionRecycler(int capacity) : capacity_(capacity) {}
  /// Adds solution x (normalised) to the basis, replacing the oldest when full.
  void remember(const Eigen::VectorXd& x);
  /// x <- the combination of the remembered solutions with the least A-norm error for
  /// A x = b. Returns A x for it (the first residual then needs no product), or nullptr
  /// when x was left as given. `blocks`: the system whose current upper blocks hold A
  /// (SparseSystem::has_blocks), or nullptr for A's CSR values.
  const Eigen::VectorXd* project(const SparseMatrix& A, const Eigen::VectorXd& b, Eigen::VectorXd& x,
                                 const SparseSystem* blocks);
  /// Forgets every solution (the state jumped).
  void forget() { count_ = next_ = 0; }
  /// Whether no solution is remembered (the next project() leaves the guess as given).
  bool empty() const { return count_ == 0; }
  /// The basis into / from LinearSolverState's history fields.
  void save(LinearSolverState& st) const;
  /// @throws std::invalid_argument if the saved basis is inconsistent.
  static void check(const LinearSolverState& st);
  void load(const LinearSolverState& st);

 private:
  int capacity_ = 0;
  // Recycled subspace: the last solutions (normalised), one per row-major column so that
  // A times all of them is one pass over A.
  using RowMajorMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  RowMajorMatrix history_;
  int count_ = 0, next_ = 0;
  // The projection's small matrices, sized at most 64 (SolverSettings::recycled_solutions):
  // fixed-capacity Eigen types, so the projection allocates nothing.
  using SmallMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 64, 64>;
  using SmallVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 64, 1>;
  SmallMatrix G_;
  SmallVector Wb_;
  // The projection's sums per part of the rows (fixed parts: the same bits on any thread count).
  static constexpr int kProjectionParts = 8;
  static constexpr int kParallelRows = 2000;  // remember()'s strided copy on the threads from this many rows
  /// First row of part p of kProjectionParts over `rows` rows (p = kProjectionParts: the end).
  static int part_begin(int rows, int p) { return static_cast<int>(static_cast<long>(rows) * p / kProjectionParts); }
  std::array<SmallMatrix, kProjectionParts> part_g_;
  std::array<SmallVector, kProjectionParts> part_wb_;
  // A W, row by row, from the projection's pass, and A x0 = (A W) y for its guess: PCG's
  // first residual then needs no product with A (one of the 2 to 3 products of a step at
  // the interactive tolerance).
  RowMajorMatrix AW_;
  Eigen::VectorXd guess_Ax_;
  Eigen::SelfAdjointEigenSolver<SmallMatrix> eig_;
};

}  // namespace fiberfem::core::detail
