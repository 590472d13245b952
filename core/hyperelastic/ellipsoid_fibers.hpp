#pragma once
/// @file The helix fiber rule evaluated in the lv_ellipsoid generator's own coordinates
/// (Land et al. 2015, problem 3): at any point of the shell, the transmural coordinate t of
/// the ellipsoid of the family through it (radii linear in t), the prolate angles u, v of
/// x = rs sin(u) cos(v), y = rs sin(u) sin(v), z = rl cos(u) (u in [-pi, 0]), and
///   alpha = endo_angle + (epi_angle - endo_angle) t,  f = sin(alpha) e_u + cos(alpha) e_v
/// with e_u, e_v the unit derivatives of the point along u and v; the sheet is the normal
/// of the family's ellipsoid. Continuous in the point, so the accurate tier evaluates it
/// at every quadrature point.

#include "core/hyperelastic/law.hpp"
#include "core/lv_ellipsoid.hpp"

namespace fiberfem::core::hyperelastic {

/// Axes at rest point X (m) for helix angles in degrees.
MaterialAxes ellipsoid_helix_axes(const LvEllipsoidSpec& shell, double endo_angle_deg, double epi_angle_deg, const Vec3& X);

/// The transmural coordinate of X: 0 on the inner ellipsoid, 1 on the outer.
double ellipsoid_transmural(const LvEllipsoidSpec& shell, const Vec3& X);

}  // namespace fiberfem::core::hyperelastic
