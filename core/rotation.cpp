#include "core/rotation.hpp"

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

// Mueller, Bender, Chentanez, Macklin 2016, "A robust method to extract the rotational
// part of deformations": rotate q by omega = sum_i r_i x f_i / |sum_i r_i . f_i|, an
// ascent step on trace(R^T F) that keeps q a unit quaternion.
int rotation_polar(const Mat3& F, Eigen::Quaterniond& q, int max_iterations, double tolerance_rad) {
  int it = 0;
  for (; it < max_iterations; ++it) {
    const Mat3 R = q.toRotationMatrix();
    const Vec3 omega_num = R.col(0).cross(F.col(0)) + R.col(1).cross(F.col(1)) + R.col(2).cross(F.col(2));
    const double denom = std::abs(R.col(0).dot(F.col(0)) + R.col(1).dot(F.col(1)) + R.col(2).dot(F.col(2))) + 1e-9;
    const Vec3 omega = omega_num / denom;
    const double w = omega.norm();
    if (!(w >= tolerance_rad)) break;  // also stops on NaN
    q = Eigen::Quaterniond(Eigen::AngleAxisd(w, omega / w)) * q;
    q.normalize();
  }
  return it;
}

}  // namespace fiberfem::core
