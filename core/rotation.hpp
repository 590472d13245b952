#pragma once
/// @file Rotation extraction from a deformation gradient (PHYSICS.md section 4).

#include "core/types.hpp"

#include <Eigen/Geometry>

namespace fiberfem::core {

/// How the rotation part of F is extracted. Both return a proper rotation (det = +1), also
/// for inverted elements (det F <= 0), and both return the rotation that maximises
/// trace(R^T F) over SO(3), so they agree wherever that maximiser is unique.
enum class RotationMethod {
  /// 3x3 SVD with the sign fix of Irving, Teran and Fedkiw (2004). Exact, the reference.
  svd,
  /// Quaternion ascent on trace(R^T F) with Newton steps (falling back to the steps of
  /// Mueller et al. 2016 far from the answer), warm-started from the element's previous
  /// rotation: two or three iterations per step, cheaper than the SVD.
  polar,
};

/// "svd" or "polar".
const char* to_string(RotationMethod m);

/// Proper rotation of F by modified SVD: F = U S V^T with the sign of the smallest singular
/// value flipped when U or V is a reflection, R = U V^T.
Mat3 rotation_svd(const Mat3& F);

/// Proper rotation of F by quaternion iteration, starting from and updating `q`.
/// Stops when the update angle is below `tolerance_rad`, after a Newton update w with
/// w^2 < tolerance_rad / 10 (quadratic convergence: the next update would be below the
/// tolerance), or after `max_iterations`.
/// @return the number of iterations used.
int rotation_polar(const Mat3& F, Eigen::Quaterniond& q, int max_iterations = 20,
                   double tolerance_rad = 1e-12);

/// rotation_polar for n <= 4 elements at once (SIMD lanes): F[l], the warm start *q[l]
/// (updated) and the rotation *R[l] of each. Agrees with rotation_polar to the tolerance;
/// lanes far from the answer or inverted are handed to rotation_polar itself.
void rotation_polar_batch(const Mat3* F, Eigen::Quaterniond* const* q, Mat3* const* R, int n,
                          double tolerance_rad);

}  // namespace fiberfem::core
