#pragma once
/// @file A single-precision copy of a CHOLMOD supernodal factor and its substitutions, for
/// preconditioning (SolverSettings::single_precision_preconditioner). CHOLMOD builds only.

#ifdef FIBERFEM_HAVE_CHOLMOD
#include "core/parallel.hpp"

#include <Eigen/CholmodSupport>
#include <Eigen/Dense>
#include <omp.h>

#include <array>
#include <utility>
#include <vector>

namespace fiberfem::core::detail {

/// Forward and back substitution with a single-precision copy of a CHOLMOD supernodal
/// LL^T factor, for preconditioning: half the memory traffic of the double factor, and no
/// allocation per solve. Per supernode: a dense triangular solve on its diagonal block and
/// a dense matrix-vector product with the rows below (Eigen), scattered or gathered through
/// the supernode's row list. Measured on the 5,760-tet benchmark beam (nnz(L) 440k):
/// 0.22 ms per solve against 0.32 ms for cholmod_solve in double.
///
/// Two threads share a solve when the supernodal elimination tree has two disjoint sets of
/// subtrees of similar size (a nested-dissection ordering has them; AMD on a slender beam
/// gives a chain and stays on one thread). Each thread substitutes through its own
/// subtrees; the supernodes above them (the top) are done on one thread in between. In the
/// forward pass a subtree's updates to top rows go to its thread's own copy of those rows,
/// summed before the top is solved; the backward pass only reads top rows.
class SinglePrecisionSupernodalSolve {
 public:
  /// Copies `L` (supernodal, real); false (and unusable) for any other kind of factor.
  bool build(const cholmod_factor* L);
  bool ok() const { return ok_; }
  /// Whether solves run on two threads (the tree split pays), for tests and reports.
  bool parallel() const { return !ranges_[0].empty() && !ranges_[1].empty(); }

  /// x = A^-1 b with the factor of A = P^T L L^T P (x and b may not alias).
  template <class Rhs, class Dest>
  void solve(const Rhs& b, Dest& x) const {
    if (!parallel()) {
      for (int i = 0; i < n_; ++i) w_(i) = static_cast<float>(b(perm_[static_cast<size_t>(i)]));
      const int ns = static_cast<int>(super_.size()) - 1;
      forward(0, ns - 1, 0, nullptr);
      backward(0, ns - 1, 0);
      for (int i = 0; i < n_; ++i) x(perm_[static_cast<size_t>(i)]) = static_cast<double>(w_(i));
      return;
    }
    // Where the tree splits, the split order is followed on any number of threads (one
    // thread walks both parts in turn), so the result does not depend on the thread count.
    if (!threaded()) {
      for (int i = 0; i < n_; ++i) w_(i) = static_cast<float>(b(perm_[static_cast<size_t>(i)]));
      for (int part = 0; part < 2; ++part) forward_part(part);
      solve_top();
      for (int part = 0; part < 2; ++part) backward_part(part);
      for (int i = 0; i < n_; ++i) x(perm_[static_cast<size_t>(i)]) = static_cast<double>(w_(i));
      return;
    }
    const int cpu = current_cpu();
#pragma omp parallel
    {
      keep_team_apart(cpu);
      const int nt = omp_get_num_threads(), t = omp_get_thread_num();
#pragma omp for schedule(static)
      for (int i = 0; i < n_; ++i) w_(i) = static_cast<float>(b(perm_[static_cast<size_t>(i)]));
      for (int part = t; part < 2; part += nt) forward_part(part);
#pragma omp barrier
#pragma omp single
      solve_top();  // the others wait: scratch 0 is free; implicit barrier
      for (int part = t; part < 2; part += nt) backward_part(part);
#pragma omp barrier
#pragma omp for schedule(static)
      for (int i = 0; i < n_; ++i) x(perm_[static_cast<size_t>(i)]) = static_cast<double>(w_(i));
    }
  }

 private:
  struct Shape {
    int first, columns, below;
  };
  using Mat = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic>;
  using Block = Eigen::Map<const Mat, 0, Eigen::OuterStride<>>;
  Shape shape(int s) const {
    const size_t k = static_cast<size_t>(s);
    const int nc = static_cast<int>(super_[k + 1] - super_[k]);
    return {static_cast<int>(super_[k]), nc, static_cast<int>(pi_[k + 1] - pi_[k]) - nc};
  }
  Block block(int s, const Shape& sh) const {
    return Block(values_.data() + px_[static_cast<size_t>(s)], sh.columns + sh.below, sh.columns,
                 Eigen::OuterStride<>(sh.columns + sh.below));
  }
  // L z = P b over supernodes a..z with scratch vector k; `target` (when given) redirects
  // each row-list entry to where this part writes its update (the row, or its copy of a
  // top row).
  void forward(int a, int z, int k, const int* target) const {
    Eigen::VectorXf& tmp = t_[static_cast<size_t>(k)];
    for (int s = a; s <= z; ++s) {
      const Shape sh = shape(s);
      const Block L = block(s, sh);
      auto ws = w_.segment(sh.first, sh.columns);
      L.topRows(sh.columns).triangularView<Eigen::Lower>().solveInPlace(ws);
      if (sh.below == 0) continue;
      tmp.head(sh.below).noalias() = L.bottomRows(sh.below) * ws;
      const size_t off = static_cast<size_t>(pi_[static_cast<size_t>(s)] + sh.columns);
      const int* below = (target ? target : rows_.data()) + off;
      for (int j = 0; j < sh.below; ++j) w_(below[j]) -= tmp(j);
    }
  }
  // L^T y = z over supernodes z..a (descending).
  void backward(int a, int z, int k) const {
    Eigen::VectorXf& tmp = t_[static_cast<size_t>(k)];
    for (int s = z; s >= a; --s) {
      const Shape sh = shape(s);
      const Block L = block(s, sh);
      auto ws = w_.segment(sh.first, sh.columns);
      if (sh.below > 0) {
        const int* below = rows_.data() + pi_[static_cast<size_t>(s)] + sh.columns;
        for (int j = 0; j < sh.below; ++j) tmp(j) = w_(below[j]);
        ws.noalias() -= L.bottomRows(sh.below).transpose() * tmp.head(sh.below);
      }
      L.topRows(sh.columns).transpose().triangularView<Eigen::Upper>().solveInPlace(ws);
    }
  }
  // One part of the split tree: the forward pass through its subtrees, its updates to top
  // rows into its own copy of them (zeroed first).
  void forward_part(int part) const {
    const int ntop = static_cast<int>(top_cols_.size());
    w_.segment(n_ + part * ntop, ntop).setZero();
    for (const auto& [a, z] : ranges_[static_cast<size_t>(part)]) forward(a, z, part, target_.data());
  }
  // The top: both parts' copies of the top rows added (part 0's first), then the forward
  // and backward passes through the top supernodes, with scratch 0.
  void solve_top() const {
    const int ntop = static_cast<int>(top_cols_.size());
    for (int i = 0; i < ntop; ++i) w_(top_cols_[static_cast<size_t>(i)]) += w_(n_ + i) + w_(n_ + ntop + i);
    for (const auto& [a, z] : top_) forward(a, z, 0, nullptr);
    for (auto it = top_.rbegin(); it != top_.rend(); ++it) backward(it->first, it->second, 0);
  }
  void backward_part(int part) const {
    for (auto it = ranges_[static_cast<size_t>(part)].rbegin(); it != ranges_[static_cast<size_t>(part)].rend(); ++it)
      backward(it->first, it->second, part);
  }
  // Splits the supernodal elimination tree into two parts of disjoint subtrees plus the
  // top (single_precision_solve.cpp); leaves the ranges empty when the split does not pay.
  void split_tree();

  bool ok_ = false;
  int n_ = 0;
  std::vector<long> super_, pi_, px_;
  std::vector<int> rows_, perm_;
  std::vector<float> values_;
  // Two-thread split: each part's subtrees as supernode ranges, the top's ranges, the top
  // columns (slot order), and rows_ redirected for the parts' forward updates.
  std::array<std::vector<std::pair<int, int>>, 2> ranges_;
  std::vector<std::pair<int, int>> top_;
  std::vector<int> top_cols_, target_;
  mutable Eigen::VectorXf w_;
  mutable std::array<Eigen::VectorXf, 2> t_;
};

}  // namespace fiberfem::core::detail
#endif
