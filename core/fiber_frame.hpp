#pragma once
/// @file Fiber frames and the Voigt (Bond) strain transform (PHYSICS.md section 3).

#include "core/types.hpp"

namespace fiberfem::core {

/// Rotation Q taking global components to the fiber frame: rows m1^T, m2^T, m3^T with
/// m3 = fiber / |fiber| and (m1, m2) an arbitrary right-handed pair around it. det Q = +1.
/// @param fiber non-zero, finite direction. @throws std::invalid_argument otherwise.
Mat3 frame_from_fiber(const Vec3& fiber);

/// Same as `frame_from_fiber`, with m1 turned by `angle_rad` about the fiber. The material
/// answer must not depend on this angle (a required invariance test).
Mat3 frame_from_fiber(const Vec3& fiber, double angle_rad);

/// Voigt strain transform T(Q) for engineering shear, order (xx, yy, zz, xy, yz, zx):
/// eps_local = T(Q) eps_global when the strain tensor transforms as Q eps Q^T.
Mat6 bond_strain_transform(const Mat3& Q);

/// Stiffness in global components, C_g = T(Q)^T C T(Q), so that
/// eps_g^T C_g eps_g = eps_l^T C eps_l for every strain.
Mat6 rotate_stiffness(const Mat6& C_local, const Mat3& Q);

/// Strain tensor from a Voigt vector with engineering shear.
Mat3 strain_tensor(const Vec6& voigt_engineering);
/// Voigt vector with engineering shear from a symmetric strain tensor.
Vec6 strain_voigt(const Mat3& eps);
/// Voigt vector of a symmetric stress tensor (no factor two on shear).
Vec6 stress_voigt(const Mat3& sigma);

}  // namespace fiberfem::core
