#pragma once
/// @file The warp preconditioner W A_0^-1 W^T of the PCG solver (PreconditionerKind::cholesky
/// and amg): a lagged factor or amg hierarchy of an earlier matrix (a FactorSlot), warped
/// by the change of each node block's rotation since it was made.

#include "core/amg_preconditioner.hpp"
#include "core/solvers/cholesky_factor.hpp"

#include <Eigen/Core>

#include <memory>
#include <vector>

namespace fiberfem::core::detail {

struct BesideFactor;  // lagged_factors.hpp

/// One lagged factor: the factorisation of an earlier matrix and the node-block rotations
/// it was made at.
struct FactorSlot {
  CholeskyFactor factor;
  AmgHierarchy amg;                 // instead of the factor, with PreconditionerKind::amg
  SparseMatrix amg_matrix;          // the matrix the amg was built from (checkpoints)
  Eigen::VectorXd amg_positions;    // node-block positions the amg was built at
  std::vector<Mat3> at_factor;
  Eigen::Index rows = -1;
  bool stale = true;       // refactorise before the next use
  int baseline = -1;       // iterations of the first solve with this factor (-1: none yet)
  double excess = 0;       // iterations beyond the baseline summed over the later solves
  double key = 0;          // which matrix family (the step size h that built it)
  long last_used = 0;
  /// The slot's first factor while it is made beside the steps (no factor yet).
  std::shared_ptr<BesideFactor> beside;
};

/// What the warp preconditioner shares with its solver: the slot in use, the node blocks,
/// and the current node-block rotations.
struct WarpState {
  FactorSlot* slot = nullptr;
  std::vector<int> starts;        // node blocks
  std::vector<Mat3> current;      // block rotations now
  std::vector<Mat3> warp;         // current * at_factor^T, per block
  mutable Eigen::VectorXd work;
  const CholeskyFactor& factor() const { return slot->factor; }
  /// z = A_0^-1 r with the slot's factor, or one V-cycle of its amg hierarchy.
  void apply_lagged(const Eigen::VectorXd& r, Eigen::VectorXd& z) const {
    if (slot->amg.ok())
      slot->amg.apply(r, z);
    else
      slot->factor.precondition(r, z);
  }
  void update_warp() {
    const std::vector<Mat3>& at = slot->at_factor;
    const size_t nb = current.size();
    warp.resize(nb);
    for (size_t k = 0; k < nb; ++k)
      warp[k] = k < at.size() ? Mat3(current[k] * at[k].transpose()) : Mat3::Identity();
  }
};

/// Eigen preconditioner concept around WarpState: x = W A_0^-1 W^T b, with W the per-node
/// rotation change (blocks with fixed components are not warped).
class WarpCholeskyPreconditioner {
 public:
  using StorageIndex = int;
  enum { ColsAtCompileTime = Eigen::Dynamic, MaxColsAtCompileTime = Eigen::Dynamic };
  WarpCholeskyPreconditioner() = default;
  void set_state(WarpState* s) { s_ = s; }
  template <class MatType>
  WarpCholeskyPreconditioner& analyzePattern(const MatType&) { return *this; }
  template <class MatType>
  WarpCholeskyPreconditioner& factorize(const MatType& m) { return compute(m); }
  template <class MatType>
  WarpCholeskyPreconditioner& compute(const MatType& m) {
    n_ = m.rows();
    return *this;
  }
  template <class Rhs, class Dest>
  void _solve_impl(const Rhs& b, Dest& x) const {
    const bool warp = !s_->warp.empty() && s_->starts.size() == s_->warp.size() + 1;
    if (!warp) {
      s_->apply_lagged(b, x);
      return;
    }
    Eigen::VectorXd& y = s_->work;
    y = b;
    const int nb = static_cast<int>(s_->warp.size());
    for (int k = 0; k < nb; ++k) {
      const int r0 = s_->starts[static_cast<size_t>(k)];
      if (s_->starts[static_cast<size_t>(k) + 1] - r0 == 3)
        y.segment<3>(r0) = s_->warp[static_cast<size_t>(k)].transpose() * b.template segment<3>(r0);
    }
    s_->apply_lagged(y, x);
    for (int k = 0; k < nb; ++k) {
      const int r0 = s_->starts[static_cast<size_t>(k)];
      if (s_->starts[static_cast<size_t>(k) + 1] - r0 == 3) {
        const Vec3 z = x.template segment<3>(r0);
        x.template segment<3>(r0) = s_->warp[static_cast<size_t>(k)] * z;
      }
    }
  }
  template <class Rhs>
  inline const Eigen::Solve<WarpCholeskyPreconditioner, Rhs> solve(const Eigen::MatrixBase<Rhs>& b) const {
    return Eigen::Solve<WarpCholeskyPreconditioner, Rhs>(*this, b.derived());
  }
  Eigen::ComputationInfo info() { return Eigen::Success; }
  Eigen::Index rows() const { return n_; }
  Eigen::Index cols() const { return n_; }

 private:
  WarpState* s_ = nullptr;
  Eigen::Index n_ = 0;
};

}  // namespace fiberfem::core::detail
