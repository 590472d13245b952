// The helix rule in the lv_ellipsoid shell's own coordinates against the parametrisation
// it is defined by: points built from (t, u, v) give back t, and the fiber is
// sin(alpha) dx/du + cos(alpha) dx/dv (unit derivatives by central differences of the
// parametrisation), tangent to the ellipsoid through the point.

#include "core/hyperelastic/ellipsoid_fibers.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace fiberfem::core::hyperelastic {
namespace {

// x = rs(t) sin(u) cos(v), y = rs(t) sin(u) sin(v), z = rl(t) cos(u), radii linear in t.
Vec3 point(const LvEllipsoidSpec& s, double t, double u, double v) {
  const double rs = s.endo_rs_m + t * (s.epi_rs_m - s.endo_rs_m);
  const double rl = s.endo_rl_m + t * (s.epi_rl_m - s.endo_rl_m);
  return Vec3(rs * std::sin(u) * std::cos(v), rs * std::sin(u) * std::sin(v), rl * std::cos(u));
}

TEST(EllipsoidFibers, FollowTheParametrisationOfTheShell) {
  const LvEllipsoidSpec s;  // Land et al. 2015's ventricle
  const double endo = 90, epi = -90;
  int checked = 0;
  for (double t : {0.0, 0.25, 0.6, 1.0})
    for (double u : {-2.9, -2.2, -1.6})
      for (double v : {-2.5, -0.3, 0.4, 1.9, 3.0}) {
        const Vec3 X = point(s, t, u, v);
        EXPECT_NEAR(ellipsoid_transmural(s, X), t, 1e-9);
        const double h = 1e-6;
        const Vec3 du = ((point(s, t, u + h, v) - point(s, t, u - h, v)) / (2 * h)).normalized();
        const Vec3 dv = ((point(s, t, u, v + h) - point(s, t, u, v - h)) / (2 * h)).normalized();
        const double alpha = (endo + (epi - endo) * t) * M_PI / 180;
        const Vec3 expected = (std::sin(alpha) * du + std::cos(alpha) * dv).normalized();
        const MaterialAxes ax = ellipsoid_helix_axes(s, endo, epi, X);
        EXPECT_NEAR(std::abs(ax.f.dot(expected)), 1.0, 1e-8) << "t " << t << " u " << u << " v " << v;
        // Tangent to the ellipsoid of the family through X; the sheet along its normal.
        const Vec3 normal = du.cross(dv).normalized();
        EXPECT_NEAR(ax.f.dot(normal), 0.0, 1e-8);
        EXPECT_NEAR(std::abs(ax.s.dot(normal)), 1.0, 1e-6);
        ++checked;
      }
  EXPECT_EQ(checked, 60);
}

}  // namespace
}  // namespace fiberfem::core::hyperelastic
