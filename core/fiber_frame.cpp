#include "core/fiber_frame.hpp"

#include <Eigen/Geometry>

#include <cmath>
#include <stdexcept>

namespace fiberfem::core {

Mat3 frame_from_fiber(const Vec3& fiber) { return frame_from_fiber(fiber, 0.0); }

Mat3 frame_from_fiber(const Vec3& fiber, double angle_rad) {
  const double n = fiber.norm();
  if (!(std::isfinite(n) && n > 0))
    throw std::invalid_argument("fiber direction must be finite and non-zero");
  const Vec3 m3 = fiber / n;
  // Start m1 from the coordinate axis least aligned with the fiber.
  Eigen::Index k = 0;
  m3.cwiseAbs().minCoeff(&k);
  Vec3 m1 = Vec3::Unit(k).cross(m3).normalized();
  if (angle_rad != 0.0) m1 = Eigen::AngleAxisd(angle_rad, m3) * m1;
  const Vec3 m2 = m3.cross(m1);
  Mat3 Q;
  Q.row(0) = m1.transpose();
  Q.row(1) = m2.transpose();
  Q.row(2) = m3.transpose();
  return Q;
}

Mat3 strain_tensor(const Vec6& v) {
  Mat3 e;
  e << v(0), 0.5 * v(3), 0.5 * v(5),
       0.5 * v(3), v(1), 0.5 * v(4),
       0.5 * v(5), 0.5 * v(4), v(2);
  return e;
}

Vec6 strain_voigt(const Mat3& e) {
  Vec6 v;
  v << e(0, 0), e(1, 1), e(2, 2), e(0, 1) + e(1, 0), e(1, 2) + e(2, 1), e(2, 0) + e(0, 2);
  return v;
}

Vec6 stress_voigt(const Mat3& s) {
  Vec6 v;
  v << s(0, 0), s(1, 1), s(2, 2), 0.5 * (s(0, 1) + s(1, 0)), 0.5 * (s(1, 2) + s(2, 1)),
      0.5 * (s(2, 0) + s(0, 2));
  return v;
}

// Column j of T is the local Voigt image of the j-th unit global engineering strain:
// exact by construction for every Q, with no hand-expanded Bond formulas to get wrong.
Mat6 bond_strain_transform(const Mat3& Q) {
  Mat6 T;
  for (int j = 0; j < 6; ++j) T.col(j) = strain_voigt(Q * strain_tensor(Vec6::Unit(j)) * Q.transpose());
  return T;
}

Mat6 rotate_stiffness(const Mat6& C_local, const Mat3& Q) {
  const Mat6 T = bond_strain_transform(Q);
  return T.transpose() * C_local * T;
}

}  // namespace fiberfem::core
