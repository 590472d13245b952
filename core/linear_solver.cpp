#include "core/linear_solver.hpp"

#include "core/amg_preconditioner.hpp"
#include "core/parallel.hpp"

#include <Eigen/Dense>
#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseCholesky>
#ifdef FIBERFEM_HAVE_CHOLMOD
#include <Eigen/CholmodSupport>
#endif

#include <dlfcn.h>
#include <omp.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

namespace fiberfem::core {

const char* to_string(PreconditionerKind k) {
  switch (k) {
    case PreconditionerKind::block_jacobi: return "block_jacobi";
    case PreconditionerKind::cholesky: return "cholesky";
    case PreconditionerKind::amg: return "amg";
  }
  return "?";
}

const char* to_string(LinearSolverKind k) { return k == LinearSolverKind::pcg ? "pcg" : "direct"; }

bool has_cholmod() {
#ifdef FIBERFEM_HAVE_CHOLMOD
  return true;
#else
  return false;
#endif
}

SolverSettings with_cost_refresh(SolverSettings s) {
  s.refresh_iterations = 32;
  s.refresh_budget = 1.0;
  return s;
}

void SolverSettings::validate() const {
  if (refresh_iterations < 1)
    throw std::invalid_argument("solver: refresh_iterations must be >= 1, got " + std::to_string(refresh_iterations));
  if (!(refresh_budget >= 0 && std::isfinite(refresh_budget)))
    throw std::invalid_argument("solver: refresh_budget must be finite and >= 0, got " + std::to_string(refresh_budget));
  if (!(tolerance > 0 && tolerance < 1))
    throw std::invalid_argument("solver: tolerance must be in (0, 1), got " + std::to_string(tolerance));
  if (max_iterations < 1)
    throw std::invalid_argument("solver: max_iterations must be >= 1, got " + std::to_string(max_iterations));
  if (recycled_solutions < 0 || recycled_solutions > 64)
    throw std::invalid_argument("solver: recycled_solutions must be in [0, 64], got " + std::to_string(recycled_solutions));
  if (!(failure_residual > 0 && std::isfinite(failure_residual)))
    throw std::invalid_argument("solver: failure_residual must be > 0, got " + std::to_string(failure_residual));
  if (method == LinearSolverKind::pcg && preconditioner == PreconditionerKind::amg && !has_amg())
    throw std::invalid_argument(
        "solver: preconditioner amg needs a build with AMGCL (Debian's libamgcl-dev, scripts/setup.sh); use cholesky");
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

#ifdef FIBERFEM_HAVE_CHOLMOD
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
  bool build(const cholmod_factor* L) {
    ok_ = false;
    if (!L || !L->is_super || !L->is_ll || L->xtype != CHOLMOD_REAL || L->dtype != CHOLMOD_DOUBLE) return false;
    const auto index = [&](const void* p, size_t k) -> long {
      return L->itype == CHOLMOD_LONG ? static_cast<long>(static_cast<const SuiteSparse_long*>(p)[k])
                                      : static_cast<long>(static_cast<const int*>(p)[k]);
    };
    n_ = static_cast<int>(L->n);
    const size_t ns = L->nsuper;
    super_.resize(ns + 1);
    pi_.resize(ns + 1);
    px_.resize(ns + 1);
    for (size_t k = 0; k <= ns; ++k) {
      super_[k] = index(L->super, k);
      pi_[k] = index(L->pi, k);
      px_[k] = index(L->px, k);
    }
    rows_.resize(static_cast<size_t>(pi_[ns]));
    for (size_t k = 0; k < rows_.size(); ++k) rows_[k] = static_cast<int>(index(L->s, k));
    perm_.resize(static_cast<size_t>(n_));
    for (size_t k = 0; k < perm_.size(); ++k) perm_[k] = static_cast<int>(index(L->Perm, k));
    const double* x = static_cast<const double*>(L->x);
    values_.assign(x, x + px_[ns]);
    split_tree();
    w_.resize(n_ + 2 * static_cast<Eigen::Index>(top_cols_.size()));
    for (auto& t : t_) t.resize(n_);
    ok_ = true;
    return true;
  }
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
#pragma omp parallel
    {
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
  // Splits the supernodal elimination tree (postordered: a subtree is a contiguous range
  // of supernodes ending at its root) into two parts of disjoint subtrees plus the top,
  // greedily: starting from the roots, the heaviest subtree is moved to the top and
  // replaced by its children while that lowers top + the larger part (weights: entries of
  // L, the memory a solve reads). Kept only if it would cut the solve below 0.85 of serial.
  void split_tree() {
    for (auto& r : ranges_) r.clear();
    top_.clear();
    top_cols_.clear();
    target_.clear();
    const int ns = static_cast<int>(super_.size()) - 1;
    if (ns < 4) return;
    std::vector<int> col_super(static_cast<size_t>(n_)), parent(static_cast<size_t>(ns), -1),
        first(static_cast<size_t>(ns)), count(static_cast<size_t>(ns), 1);
    std::vector<double> w(static_cast<size_t>(ns)), W(static_cast<size_t>(ns));
    double total = 0;
    for (int s = 0; s < ns; ++s) {
      const Shape sh = shape(s);
      for (int c = sh.first; c < sh.first + sh.columns; ++c) col_super[static_cast<size_t>(c)] = s;
      w[static_cast<size_t>(s)] = static_cast<double>(sh.columns) * (sh.columns + sh.below);
      total += w[static_cast<size_t>(s)];
      first[static_cast<size_t>(s)] = s;
    }
    W = w;
    std::vector<std::vector<int>> children(static_cast<size_t>(ns));
    std::vector<int> list;
    for (int s = 0; s < ns; ++s) {
      const Shape sh = shape(s);
      if (sh.below > 0) {
        const int p = col_super[static_cast<size_t>(rows_[static_cast<size_t>(pi_[static_cast<size_t>(s)] + sh.columns)])];
        if (p <= s) return;  // not postordered: stay serial
        parent[static_cast<size_t>(s)] = p;
        children[static_cast<size_t>(p)].push_back(s);
        W[static_cast<size_t>(p)] += W[static_cast<size_t>(s)];
        first[static_cast<size_t>(p)] = std::min(first[static_cast<size_t>(p)], first[static_cast<size_t>(s)]);
        count[static_cast<size_t>(p)] += count[static_cast<size_t>(s)];
      } else {
        list.push_back(s);
      }
    }
    for (int s = 0; s < ns; ++s)
      if (s - first[static_cast<size_t>(s)] + 1 != count[static_cast<size_t>(s)]) return;  // subtrees not contiguous
    // Greedy split, keeping the best assignment seen.
    const auto assign = [&](std::vector<int> l, std::array<std::vector<int>, 2>& parts) {
      std::sort(l.begin(), l.end(), [&](int x, int y) { return W[static_cast<size_t>(x)] > W[static_cast<size_t>(y)]; });
      double load[2] = {0, 0};
      for (auto& p : parts) p.clear();
      for (int x : l) {
        const int k = load[0] <= load[1] ? 0 : 1;
        load[k] += W[static_cast<size_t>(x)];
        parts[static_cast<size_t>(k)].push_back(x);
      }
      return std::max(load[0], load[1]);
    };
    double top = 0, best = total;
    std::array<std::vector<int>, 2> parts, best_parts;
    for (int it = 0; it < 256 && !list.empty() && top < 0.5 * total; ++it) {
      const double cost = top + assign(list, parts);
      if (cost < best) {
        best = cost;
        best_parts = parts;
      }
      const auto h = std::max_element(list.begin(), list.end(), [&](int x, int y) {
        return W[static_cast<size_t>(x)] < W[static_cast<size_t>(y)];
      });
      const int root = *h;
      list.erase(h);
      top += w[static_cast<size_t>(root)];
      for (int c : children[static_cast<size_t>(root)]) list.push_back(c);
    }
    if (best > 0.85 * total || best_parts[0].empty() || best_parts[1].empty()) return;
    // Ranges per part (ascending), the owner of each supernode (-1: top), top ranges.
    std::vector<int> owner(static_cast<size_t>(ns), -1);
    for (int k = 0; k < 2; ++k) {
      auto& r = ranges_[static_cast<size_t>(k)];
      for (int root : best_parts[static_cast<size_t>(k)]) {
        r.emplace_back(first[static_cast<size_t>(root)], root);
        for (int s = first[static_cast<size_t>(root)]; s <= root; ++s) owner[static_cast<size_t>(s)] = k;
      }
      std::sort(r.begin(), r.end());
    }
    for (int s = 0; s < ns; ++s) {
      if (owner[static_cast<size_t>(s)] >= 0) continue;
      if (!top_.empty() && top_.back().second == s - 1)
        top_.back().second = s;
      else
        top_.emplace_back(s, s);
    }
    // Top columns get a slot in each part's copy; row-list entries of a part's supernodes
    // point at the row (own subtree) or at the part's copy of the top row.
    std::vector<int> slot(static_cast<size_t>(n_), -1);
    for (const auto& [a, z] : top_)
      for (int c = shape(a).first; c < super_[static_cast<size_t>(z) + 1]; ++c) {
        slot[static_cast<size_t>(c)] = static_cast<int>(top_cols_.size());
        top_cols_.push_back(c);
      }
    const int ntop = static_cast<int>(top_cols_.size());
    target_ = rows_;
    for (int s = 0; s < ns; ++s) {
      const int k = owner[static_cast<size_t>(s)];
      if (k < 0) continue;
      for (long p = pi_[static_cast<size_t>(s)]; p < pi_[static_cast<size_t>(s) + 1]; ++p) {
        const int r = rows_[static_cast<size_t>(p)];
        const int o = owner[static_cast<size_t>(col_super[static_cast<size_t>(r)])];
        if (o == k) continue;
        if (o >= 0 || slot[static_cast<size_t>(r)] < 0) {  // another part's row: the split is wrong
          for (auto& rr : ranges_) rr.clear();
          return;
        }
        target_[static_cast<size_t>(p)] = n_ + k * ntop + slot[static_cast<size_t>(r)];
      }
    }
  }

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

/// Eigen's CHOLMOD wrapper with its factor exposed (for the single-precision copy).
template <class Matrix>
class OpenCholmodSupernodalLLT : public Eigen::CholmodSupernodalLLT<Matrix, Eigen::Lower> {
 public:
  const cholmod_factor* factor() const { return this->m_cholmodFactor; }
};
#endif

/// A sparse Cholesky factorisation of the engine's SPD matrix (stored row-major with both
/// triangles; being symmetric, the same arrays read as column-major give the same matrix).
/// CHOLMOD supernodal when built with it, else Eigen's simplicial LLT. The symbolic
/// analysis is done once per pattern.
class CholeskyFactor {
 public:
  CholeskyFactor() {
#ifdef FIBERFEM_HAVE_CHOLMOD
    single_threaded_blas();
    // Fill-reducing ordering: CHOLMOD tries AMD and METIS at analysis and keeps the one
    // with the smaller factor. Its own default kept AMD on the 245,760-tet beam (nnz(L)
    // 127 M, 116 GFlop to factorise) where METIS gives 81 M and 104 GFlop; on the
    // slender 5,760-tet beam AMD stays best (418 k against 515 k).
    cholmod_common& c = llt_.cholmod();
    c.nmethods = 2;
    c.method[0].ordering = CHOLMOD_AMD;
    c.method[1].ordering = CHOLMOD_METIS;
    c.postorder = 1;
#endif
  }
  bool factorize(const SparseMatrix& A) {
    Acol_ = Eigen::Map<const Eigen::SparseMatrix<double, Eigen::ColMajor, int>>(
        A.rows(), A.cols(), A.nonZeros(), A.outerIndexPtr(), A.innerIndexPtr(), A.valuePtr());
    within_engine_threads([&] {
      if (!analysed_ || Acol_.rows() != rows_) {
        llt_.analyzePattern(Acol_);
        analysed_ = true;
        rows_ = Acol_.rows();
      }
      llt_.factorize(Acol_);
    });
    ok_ = llt_.info() == Eigen::Success;
#ifdef FIBERFEM_HAVE_CHOLMOD
    if (ok_ && single_precision_) single_.build(llt_.factor());
#endif
    const FactorInfo i = info();
    cost_in_applications_ = i.nonzeros > 0 ? i.flops / (4 * i.nonzeros) : 0;
    return ok_;
  }
  bool ok() const { return ok_; }
  /// What a factorisation costs in applications of the factor: its flops over 4 nnz(L)
  /// (one forward and one backward substitution, a multiply and an add per entry); set by
  /// factorize().
  double iterations_per_factorisation() const { return cost_in_applications_; }
  FactorInfo info() const {
    FactorInfo i;
    i.factored = ok_;
    if (!ok_) return i;
#ifdef FIBERFEM_HAVE_CHOLMOD
    const cholmod_common& c = const_cast<OpenCholmodSupernodalLLT<Eigen::SparseMatrix<double, Eigen::ColMajor, int>>&>(llt_).cholmod();
    i.nonzeros = c.lnz;
    i.flops = c.fl;
    const int ordering = c.selected >= 0 && c.selected < CHOLMOD_MAXMETHODS ? c.method[c.selected].ordering : -1;
    i.ordering = ordering == CHOLMOD_AMD ? "amd" : ordering == CHOLMOD_METIS ? "metis" : ordering == CHOLMOD_NESDIS ? "nesdis" : "other";
    i.solve_threads = single_precision_ && single_.ok() && single_.parallel() && omp_get_max_threads() >= 2 ? 2 : 1;
#else
    const auto& L = llt_.matrixL().nestedExpression();
    i.nonzeros = static_cast<double>(L.nonZeros());
    for (Eigen::Index j = 0; j < L.outerSize(); ++j) {  // sum of squared column counts
      const double c = static_cast<double>(L.outerIndexPtr()[j + 1] - L.outerIndexPtr()[j]);
      i.flops += c * c;
    }
    i.ordering = "amd";
#endif
    return i;
  }
  /// The matrix of the last factorize() (column-major copy of its arrays).
  const Eigen::SparseMatrix<double, Eigen::ColMajor, int>& matrix() const { return Acol_; }
  template <class Rhs>
  Eigen::VectorXd solve(const Rhs& b) const { return llt_.solve(b); }
  /// Keep a single-precision copy of the factor for `precondition` (CHOLMOD only).
  void set_single_precision(bool on) { single_precision_ = on; }
  /// x ~ A^-1 b for preconditioning: the single-precision copy when there is one.
  template <class Rhs, class Dest>
  void precondition(const Rhs& b, Dest& x) const {
#ifdef FIBERFEM_HAVE_CHOLMOD
    if (single_precision_ && single_.ok()) {
      single_.solve(b, x);
      return;
    }
#endif
    x = llt_.solve(b);
  }

 private:
#ifdef FIBERFEM_HAVE_CHOLMOD
  // The supernodal factorisation calls BLAS between the engine's OpenMP loops. A
  // multithreaded OpenBLAS keeps its threads spinning after the call and slows those loops
  // down (measured: the rotation phase 3x slower on two cores), so BLAS runs on one thread.
  static void single_threaded_blas() {
    using SetThreads = void (*)(int);
    if (auto f = reinterpret_cast<SetThreads>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads"))) f(1);
  }
#endif
  // CHOLMOD's own OpenMP loops (in the supernodal factorisation) ask for teams of
  // CHOLMOD_OMP_NUM_THREADS threads, which Debian's build fixes at 4 whatever the machine.
  // On two cores that oversubscribes them, and the engine's worker threads then wait in
  // the kernel instead of spinning: the factorisation of the 5,760-tet benchmark beam took
  // 20 ms instead of 5-6. A host teams region caps every parallel region inside it at the
  // engine's thread count (its thread_limit). Not from inside a parallel region, where
  // a teams construct may not nest (and CHOLMOD's regions are serialised anyway).
  template <class F>
  static void within_engine_threads(F&& f) {
    if (omp_in_parallel()) {
      f();
      return;
    }
    const int limit = std::max(1, std::min(omp_get_max_threads(), omp_get_num_procs()));
#pragma omp teams num_teams(1) thread_limit(limit)
    f();
  }
  Eigen::SparseMatrix<double, Eigen::ColMajor, int> Acol_;
  bool single_precision_ = false;
#ifdef FIBERFEM_HAVE_CHOLMOD
  OpenCholmodSupernodalLLT<Eigen::SparseMatrix<double, Eigen::ColMajor, int>> llt_;
  SinglePrecisionSupernodalSolve single_;
#else
  Eigen::SimplicialLLT<Eigen::SparseMatrix<double, Eigen::ColMajor, int>, Eigen::Lower> llt_;
#endif
  bool analysed_ = false;
  double cost_in_applications_ = 0;
  bool ok_ = false;
  Eigen::Index rows_ = -1;
};

/// What the warp preconditioner shares with its solver: the factor of an earlier matrix,
/// the node-block rotations at factorisation time, and the current ones.
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

/// Sum of body(i) over rows 0..n-1, on the OpenMP threads when `parallel`, in a fixed
/// partition (core/parallel.hpp: the same bits on any number of threads).
template <class Body>
double sum_rows(int n, bool parallel, Body&& body) {
  return fixed_sum(n, parallel, std::forward<Body>(body));
}

/// Preconditioned conjugate gradients with its work vectors kept between solves and the
/// vector updates fused into OpenMP passes over the rows. Eigen's ConjugateGradient
/// allocates four vectors per solve and makes a separate pass for each update and norm;
/// this one allocates nothing after the first solve of a size (issue 6, no allocation in
/// the step). The iteration and the stopping rule are Eigen's conjugate_gradient: stop when
/// |r|^2 < max(tol^2 |b|^2, DBL_MIN) for the recursively updated residual r; iterations
/// are counted as products with A.
class Pcg {
 public:
  /// `precondition(r, z)` writes z = M^-1 r. `Ax`, when given, is A x for the initial
  /// guess (the recycled projection has it): the first residual then needs no product.
  template <class Precondition>
  SolveStats solve(const SparseMatrix& A, const Eigen::VectorXd& b, Eigen::VectorXd& x, double tol, int max_iterations,
                   Precondition&& precondition, const Eigen::VectorXd* Ax = nullptr) {
    const int n = static_cast<int>(b.size());
    r_.resize(n);
    z_.resize(n);
    p_.resize(n);
    q_.resize(n);
    SolveStats st;
    const double rhs2 = b.squaredNorm();
    if (rhs2 == 0) {
      x.setZero();
      st.ok = true;
      return st;
    }
    const double threshold = std::max(tol * tol * rhs2, std::numeric_limits<double>::min());
    // Threads only where a pass is long enough to pay for the fork and join (as Eigen's
    // own sparse product: more than 20,000 non-zeros); short passes stay on one thread.
    const bool par = n > kParallelRows;

    if (Ax)
      r_ = *Ax;
    else
      product(A, x, r_);
    double rr = sum_rows(n, par, [&](int i) {
      r_[i] = b[i] - r_[i];
      return r_[i] * r_[i];
    });
    if (rr >= threshold) {
      precondition(r_, p_);
      double rz = r_.dot(p_);
      while (st.iterations < max_iterations) {
        const double pq = product(A, p_, q_);
        ++st.iterations;
        const double alpha = rz / pq;
        rr = sum_rows(n, par, [&](int i) {
          x[i] += alpha * p_[i];
          r_[i] -= alpha * q_[i];
          return r_[i] * r_[i];
        });
        if (rr < threshold) break;
        precondition(r_, z_);
        const double rz_new = r_.dot(z_);
        const double beta = rz_new / rz;
        rz = rz_new;
        sum_rows(n, par, [&](int i) {
          p_[i] = z_[i] + beta * p_[i];
          return 0.0;
        });
      }
    }
    st.relative_residual = std::sqrt(rr / rhs2);
    st.ok = std::isfinite(st.relative_residual) && st.relative_residual <= tol && x.allFinite();
    return st;
  }

 private:
  // y = A v over the rows (A symmetric with both triangles stored); returns v . A v.
  double product(const SparseMatrix& A, const Eigen::VectorXd& v, Eigen::VectorXd& y) const {
    if (blocks_) return blocks_->block_product(v, y, A.nonZeros() > 20000);
    const int* outer = A.outerIndexPtr();
    const int* inner = A.innerIndexPtr();
    const double* val = A.valuePtr();
    const int rows = static_cast<int>(A.rows());
    return sum_rows(rows, A.nonZeros() > 20000, [&](int r) {
      double s = 0;
      for (int k = outer[r]; k < outer[r + 1]; ++k) s += val[k] * v[inner[k]];
      y[r] = s;
      return s * v[r];
    });
  }
  static constexpr int kParallelRows = 20000;
  Eigen::VectorXd r_, z_, p_, q_;

 public:
  /// Products from this system's upper blocks (current), or from A's CSR values (nullptr).
  const SparseSystem* blocks_ = nullptr;
};

class PcgSolver final : public LinearSolver {
 public:
  explicit PcgSolver(const SolverSettings& s) : s_(s) { warp_pre_.set_state(&warp_); }
  SolveStats solve(const SparseMatrix& A, const Eigen::VectorXd& b_in, Eigen::VectorXd& x) override {
    if (!s_.warm_start || x.size() != b_in.size()) x = Eigen::VectorXd::Zero(b_in.size());
    // Solve for x / |b| with a unit right-hand side: CG's squared norms would underflow
    // below DBL_MIN for a body decaying to rest (|b| ~ 1e-154) and stop it early.
    const double bn = b_in.norm();
    if (bn == 0.0) {
      x.setZero();
      SolveStats st;
      st.ok = true;
      return st;
    }
    if (!std::isfinite(bn)) return failed({});
    scaled_b_ = b_in / bn;
    const Eigen::VectorXd& b = scaled_b_;
    // The upper block store when it holds this matrix (the simulator's step) and this
    // solver's passes have a block form (the cholesky preconditioner; the projection with
    // eight recycled solutions); otherwise the CSR values, synced.
    use_blocks_ = system_ && system_->blocks_current() && &A == &system_->matrix() &&
                  s_.preconditioner == PreconditionerKind::cholesky && (!s_.warm_start || s_.recycled_solutions == 8);
    if (system_ && system_->blocks_current() && !use_blocks_) system_->sync_matrix();
    pcg_.blocks_ = use_blocks_ ? system_ : nullptr;
    x /= bn;
    guess_product_ = false;
    if (s_.warm_start) project_guess(A, b, x);
    SolveStats st = solve_scaled(A, b, x);
    if (st.ok && s_.warm_start) remember(x);
    x *= bn;
    return st;
  }

 private:
  // Recycled subspace: the last solutions (normalised), one per row-major column so that
  // A times all of them is one pass over A.
  using RowMajorMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  RowMajorMatrix history_;
  int history_count_ = 0, history_next_ = 0;
  // The projection's small matrices, sized at most 64 (SolverSettings::recycled_solutions):
  // fixed-capacity Eigen types, so the projection allocates nothing.
  using SmallMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 64, 64>;
  using SmallVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 64, 1>;
  SmallMatrix G_;
  SmallVector Wb_;
  // The projection's sums per part of the rows (fixed parts: the same bits on any thread count).
  static constexpr int kProjectionParts = 8;
  std::array<SmallMatrix, kProjectionParts> part_g_;
  std::array<SmallVector, kProjectionParts> part_wb_;
  // A W, row by row, from the projection's pass, and A x0 = (A W) y for its guess: PCG's
  // first residual then needs no product with A (one of the 2 to 3 products of a step at
  // the interactive tolerance).
  RowMajorMatrix AW_;
  Eigen::VectorXd guess_Ax_;
  bool guess_product_ = false;  // guess_Ax_ is A x for the x solve_scaled starts from
  Eigen::SelfAdjointEigenSolver<SmallMatrix> eig_;

  void remember(const Eigen::VectorXd& x) {
    const int m = s_.recycled_solutions;
    const double n = x.norm();
    if (m == 0 || !(n > 0) || !std::isfinite(n)) return;
    if (history_.rows() != x.size() || history_.cols() != m) {
      history_.setZero(x.size(), m);
      history_count_ = history_next_ = 0;
    }
    history_.col(history_next_) = x / n;
    history_next_ = (history_next_ + 1) % m;
    history_count_ = std::min(history_count_ + 1, m);
  }

  // x <- the combination of the remembered solutions with the least A-norm error,
  // x = W (W^T A W)^+ W^T b (a pseudo-inverse: consecutive solutions are nearly parallel).
  // For motion that stays near a few modes this removes most of the initial residual and
  // PCG does the rest. The caller's guess (the last velocity extrapolated) is left out:
  // measured, adding it to the span costs PCG iterations (it lowers the A-norm error but
  // not the residual PCG stops on). It is kept when nothing is remembered yet.
  void project_guess(const SparseMatrix& A, const Eigen::VectorXd& b, Eigen::VectorXd& x) {
    const int m = history_count_;
    if (m == 0 || history_.rows() != b.size()) return;
    const auto W = history_.leftCols(m);
    // G = W^T A W and W^T b in one pass over A (rows split between threads, each thread
    // summing its rows' outer products): Eigen's products would pass over A once per
    // column and allocate A W.
    const int* outer = A.outerIndexPtr();
    const int* inner = A.innerIndexPtr();
    const double* val = A.valuePtr();
    const int rows = static_cast<int>(A.rows());
    const double* w = history_.data();
    const Eigen::Index stride = history_.cols();
    AW_.resize(rows, stride);  // no allocation after the first solve of a size
    double* aw = AW_.data();
    G_.setZero(m, m);
    Wb_.setZero(m);
    // A W from the upper blocks (one pass for all eight columns) when the solve reads them;
    // otherwise each row of A W is summed from the CSR values in the pass below.
    const bool from_blocks = use_blocks_ && stride == 8;
    if (from_blocks) system_->block_product8(w, aw, A.nonZeros() > 20000);
    // Rows [begin, end) into G_ and Wb_ (through per-thread sums when threaded).
    auto accumulate = [&](int begin, int end, SmallMatrix& g, SmallVector& wb) {
      if (m == 8 && stride == 8) {  // the default: fixed sizes, vectorised (measured 3x fewer instructions)
        using V8 = Eigen::Matrix<double, 8, 1>;
        Eigen::Matrix<double, 8, 8> g8 = Eigen::Matrix<double, 8, 8>::Zero();
        V8 wb8 = V8::Zero();
        for (int r = begin; r < end; ++r) {
          V8 acc = V8::Zero();
          if (from_blocks) {
            acc = Eigen::Map<const V8>(aw + r * 8);
          } else {
            for (int p = outer[r]; p < outer[r + 1]; ++p) acc += val[p] * Eigen::Map<const V8>(w + inner[p] * 8);
            Eigen::Map<V8>(aw + r * 8) = acc;
          }
          const Eigen::Map<const V8> wr(w + r * 8);
          wb8 += b[r] * wr;
          g8.noalias() += wr * acc.transpose();
        }
        g += g8;
        wb += wb8;
        return;
      }
      SmallVector acc(m);
      for (int r = begin; r < end; ++r) {
        acc.setZero();
        if (from_blocks) {
          for (int k = 0; k < m; ++k) acc[k] = aw[r * stride + k];
        } else {
          for (int p = outer[r]; p < outer[r + 1]; ++p) {
            const double v = val[p];
            const double* wr = w + inner[p] * stride;
            for (int k = 0; k < m; ++k) acc[k] += v * wr[k];
          }
          for (int k = 0; k < m; ++k) aw[r * stride + k] = acc[k];
        }
        const double* wr = w + r * stride;
        for (int k = 0; k < m; ++k) {
          wb[k] += wr[k] * b[r];
          for (int l = 0; l < m; ++l) g(k, l) += wr[k] * acc[l];
        }
      }
    };
    if (A.nonZeros() > 20000) {
      // Fixed parts (not one per thread), added in order: the same bits on any thread count.
      parallel_for(kProjectionParts, [&](int p) {
        SmallMatrix& g = part_g_[static_cast<size_t>(p)];
        SmallVector& wb = part_wb_[static_cast<size_t>(p)];
        g.setZero(m, m);
        wb.setZero(m);
        accumulate(static_cast<int>(static_cast<long>(rows) * p / kProjectionParts),
                   static_cast<int>(static_cast<long>(rows) * (p + 1) / kProjectionParts), g, wb);
      });
      for (int p = 0; p < kProjectionParts; ++p) {
        G_ += part_g_[static_cast<size_t>(p)];
        Wb_ += part_wb_[static_cast<size_t>(p)];
      }
    } else {
      accumulate(0, rows, G_, Wb_);
    }
    eig_.compute(G_);
    if (eig_.info() != Eigen::Success) return;
    const SmallVector& lambda = eig_.eigenvalues();  // ascending
    const double top = lambda(m - 1);
    if (!(top > 0) || !std::isfinite(top)) return;
    SmallVector c(m);
    c.noalias() = eig_.eigenvectors().transpose() * Wb_;
    for (int k = 0; k < m; ++k) c(k) = lambda(k) > 1e-12 * top ? c(k) / lambda(k) : 0.0;
    SmallVector y(m);
    y.noalias() = eig_.eigenvectors() * c;
    if (!y.allFinite()) return;
    x.noalias() = W * y;
    guess_Ax_.noalias() = AW_.leftCols(m) * y;
    guess_product_ = true;
  }
  SolveStats solve_scaled(const SparseMatrix& A, const Eigen::VectorXd& b, Eigen::VectorXd& x) {
    const Eigen::VectorXd* Ax0 = guess_product_ ? &guess_Ax_ : nullptr;
    if (s_.preconditioner == PreconditionerKind::block_jacobi) return run(jacobi_pre_, A, b, x, Ax0);
    SolveStats st;
    FactorSlot& slot = select_slot();
    warp_.slot = &slot;
    if (slot.stale || !lagged_ok(slot) || slot.rows != A.rows()) refactor(A, slot, st);
    if (!lagged_ok(slot)) return failed(st);
    warp_.update_warp();
    first_guess_ = x;
    const Eigen::VectorXd& x0 = first_guess_;
    SolveStats cg = run(warp_pre_, A, b, x, Ax0);
    int first = 0;  // iterations of a first attempt with the old factor
    if (!cg.ok && st.factorizations == 0) {
      // The old factor was too far from this matrix: refresh it and solve again.
      refactor(A, slot, st);
      if (!lagged_ok(slot)) return failed(st);
      warp_.update_warp();
      first = cg.iterations;
      x = x0;
      cg = run(warp_pre_, A, b, x, Ax0);
    }
    note_iterations(slot, cg.iterations);  // with the factor now in the slot
    cg.iterations += first;
    cg.factorizations = st.factorizations;
    slot.stale = slot.stale || cg.iterations > s_.refresh_iterations;
    return cg;
  }
  // The refresh rule that minimises the time of a run when a factor's iterations grow as
  // it ages: refactorise once the iterations it has cost beyond its first solve add up to
  // what a factorisation costs, counted in iterations (its flops over those of one
  // application of the factor, 4 nnz(L)), times refresh_budget. Deterministic: counts,
  // not timings, so a run and its restore from a checkpoint refresh at the same steps.
  void note_iterations(FactorSlot& slot, int iterations) {
    if (slot.baseline < 0) {
      slot.baseline = iterations;
      return;
    }
    slot.excess += std::max(0, iterations - slot.baseline);
    const double setup_cost =
        s_.preconditioner == PreconditionerKind::amg ? kAmgSetupIterations : slot.factor.iterations_per_factorisation();
    if (s_.refresh_budget > 0 && slot.excess > s_.refresh_budget * setup_cost)
      slot.stale = true;
  }

  // Factors are kept per matrix family (the step size): a step retried with substeps, and
  // the full step after it, each find their own factor instead of refactorising back and
  // forth. At most kSlots factors (least recently used replaced).
  static constexpr size_t kSlots = 2;
  FactorSlot& select_slot() {
    ++clock_;
    FactorSlot* lru = nullptr;
    for (auto& sl : slots_) {
      if (sl->key == key_) {
        sl->last_used = clock_;
        return *sl;
      }
      if (!lru || sl->last_used < lru->last_used) lru = sl.get();
    }
    if (slots_.size() < kSlots) {
      slots_.push_back(std::make_unique<FactorSlot>());
      lru = slots_.back().get();
    }
    lru->key = key_;
    lru->stale = true;
    lru->last_used = clock_;
    return *lru;
  }

 public:
  std::string name() const override { return std::string("pcg/") + to_string(s_.preconditioner); }
  FactorInfo factor_info() const override {
    if (!warp_.slot) return {};
    if (!warp_.slot->amg.ok()) return warp_.slot->factor.info();
    FactorInfo i;  // an amg hierarchy: no factor entries or flops to report
    i.factored = true;
    i.ordering = "amg";
    i.solve_threads = omp_get_max_threads();
    return i;
  }
  void set_blocks(std::vector<int> starts) override {
    warp_.starts = starts;
    jacobi_pre_.set_blocks(std::move(starts));
  }
  bool uses_block_rotations() const override { return s_.preconditioner != PreconditionerKind::block_jacobi; }
  void set_block_rotations(const std::vector<Mat3>& rotations) override { warp_.current = rotations; }
  bool uses_block_positions() const override { return s_.preconditioner == PreconditionerKind::amg; }
  void set_block_positions(const Eigen::VectorXd& positions) override { positions_ = &positions; }
  void invalidate() override {
    for (auto& sl : slots_) sl->stale = true;
  }
  void set_matrix_key(double key) override { key_ = key; }
  void set_system(SparseSystem* system) override { system_ = system; }
  bool reads_blocks() const override { return true; }
  void forget_solutions() override { history_count_ = history_next_ = 0; }
  LinearSolverState save_state() const override {
    LinearSolverState st;
    st.solver_name = name();
    st.history_rows = history_.rows();
    st.history_cols = static_cast<int>(history_.cols());
    st.history = Eigen::Map<const Eigen::VectorXd>(history_.data(), history_.size());
    st.history_count = history_count_;
    st.history_next = history_next_;
    st.key = key_;
    st.clock = clock_;
    for (const auto& sl : slots_) {
      LinearSolverState::Factor f;
      f.factored = lagged_ok(*sl);
      if (f.factored) {
        if (sl->amg.ok()) {
          f.matrix_values = Eigen::Map<const Eigen::VectorXd>(sl->amg_matrix.valuePtr(), sl->amg_matrix.nonZeros());
          f.setup_positions = sl->amg_positions;
        } else {
          const auto& A = sl->factor.matrix();
          f.matrix_values = Eigen::Map<const Eigen::VectorXd>(A.valuePtr(), A.nonZeros());
        }
      }
      f.at_factor = sl->at_factor;
      f.rows = sl->rows;
      f.stale = sl->stale;
      f.baseline = sl->baseline;
      f.excess = sl->excess;
      f.key = sl->key;
      f.last_used = sl->last_used;
      st.factors.push_back(std::move(f));
    }
    return st;
  }
  void load_state(const LinearSolverState& st, const SparseMatrix& pattern) override {
    if (st.solver_name != name())
      throw std::invalid_argument("linear solver state: saved by '" + st.solver_name + "', restoring into '" + name() + "'");
    if (st.history.size() != st.history_rows * st.history_cols || st.history_count < 0 ||
        st.history_count > st.history_cols || st.history_next < 0 || (st.history_cols > 0 && st.history_next >= st.history_cols))
      throw std::invalid_argument("linear solver state: inconsistent recycled-solution basis");
    if (st.factors.size() > kSlots)
      throw std::invalid_argument("linear solver state: " + std::to_string(st.factors.size()) + " factors, at most " +
                                  std::to_string(kSlots));
    for (const auto& f : st.factors) {
      if (f.factored && f.matrix_values.size() != pattern.nonZeros())
        throw std::invalid_argument("linear solver state: a factor's matrix has " + std::to_string(f.matrix_values.size()) +
                                    " values, the system " + std::to_string(pattern.nonZeros()));
      if (f.factored && s_.preconditioner == PreconditionerKind::amg && f.setup_positions.size() != pattern.rows())
        throw std::invalid_argument("linear solver state: an amg hierarchy with " + std::to_string(f.setup_positions.size()) +
                                    " setup positions, the system " + std::to_string(pattern.rows()));
    }
    history_ = Eigen::Map<const RowMajorMatrix>(st.history.data(), st.history_rows, st.history_cols);
    history_count_ = st.history_count;
    history_next_ = st.history_next;
    key_ = st.key;
    clock_ = st.clock;
    slots_.clear();
    warp_.slot = nullptr;
    for (const auto& f : st.factors) {
      auto sl = std::make_unique<FactorSlot>();
      if (f.factored) {
        SparseMatrix A = pattern;
        Eigen::Map<Eigen::VectorXd>(A.valuePtr(), A.nonZeros()) = f.matrix_values;
        if (s_.preconditioner == PreconditionerKind::amg) {
          build_amg(A, f.setup_positions, *sl);  // (sizes checked above, before anything changed)
        } else {
          sl->factor.set_single_precision(s_.single_precision_preconditioner);
          sl->factor.factorize(A);
        }
      }
      sl->at_factor = f.at_factor;
      sl->rows = f.rows;
      sl->stale = f.stale;
      sl->baseline = f.baseline;
      sl->excess = f.excess;
      sl->key = f.key;
      sl->last_used = f.last_used;
      slots_.push_back(std::move(sl));
    }
  }

 private:
  template <class Preconditioner>
  SolveStats run(Preconditioner& pre, const SparseMatrix& A, const Eigen::VectorXd& b, Eigen::VectorXd& x,
                 const Eigen::VectorXd* Ax0) {
    pre.compute(A);
    return pcg_.solve(
        A, b, x, s_.tolerance, s_.max_iterations, [&](const Eigen::VectorXd& r, Eigen::VectorXd& z) { pre._solve_impl(r, z); },
        Ax0);
  }
  static bool lagged_ok(const FactorSlot& slot) { return slot.amg.ok() || slot.factor.ok(); }
  void build_amg(const SparseMatrix& A, const Eigen::VectorXd& positions, FactorSlot& slot) {
    slot.amg_matrix = A;  // kept for checkpoints (a Cholesky factor keeps its own copy)
    slot.amg_positions = positions;
    if (!slot.amg.build(A, positions)) slot.amg_matrix = SparseMatrix();
  }
  void refactor(const SparseMatrix& A, FactorSlot& slot, SolveStats& st) {
    if (use_blocks_) system_->sync_matrix();  // the factorisation reads the CSR values (of A)
    if (s_.preconditioner == PreconditionerKind::amg) {
      // Rigid-body modes about the current configuration (about the rest one, 40 instead
      // of 9 iterations were measured once the beam had swung).
      if (!positions_ || positions_->size() != A.rows())
        throw std::logic_error("pcg/amg: set_block_positions was not called with the " + std::to_string(A.rows()) +
                               " node-block positions before solve");
      build_amg(A, *positions_, slot);
    } else {
      slot.factor.set_single_precision(s_.single_precision_preconditioner);
      slot.factor.factorize(A);
    }
    slot.at_factor = warp_.current;
    slot.rows = A.rows();
    slot.stale = false;
    slot.baseline = -1;
    slot.excess = 0;
    ++st.factorizations;
  }
  static SolveStats failed(SolveStats st) {
    st.ok = false;
    st.relative_residual = std::numeric_limits<double>::infinity();
    return st;
  }

  SolverSettings s_;
  Pcg pcg_;
  BlockJacobiPreconditioner jacobi_pre_;
  WarpState warp_;
  WarpCholeskyPreconditioner warp_pre_;
  SparseSystem* system_ = nullptr;
  const Eigen::VectorXd* positions_ = nullptr;  // node-block positions of the next solve (amg; the caller's)
  bool use_blocks_ = false;
  Eigen::VectorXd scaled_b_, first_guess_;  // solve()'s b / |b| and solve_scaled()'s x0 (kept: no allocation)
  std::vector<std::unique_ptr<FactorSlot>> slots_;
  double key_ = 0;
  long clock_ = 0;
};

class DirectSolver final : public LinearSolver {
 public:
  SolveStats solve(const SparseMatrix& A, const Eigen::VectorXd& b, Eigen::VectorXd& x) override {
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
  std::string name() const override { return direct_solver_uses_cholmod() ? "cholmod" : "llt"; }
  FactorInfo factor_info() const override {
    FactorInfo i = factor_.info();
    i.solve_threads = 1;  // CHOLMOD's double solve
    return i;
  }

 private:
  CholeskyFactor factor_;
};

}  // namespace

void LinearSolver::load_state(const LinearSolverState& state, const SparseMatrix& /*pattern*/) {
  if (state.solver_name != name())
    throw std::invalid_argument("linear solver state: saved by '" + state.solver_name + "', restoring into '" + name() + "'");
}

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
