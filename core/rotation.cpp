#include "core/rotation.hpp"

#include <Eigen/Cholesky>
#include <Eigen/SVD>

#include <cmath>

namespace fiberfem::core {

// Irving, Teran, Fedkiw 2004, section 5: Eigen sorts singular values in decreasing order,
// so the sign fix goes on the last column.
Mat3 rotation_svd(const Mat3& F) {
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
  int it = 0;
  for (; it < max_iterations; ++it) {
    const Mat3 R = q.toRotationMatrix();
    const Vec3 g = R.col(0).cross(F.col(0)) + R.col(1).cross(F.col(1)) + R.col(2).cross(F.col(2));
    const Mat3 FRt = F * R.transpose();
    const Mat3 P = 0.5 * (FRt + FRt.transpose());
    const double tr = P.trace();
    const Mat3 H = tr * Mat3::Identity() - P;
    Vec3 omega;
    Eigen::LLT<Mat3> llt(H);
    // Newton only where H is well inside the positive-definite cone: its smallest diagonal
    // of the factor bounded away from zero relative to the scale of F.
    const double scale = F.norm() + 1e-300;
    if (llt.info() == Eigen::Success && llt.matrixLLT().diagonal().minCoeff() > 1e-3 * std::sqrt(scale)) {
      omega = llt.solve(g);
    } else {
      omega = g / (std::abs(tr) + 1e-9 * scale);
    }
    double w = omega.norm();
    if (!(w >= tolerance_rad)) break;  // also stops on NaN
    if (w > 1.0) {  // keep steps in the trusted region of the quadratic model
      omega *= 1.0 / w;
      w = 1.0;
    }
    q = Eigen::Quaterniond(Eigen::AngleAxisd(w, omega / w)) * q;
    q.normalize();
  }
  return it;
}

}  // namespace fiberfem::core
