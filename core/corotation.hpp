#pragma once
/// @file Corotated element force and tangents (PHYSICS.md section 4).

#include "core/types.hpp"

namespace fiberfem::core {

/// Deformation gradient F = Ds Dm^-1 of an element with current positions `x` (12).
Mat3 deformation_gradient(const Vec12& x, const Mat3& Dm_inv);

/// Local displacement u = R^T x - X, node by node (12), up to a rigid translation: it is
/// taken relative to node 0 (u_0 = 0), which K^e does not see, to keep round-off small.
Vec12 corotated_displacement(const Mat3& R, const Vec12& x, const Vec12& X);

/// Elastic force on the element's nodes, f = -R K (R^T x - X), newtons.
Vec12 corotated_force(const Mat3& R, const Mat12& K, const Vec12& x, const Vec12& X);

/// Elastic energy 1/2 u^T K u with u = R^T x - X, joules.
double corotated_energy(const Mat3& R, const Mat12& K, const Vec12& x, const Vec12& X);

/// Warped stiffness K_t = R K R^T (blockdiag(R) K blockdiag(R)^T), the paper's tangent:
/// the derivative of -f with R held fixed. Symmetric.
Mat12 warped_stiffness(const Mat3& R, const Mat12& K);

/// Consistent tangent -df/dx including the derivative of the polar rotation R(F), for
/// static Newton solves. Not symmetric for anisotropic materials. Precondition: R is the
/// polar rotation of F = deformation_gradient(x, Dm_inv) (as both rotation methods return).
/// dR = R [w]x with (tr(S) I - S) w = axial(R^T dF - dF^T R), S = R^T F (McAdams et al.
/// 2011; Barbic 2012).
Mat12 consistent_stiffness(const Mat3& R, const Mat12& K, const Vec12& x, const Vec12& X,
                           const Mat3& Dm_inv);

}  // namespace fiberfem::core
