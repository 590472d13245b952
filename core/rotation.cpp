#include "core/rotation.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <limits>

namespace fiberfem::core {

const char* to_string(RotationMethod m) { return m == RotationMethod::svd ? "svd" : "polar"; }

// Irving, Teran, Fedkiw 2004, section 5: Eigen sorts singular values in decreasing order,
// so the sign fix goes on the last column.
Mat3 rotation_svd(const Mat3& F) {
  // JacobiSVD leaves U and V unset for non-finite input: make the failure visible instead.
  if (!F.allFinite()) return Mat3::Constant(std::numeric_limits<double>::quiet_NaN());
  Eigen::JacobiSVD<Mat3> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Mat3 U = svd.matrixU();
  Mat3 V = svd.matrixV();
  if (U.determinant() < 0) U.col(2) *= -1;
  if (V.determinant() < 0) V.col(2) *= -1;
  return U * V.transpose();
}

// Maximises trace(R^T F) over rotations R = exp([w]) R_k, starting from q. The gradient in
// w is g = sum_i r_i x f_i (columns of R and F) and the Hessian is -(tr(P) I - P) with
// P = sym(F R^T), so a Newton step is w = (tr(P) I - P)^-1 g: quadratic convergence near
// the answer (two or three iterations from a warm start). Where that matrix is not safely
// positive definite (far from the answer, or inverted elements) the step falls back to
// Mueller, Bender, Chentanez and Macklin 2016 (w = g / |tr P|), which always ascends.
int rotation_polar(const Mat3& F, Eigen::Quaterniond& q, int max_iterations, double tolerance_rad) {
  const double scale = F.norm() + 1e-300;
  int it = 0;
  for (; it < max_iterations; ++it) {
    const Mat3 R = q.toRotationMatrix();
    const Vec3 g = R.col(0).cross(F.col(0)) + R.col(1).cross(F.col(1)) + R.col(2).cross(F.col(2));
    const Mat3 FRt = F * R.transpose();
    const double tr = FRt.trace();
    // H = tr I - sym(F R^T), solved in closed form (cofactors). Newton only where H is
    // safely positive definite (Sylvester's minors, relative to the scale of F).
    const double h00 = tr - FRt(0, 0), h11 = tr - FRt(1, 1), h22 = tr - FRt(2, 2);
    const double h01 = -0.5 * (FRt(0, 1) + FRt(1, 0)), h02 = -0.5 * (FRt(0, 2) + FRt(2, 0)),
                 h12 = -0.5 * (FRt(1, 2) + FRt(2, 1));
    const double c00 = h11 * h22 - h12 * h12, c01 = h02 * h12 - h01 * h22, c02 = h01 * h12 - h02 * h11;
    const double det = h00 * c00 + h01 * c01 + h02 * c02;
    const double eps = 1e-3 * scale;
    Vec3 omega;
    const bool newton = h00 > eps && h00 * h11 - h01 * h01 > eps * eps && det > eps * eps * eps;
    if (newton) {
      const double c11 = h00 * h22 - h02 * h02, c12 = h01 * h02 - h00 * h12, c22 = h00 * h11 - h01 * h01;
      omega = Vec3(c00 * g.x() + c01 * g.y() + c02 * g.z(), c01 * g.x() + c11 * g.y() + c12 * g.z(),
                   c02 * g.x() + c12 * g.y() + c22 * g.z()) /
              det;
    } else {
      omega = g / (std::abs(tr) + 1e-9 * scale);
      // A critical point that is not the maximum (a saddle: g = 0 but H indefinite, e.g.
      // starting half a turn away or at an exactly diagonal inverted F) would stop the
      // ascent; take the exact answer from the SVD instead.
      if (omega.norm() < 1e-6 && F.allFinite()) {
        Mat3 Hs;
        Hs << h00, h01, h02, h01, h11, h12, h02, h12, h22;
        Eigen::SelfAdjointEigenSolver<Mat3> es;
        es.computeDirect(Hs, Eigen::EigenvaluesOnly);
        if (es.eigenvalues()(0) < -1e-9 * scale) {
          q = Eigen::Quaterniond(rotation_svd(F));
          return it + 1;
        }
      }
    }
    const double w = omega.norm();
    if (!(w >= tolerance_rad)) break;  // also stops on NaN
    if (w > 1e-2) {
      // Large steps (cold starts): exact rotation by angle min(w, 1) about omega.
      const double a = std::min(w, 1.0);
      q = Eigen::Quaterniond(Eigen::AngleAxisd(a, omega / w)) * q;
    } else {
      // Small steps: first-order quaternion exponential, then normalise (a rotation by
      // 2 atan(w / 2) about omega; same fixed point, no trigonometry).
      const Eigen::Quaterniond dq(0.0, 0.5 * omega.x(), 0.5 * omega.y(), 0.5 * omega.z());
      q.coeffs() += (dq * q).coeffs();
    }
    q.normalize();
    // Newton converges quadratically: after a step of w the error is of order w^2, so a
    // step below sqrt(tolerance / 10) needs no further iteration to confirm (saves the
    // last of the usual two or three iterations from a warm start).
    if (newton && w * w < 0.01 * tolerance_rad) return it + 1;
  }
  return it;
}

}  // namespace fiberfem::core

namespace fiberfem::core {

// rotation_polar's Newton iteration for up to four elements side by side, one per SIMD
// lane (GCC/Clang vector extensions): updates q += (0, w/2) q, normalised, for every lane
// (the first-order step turns by 2 atan(w/2), within 1e-4 rad of w for the steps allowed
// here; Newton corrects it at the next update), until every lane is judged done as
// rotation_polar would judge it (all its updates Newton steps of at most 0.1 rad, the last
// one w with w^2 < tolerance/100 or w < tolerance), at most kMaxLaneUpdates. Then a lane
// that took a safeguarded step (far from the answer, inverted) restarts from its warm start
// in rotation_polar, and one that is merely not converged continues there. Same fixed
// point, same tolerance. (A fixed two updates left most lanes short of the default 1e-9 at
// the interactive step, 1/30 s, and rotation_polar finished 4,952 of the 7,200 rotations
// of a steady step: 1.15 M instructions.)
void rotation_polar_batch(const Mat3* F, Eigen::Quaterniond* const* q, Mat3* const* R, int n,
                          double tolerance_rad) {
  constexpr int W = 4;
  using L = double __attribute__((vector_size(W * sizeof(double))));
  L f[9], qw, qx, qy, qz, scale;
  Eigen::Quaterniond q0[W];
  for (int l = 0; l < W; ++l) {
    const int m = l < n ? l : n - 1;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) f[3 * r + c][l] = F[m](r, c);
    q0[l] = *q[m];
    qw[l] = q0[l].w();
    qx[l] = q0[l].x();
    qy[l] = q0[l].y();
    qz[l] = q0[l].z();
    scale[l] = F[m].norm() + 1e-300;
  }
  bool newton_all[W] = {true, true, true, true};
  double last_w[W] = {0, 0, 0, 0};
  L r[9];
  auto to_matrix = [&] {
    const L xx = qx * qx, yy = qy * qy, zz = qz * qz, xy = qx * qy, xz = qx * qz, yz = qy * qz, wx = qw * qx,
            wy = qw * qy, wz = qw * qz;
    r[0] = 1.0 - 2.0 * (yy + zz);
    r[1] = 2.0 * (xy - wz);
    r[2] = 2.0 * (xz + wy);
    r[3] = 2.0 * (xy + wz);
    r[4] = 1.0 - 2.0 * (xx + zz);
    r[5] = 2.0 * (yz - wx);
    r[6] = 2.0 * (xz - wy);
    r[7] = 2.0 * (yz + wx);
    r[8] = 1.0 - 2.0 * (xx + yy);
  };
  constexpr int kMaxLaneUpdates = 4;
  auto converged = [&](int l) { return last_w[l] * last_w[l] < 0.01 * tolerance_rad || last_w[l] < tolerance_rad; };
  for (int it = 0; it < kMaxLaneUpdates; ++it) {
    to_matrix();
    // g = sum_i r_i x f_i over the columns i of R and F.
    L g[3];
    g[0] = r[3] * f[6] - r[6] * f[3] + r[4] * f[7] - r[7] * f[4] + r[5] * f[8] - r[8] * f[5];
    g[1] = r[6] * f[0] - r[0] * f[6] + r[7] * f[1] - r[1] * f[7] + r[8] * f[2] - r[2] * f[8];
    g[2] = r[0] * f[3] - r[3] * f[0] + r[1] * f[4] - r[4] * f[1] + r[2] * f[5] - r[5] * f[2];
    // FRt = F R^T: FRt(a, b) = sum_k F(a, k) R(b, k).
    L M[9];
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) M[3 * a + b] = f[3 * a] * r[3 * b] + f[3 * a + 1] * r[3 * b + 1] + f[3 * a + 2] * r[3 * b + 2];
    const L tr = M[0] + M[4] + M[8];
    const L h00 = tr - M[0], h11 = tr - M[4], h22 = tr - M[8];
    const L h01 = -0.5 * (M[1] + M[3]), h02 = -0.5 * (M[2] + M[6]), h12 = -0.5 * (M[5] + M[7]);
    const L c00 = h11 * h22 - h12 * h12, c01 = h02 * h12 - h01 * h22, c02 = h01 * h12 - h02 * h11;
    const L c11 = h00 * h22 - h02 * h02, c12 = h01 * h02 - h00 * h12, c22 = h00 * h11 - h01 * h01;
    const L det = h00 * c00 + h01 * c01 + h02 * c02;
    const L eps = 1e-3 * scale;
    const L inv = 1.0 / det;
    const L ox = (c00 * g[0] + c01 * g[1] + c02 * g[2]) * inv;
    const L oy = (c01 * g[0] + c11 * g[1] + c12 * g[2]) * inv;
    const L oz = (c02 * g[0] + c12 * g[1] + c22 * g[2]) * inv;
    const L w2 = ox * ox + oy * oy + oz * oz;
    for (int l = 0; l < W; ++l) {
      const bool newton = h00[l] > eps[l] && c22[l] > eps[l] * eps[l] && det[l] > eps[l] * eps[l] * eps[l];
      newton_all[l] = newton_all[l] && newton && w2[l] <= 1e-2;  // also false for NaN
      last_w[l] = std::sqrt(w2[l]);
    }
    const L nw = qw - 0.5 * (ox * qx + oy * qy + oz * qz);
    const L nx = qx + 0.5 * (qw * ox + (oy * qz - oz * qy));
    const L ny = qy + 0.5 * (qw * oy + (oz * qx - ox * qz));
    const L nz = qz + 0.5 * (qw * oz + (ox * qy - oy * qx));
    const L n2 = nw * nw + nx * nx + ny * ny + nz * nz;
    L norm;
    for (int l = 0; l < W; ++l) norm[l] = 1.0 / std::sqrt(n2[l]);
    qw = nw * norm;
    qx = nx * norm;
    qy = ny * norm;
    qz = nz * norm;
    bool done = true;
    for (int l = 0; l < n; ++l) done = done && (!newton_all[l] || converged(l));
    if (done) break;
  }
  to_matrix();
  for (int l = 0; l < n; ++l) {
    if (!newton_all[l]) {
      *q[l] = q0[l];
      rotation_polar(F[l], *q[l], 20, tolerance_rad);
      *R[l] = q[l]->toRotationMatrix();
      continue;
    }
    *q[l] = Eigen::Quaterniond(qw[l], qx[l], qy[l], qz[l]);
    if (!converged(l)) {
      rotation_polar(F[l], *q[l], 20, tolerance_rad);
      *R[l] = q[l]->toRotationMatrix();
      continue;
    }
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) (*R[l])(a, b) = r[3 * a + b][l];
  }
}

}  // namespace fiberfem::core
