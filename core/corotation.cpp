#include "core/corotation.hpp"

#include <Eigen/Dense>

namespace fiberfem::core {

Mat3 deformation_gradient(const Vec12& x, const Mat3& Dm_inv) {
  Mat3 Ds;
  for (int j = 0; j < 3; ++j) Ds.col(j) = x.segment<3>(3 * (j + 1)) - x.segment<3>(0);
  return Ds * Dm_inv;
}

Vec12 corotated_displacement(const Mat3& R, const Vec12& x, const Vec12& X) {
  // Relative to node 0: K annihilates translations, so K u is unchanged in exact
  // arithmetic, while the round-off no longer scales with the distance from the origin.
  Vec12 u;
  u.segment<3>(0).setZero();
  const Vec3 x0 = x.segment<3>(0), X0 = X.segment<3>(0);
  for (int a = 1; a < 4; ++a)
    u.segment<3>(3 * a) = R.transpose() * (x.segment<3>(3 * a) - x0) - (X.segment<3>(3 * a) - X0);
  return u;
}

Vec12 corotated_force(const Mat3& R, const Mat12& K, const Vec12& x, const Vec12& X) {
  const Vec12 ku = K * corotated_displacement(R, x, X);
  Vec12 f;
  for (int a = 0; a < 4; ++a) f.segment<3>(3 * a) = -R * ku.segment<3>(3 * a);
  return f;
}

double corotated_energy(const Mat3& R, const Mat12& K, const Vec12& x, const Vec12& X) {
  const Vec12 u = corotated_displacement(R, x, X);
  return 0.5 * u.dot(K * u);
}

Mat12 warped_stiffness(const Mat3& R, const Mat12& K) {
  Mat12 Kt;
  for (int a = 0; a < 4; ++a)
    for (int b = 0; b < 4; ++b)
      Kt.block<3, 3>(3 * a, 3 * b) = R * K.block<3, 3>(3 * a, 3 * b) * R.transpose();
  return Kt;
}

// f = -R K (R^T x - X). Differentiating along a nodal direction dx:
//   -df = dR K u + R K (dR^T x) + R K R^T dx,   u = R^T x - X,
// where dR = R [w]x and w solves (tr(S) I - S) w = axial(R^T dF - dF^T R).
Mat12 consistent_stiffness(const Mat3& R, const Mat12& K, const Vec12& x, const Vec12& X,
                           const Mat3& Dm_inv) {
  const Mat3 F = deformation_gradient(x, Dm_inv);
  Mat3 S = R.transpose() * F;
  S = 0.5 * (S + S.transpose());
  Mat3 A = S.trace() * Mat3::Identity() - S;
  const Eigen::FullPivLU<Mat3> lu(A);
  const Vec12 u = corotated_displacement(R, x, X);
  const Vec12 Ku = K * u;
  Mat12 Kc = warped_stiffness(R, K);
  // Gradient of each shape function: dF = e_c (grad N_a)^T for a unit move of node a along c.
  Eigen::Matrix<double, 3, 4> G;
  G.rightCols<3>() = Dm_inv.transpose();
  G.col(0) = -G.rightCols<3>().rowwise().sum();
  for (int a = 0; a < 4; ++a) {
    for (int c = 0; c < 3; ++c) {
      const Mat3 dF = Vec3::Unit(c) * G.col(a).transpose();
      const Mat3 W = R.transpose() * dF - dF.transpose() * R;
      const Vec3 rhs(W(2, 1), W(0, 2), W(1, 0));
      const Vec3 w = lu.solve(rhs);
      Mat3 Omega;
      Omega << 0, -w(2), w(1), w(2), 0, -w(0), -w(1), w(0), 0;
      const Mat3 dR = R * Omega;
      Vec12 dRtx;
      for (int b = 0; b < 4; ++b) dRtx.segment<3>(3 * b) = dR.transpose() * x.segment<3>(3 * b);
      const Vec12 KdRtx = K * dRtx;
      Vec12 col;
      for (int b = 0; b < 4; ++b)
        col.segment<3>(3 * b) = dR * Ku.segment<3>(3 * b) + R * KdRtx.segment<3>(3 * b);
      Kc.col(3 * a + c) += col;
    }
  }
  return Kc;
}

}  // namespace fiberfem::core
