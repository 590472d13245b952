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
