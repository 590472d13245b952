#pragma once
/// @file The conjugate-gradient iteration of the PCG solver, with its work vectors kept
/// between solves.

#include "core/linear_solver.hpp"
#include "core/parallel.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

namespace fiberfem::core::detail {

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

}  // namespace fiberfem::core::detail
