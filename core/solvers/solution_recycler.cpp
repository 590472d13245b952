#include "core/solvers/solution_recycler.hpp"

#include "core/parallel.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace fiberfem::core::detail {

void SolutionRecycler::remember(const Eigen::VectorXd& x) {
  const int m = capacity_;
  const double n = x.norm();
  if (m == 0 || !(n > 0) || !std::isfinite(n)) return;
  if (history_.rows() != x.size() || history_.cols() != m) {
    history_.setZero(x.size(), m);
    count_ = next_ = 0;
  }
  // Rows on the threads for a long vector: the column is strided (one cache line a row).
  const int rows = static_cast<int>(x.size());
  const double inv = 1.0 / n;
  parallel_for(
      kProjectionParts,
      [&](int p) {
        for (int r = part_begin(rows, p); r < part_begin(rows, p + 1); ++r) history_(r, next_) = x[r] * inv;
      },
      rows > kParallelRows);
  next_ = (next_ + 1) % m;
  count_ = std::min(count_ + 1, m);
}

// x <- the combination of the remembered solutions with the least A-norm error,
// x = W (W^T A W)^+ W^T b (a pseudo-inverse: consecutive solutions are nearly parallel).
// For motion that stays near a few modes this removes most of the initial residual and
// PCG does the rest. The caller's guess (the last velocity extrapolated) is left out:
// measured, adding it to the span costs PCG iterations (it lowers the A-norm error but
// not the residual PCG stops on). It is kept when nothing is remembered yet.
const Eigen::VectorXd* SolutionRecycler::project(const SparseMatrix& A, const Eigen::VectorXd& b, Eigen::VectorXd& x,
                                                  const SparseSystem* blocks) {
  const int m = count_;
  if (m == 0 || history_.rows() != b.size()) return nullptr;
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
  const bool from_blocks = blocks && stride == 8;
  if (from_blocks) blocks->block_product8(w, aw, A.nonZeros() > 20000);
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
      accumulate(part_begin(rows, p), part_begin(rows, p + 1), g, wb);
    });
    for (int p = 0; p < kProjectionParts; ++p) {
      G_ += part_g_[static_cast<size_t>(p)];
      Wb_ += part_wb_[static_cast<size_t>(p)];
    }
  } else {
    accumulate(0, rows, G_, Wb_);
  }
  eig_.compute(G_);
  if (eig_.info() != Eigen::Success) return nullptr;
  const SmallVector& lambda = eig_.eigenvalues();  // ascending
  const double top = lambda(m - 1);
  if (!(top > 0) || !std::isfinite(top)) return nullptr;
  SmallVector c(m);
  c.noalias() = eig_.eigenvectors().transpose() * Wb_;
  for (int k = 0; k < m; ++k) c(k) = lambda(k) > 1e-12 * top ? c(k) / lambda(k) : 0.0;
  SmallVector y(m);
  y.noalias() = eig_.eigenvectors() * c;
  if (!y.allFinite()) return nullptr;
  // x = W y and its product A x = (A W) y in one pass over the rows.
  x.resize(rows);
  guess_Ax_.resize(rows);
  const auto combine = [&](int p) {
    for (int r = part_begin(rows, p); r < part_begin(rows, p + 1); ++r) {
      x[r] = W.row(r).dot(y);
      guess_Ax_[r] = AW_.row(r).head(m).dot(y);
    }
  };
  parallel_for(kProjectionParts, combine, A.nonZeros() > 20000);
  return &guess_Ax_;
}

void SolutionRecycler::save(LinearSolverState& st) const {
  st.history_rows = history_.rows();
  st.history_cols = static_cast<int>(history_.cols());
  st.history = Eigen::Map<const Eigen::VectorXd>(history_.data(), history_.size());
  st.history_count = count_;
  st.history_next = next_;
}

void SolutionRecycler::check(const LinearSolverState& st) {
  if (st.history.size() != st.history_rows * st.history_cols || st.history_count < 0 ||
      st.history_count > st.history_cols || st.history_next < 0 || (st.history_cols > 0 && st.history_next >= st.history_cols))
    throw std::invalid_argument("linear solver state: inconsistent recycled-solution basis");
}

void SolutionRecycler::load(const LinearSolverState& st) {
  history_ = Eigen::Map<const RowMajorMatrix>(st.history.data(), st.history_rows, st.history_cols);
  count_ = st.history_count;
  next_ = st.history_next;
}

}  // namespace fiberfem::core::detail
