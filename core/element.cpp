#include "core/element.hpp"

#include "core/fiber_frame.hpp"

#include <Eigen/Dense>

#include <cmath>

namespace fiberfem::core {

Vec12 gather(const Eigen::Ref<const Positions>& x, const Tet& t) {
  Vec12 v;
  for (int a = 0; a < 4; ++a) v.segment<3>(3 * a) = x.col(t[static_cast<size_t>(a)]);
  return v;
}

Mat3 rest_shape_inverse(const Vec12& X) {
  Mat3 Dm;
  for (int j = 0; j < 3; ++j) Dm.col(j) = X.segment<3>(3 * (j + 1)) - X.segment<3>(0);
  return Dm.inverse();
}

// x(X) = x0 + Ds Dm^-1 (X - X0), so grad N_a = row (a-1) of Dm^-1 for a = 1..3 and
// grad N_0 = -(sum of the others). Rows of B follow PHYSICS.md section 1.
Mat6x12 strain_operator(const Mat3& Dm_inv) {
  Eigen::Matrix<double, 3, 4> G;
  G.rightCols<3>() = Dm_inv.transpose();
  G.col(0) = -G.rightCols<3>().rowwise().sum();
  Mat6x12 B = Mat6x12::Zero();
  for (int a = 0; a < 4; ++a) {
    const double bx = G(0, a), by = G(1, a), bz = G(2, a);
    const int c = 3 * a;
    B(0, c) = bx;
    B(1, c + 1) = by;
    B(2, c + 2) = bz;
    B(3, c) = by; B(3, c + 1) = bx;
    B(4, c + 1) = bz; B(4, c + 2) = by;
    B(5, c) = bz; B(5, c + 2) = bx;
  }
  return B;
}

namespace {
double volume_of(const Vec12& X) {
  Mat3 Dm;
  for (int j = 0; j < 3; ++j) Dm.col(j) = X.segment<3>(3 * (j + 1)) - X.segment<3>(0);
  return std::abs(Dm.determinant()) / 6.0;
}
}  // namespace

// PHYSICS.md section 3: K^e = V B^T C_g B, C_g = T(Q)^T C T(Q), B from global gradients.
// (The literal reading of the paper's eq. 11, K = M^T (LN)^T C (LN) M with global LN, is
// not rotation invariant; see tests/core/element_test.cpp.)
Mat12 element_stiffness(const Vec12& X, const Material& material, const Vec3& fiber,
                        double frame_angle_rad) {
  const Mat6x12 B = strain_operator(rest_shape_inverse(X));
  const double V = volume_of(X);
  if (material.is_isotropic()) return V * B.transpose() * material.stiffness() * B;
  const Mat6 Cg = rotate_stiffness(material.stiffness(), frame_from_fiber(fiber, frame_angle_rad));
  Mat12 K = V * B.transpose() * Cg * B;
  return 0.5 * (K + K.transpose());
}

Vec12 active_stress_vector(const Vec12& X, const Vec3& fiber) {
  const Vec3 f = fiber.normalized();
  const Mat6x12 B = strain_operator(rest_shape_inverse(X));
  return volume_of(X) * B.transpose() * stress_voigt(f * f.transpose());
}

}  // namespace fiberfem::core
