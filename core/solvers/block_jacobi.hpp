#pragma once
/// @file The block-Jacobi preconditioner of the PCG solver (PreconditionerKind::block_jacobi).

#include "core/types.hpp"

#include <Eigen/Dense>

#include <utility>
#include <vector>

namespace fiberfem::core::detail {

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
  /// The same from the upper block store of `sys` (current, has_blocks()): node block I's
  /// diagonal block read where it is stored, no CSR values needed (sync_matrix() not called).
  /// Gives the same inverses as compute() on the synced matrix.
  template <class System>
  BlockJacobiPreconditioner& compute_from_blocks(const System& sys) {
    n_ = sys.num_free();
    const int nb = n_ / 3;
    if (static_cast<int>(starts_.size()) != nb + 1 || starts_.back() != n_) {
      starts_.resize(static_cast<size_t>(nb) + 1);
      for (int k = 0; k <= nb; ++k) starts_[static_cast<size_t>(k)] = 3 * k;
    }
    inv_.resize(static_cast<size_t>(nb));
    for (int k = 0; k < nb; ++k) {
      const Mat3 blk = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(sys.diagonal_block(k));
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

}  // namespace fiberfem::core::detail
