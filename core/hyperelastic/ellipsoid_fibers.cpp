#include "core/hyperelastic/ellipsoid_fibers.hpp"

#include <algorithm>
#include <cmath>

namespace fiberfem::core::hyperelastic {

// g(t) = (x^2 + y^2)/rs(t)^2 + z^2/rl(t)^2 - 1 falls monotonically in t (the radii grow), so
// bisection on a bracket a little wider than the wall (points of a faceted surface lie
// slightly off it) finds its root.
double ellipsoid_transmural(const LvEllipsoidSpec& s, const Vec3& X) {
  auto g = [&](double t) {
    const double rs = s.endo_rs_m + t * (s.epi_rs_m - s.endo_rs_m);
    const double rl = s.endo_rl_m + t * (s.epi_rl_m - s.endo_rl_m);
    return (X.x() * X.x() + X.y() * X.y()) / (rs * rs) + X.z() * X.z() / (rl * rl) - 1;
  };
  double lo = -0.5, hi = 1.5;
  for (int i = 0; i < 80; ++i) {
    const double mid = 0.5 * (lo + hi);
    (g(mid) > 0 ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

MaterialAxes ellipsoid_helix_axes(const LvEllipsoidSpec& s, double endo_deg, double epi_deg, const Vec3& X) {
  const double t = ellipsoid_transmural(s, X);
  const double rs = s.endo_rs_m + t * (s.epi_rs_m - s.endo_rs_m);
  const double rl = s.endo_rl_m + t * (s.epi_rl_m - s.endo_rl_m);
  const double u = -std::acos(std::clamp(X.z() / rl, -1.0, 1.0));
  // x = rs sin(u) cos(v) with sin(u) <= 0: v is the azimuth of -X, not of X.
  const double v = std::atan2(-X.y(), -X.x());
  const Vec3 dxdu(rs * std::cos(u) * std::cos(v), rs * std::cos(u) * std::sin(v), -rl * std::sin(u));
  // d x/d v = rs sin(u) (-sin v, cos v, 0), and sin(u) <= 0 on the shell.
  const Vec3 e_v = (std::sin(u) > 0 ? 1.0 : -1.0) * Vec3(-std::sin(v), std::cos(v), 0.0);
  const double alpha = (endo_deg + (epi_deg - endo_deg) * std::clamp(t, 0.0, 1.0)) * M_PI / 180.0;
  const Vec3 fiber = std::sin(alpha) * dxdu.normalized() + std::cos(alpha) * e_v;
  const Vec3 normal(X.x() / (rs * rs), X.y() / (rs * rs), X.z() / (rl * rl));
  return MaterialAxes::from(fiber, normal);
}

}  // namespace fiberfem::core::hyperelastic
