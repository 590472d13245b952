#pragma once
/// @file Smoothed-aggregation algebraic multigrid (AMGCL) as a preconditioner of the step's
/// velocity system: 3 x 3 node blocks, the rigid-body modes of the configuration it was
/// built in as near-null space, one V-cycle (damped Jacobi smoothing) in single precision
/// per application. The PCG solver lags and warps it by the nodes' rotations like the
/// Cholesky factor (PreconditionerKind::amg).

#include "core/types.hpp"

#include <Eigen/SparseCore>

#include <memory>

namespace fiberfem::core {

/// Whether the engine was built with AMGCL (Debian's libamgcl-dev): without it the amg
/// preconditioner is refused by SolverSettings::validate.
bool has_amg();

class AmgHierarchy {
 public:
  AmgHierarchy();
  ~AmgHierarchy();
  AmgHierarchy(AmgHierarchy&&) noexcept;
  AmgHierarchy& operator=(AmgHierarchy&&) noexcept;

  /// Builds the hierarchy of `A` (symmetric positive definite, both triangles stored, row
  /// major; rows 3I..3I+2 are node block I) with the rigid-body modes about `positions`
  /// (3 per block, in block order, m) as near-null space. Replaces any earlier hierarchy.
  /// @return false (and ok() false) when A's size is not a multiple of 3, the positions do
  ///         not match it, or the setup fails.
  bool build(const Eigen::SparseMatrix<double, Eigen::RowMajor, int>& A, const Eigen::VectorXd& positions);
  /// A hierarchy exists.
  bool ok() const;
  /// x = one V-cycle applied to b (sizes of the built matrix; x is resized).
  void apply(const Eigen::VectorXd& b, Eigen::VectorXd& x) const;
  /// Levels of the hierarchy, and its operator complexity (non-zeros of all levels over
  /// those of the finest), for reports; 0 without a hierarchy.
  int levels() const;
  double operator_complexity() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace fiberfem::core
