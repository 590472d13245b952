#pragma once
/// @file Per-element rest-shape quantities and precomputed stiffness (PHYSICS.md sections 3, 6).

#include "core/material.hpp"
#include "core/types.hpp"

namespace fiberfem::core {

/// Rest-shape inverse Dm^-1, with Dm = [X1-X0, X2-X0, X3-X0]. Precondition: non-degenerate.
Mat3 rest_shape_inverse(const Vec12& X);

/// Strain operator B (6 x 12): eps = B u for nodal displacements u, Voigt order
/// (xx, yy, zz, xy, yz, zx) with engineering shear, built from global rest gradients.
Mat6x12 strain_operator(const Mat3& Dm_inv);

/// Element stiffness in global components by the correct frame transform of PHYSICS.md
/// section 3: K^e = V B^T C_g B with C_g = T(Q)^T C T(Q) and Q the fiber frame. For an
/// isotropic material the frame is skipped (C_g = C). Symmetric positive semi-definite
/// with exactly six zero eigenvalues (rigid motions).
/// @param X rest positions of the four nodes (12), metres.
/// @param fiber fiber direction (need not be unit; ignored for isotropic materials).
/// @param frame_angle_rad rotation of (m1, m2) about the fiber; has no effect (tested).
Mat12 element_stiffness(const Vec12& X, const Material& material, const Vec3& fiber,
                        double frame_angle_rad = 0.0);

/// Active-stress force vector g^e = V B^T voigt(f f^T) (PHYSICS.md section 6); the nodal
/// force of an active tension T_a (Pa) along the rotated fiber is -T_a R g^e.
Vec12 active_stress_vector(const Vec12& X, const Vec3& fiber);

/// Element displacement vector of the four nodes (12) from a 3 x N position matrix.
Vec12 gather(const Eigen::Ref<const Positions>& x, const Tet& t);

}  // namespace fiberfem::core
