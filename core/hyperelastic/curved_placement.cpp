#include "core/hyperelastic/curved_placement.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

namespace fiberfem::core::hyperelastic {

namespace {

// The wall of make_lv_ellipsoid is the family of ellipsoids of revolution whose radii are
// interpolated linearly in the transmural coordinate w in [0, 1] (0 endo, 1 epi).
struct Wall {
  double endo_rs, endo_rl, epi_rs, epi_rl, base_z;
  double rs(double w) const { return endo_rs + w * (epi_rs - endo_rs); }
  double rl(double w) const { return endo_rl + w * (epi_rl - endo_rl); }
  // (x^2 + y^2) / rs^2 + z^2 / rl^2 - 1 on the ellipsoid w: decreasing in w.
  double level(const Vec3& p, double w) const {
    return (p.x() * p.x() + p.y() * p.y()) / (rs(w) * rs(w)) + p.z() * p.z() / (rl(w) * rl(w)) - 1;
  }
};

// The w of the ellipsoid through p, by bisection on [0, 1] (the level is monotone in w).
// NaN when p is not in the wall.
double transmural_coordinate(const Wall& wall, const Vec3& p) {
  double lo = 0, hi = 1;
  const double scale = 1e-9;
  if (wall.level(p, lo) < -scale || wall.level(p, hi) > scale) return std::nan("");
  for (int i = 0; i < 60; ++i) {
    const double mid = 0.5 * (lo + hi);
    (wall.level(p, mid) > 0 ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

// The point of the ellipsoid (x^2 + y^2) / rs^2 + z^2 / rl^2 = 1 closest to m: the
// stationarity condition of the Lagrangian gives p(t) = (m_xy rs^2 / (rs^2 + t),
// m_z rl^2 / (rl^2 + t)) with g(t) = (ellipsoid level of p(t)) = 0. g is decreasing and
// convex for t > -rs^2, so Newton from t = 0 converges (monotonically after the first
// step); m is a chord midpoint, O(h^2) from the surface, so t stays small.
Vec3 closest_point(double rs, double rl, const Vec3& m) {
  const double rs2 = rs * rs, rl2 = rl * rl;
  const double r2 = m.x() * m.x() + m.y() * m.y(), z2 = m.z() * m.z();
  double t = 0;
  for (int i = 0; i < 50; ++i) {
    const double a = rs2 / (rs2 + t), b = rl2 / (rl2 + t);
    const double g = r2 * a * a / rs2 + z2 * b * b / rl2 - 1;
    const double dg = -2 * (r2 * a * a / (rs2 * (rs2 + t)) + z2 * b * b / (rl2 * (rl2 + t)));
    const double step = g / dg;
    t -= step;
    if (std::abs(step) <= 1e-16 * std::max(rs2, std::abs(t))) break;
  }
  return {m.x() * rs2 / (rs2 + t), m.y() * rs2 / (rs2 + t), m.z() * rl2 / (rl2 + t)};
}

// On the base (the ellipsoid w cut by z = base_z, a circle): the midpoint pushed radially
// onto the circle, z the plane exactly.
Vec3 on_base_circle(const Wall& wall, double w, const Vec3& m) {
  const double c = wall.base_z / wall.rl(w);
  const Eigen::Vector2d xy = m.head<2>().normalized() * (wall.rs(w) * std::sqrt(1 - c * c));
  return {xy.x(), xy.y(), wall.base_z};
}

}  // namespace

// Why every edge of the wall and not only the endo and epi ones: the apex of the prolate
// endocardium is sharply curved (radius rs^2 / rl, 2.9 mm for the default), so on a coarse
// mesh a curved endocardial face bulges by a good part of the first layer's thickness; with
// the layer's inner edges straight the apex elements tangle. Curving every layer along its
// own ellipsoid moves the whole wall together. Closest points rather than the mean of the
// corners' (u, v): the parametrisation is singular at the apex, where the arc of constant u
// between two nodes of the first ring bows out in the tangent plane.
EdgePlacement lv_ellipsoid_edge_placement(const LvEllipsoidSpec& spec, const TetMesh& mesh) {
  spec.validate();
  const Wall wall{spec.endo_rs_m, spec.endo_rl_m, spec.epi_rs_m, spec.epi_rl_m, spec.base_z_m};
  std::vector<double> w(static_cast<size_t>(mesh.num_nodes()));
  std::vector<bool> base(static_cast<size_t>(mesh.num_nodes()));
  for (int i = 0; i < mesh.num_nodes(); ++i) {
    const Vec3 p = mesh.rest_positions().col(i);
    w[static_cast<size_t>(i)] = transmural_coordinate(wall, p);
    if (std::isnan(w[static_cast<size_t>(i)]))
      throw std::invalid_argument("lv_ellipsoid edge placement: node " + std::to_string(i) +
                                  " is not in the wall of this spec (the mesh was made by another one?)");
    base[static_cast<size_t>(i)] = p.z() == spec.base_z_m;  // the generator sets it exactly
  }
  return [wall, w = std::move(w), base = std::move(base)](int a, int b, const Vec3& midpoint) -> Vec3 {
    const double wm = 0.5 * (w[static_cast<size_t>(a)] + w[static_cast<size_t>(b)]);
    if (base[static_cast<size_t>(a)] && base[static_cast<size_t>(b)]) return on_base_circle(wall, wm, midpoint);
    return closest_point(wall.rs(wm), wall.rl(wm), midpoint);
  };
}

}  // namespace fiberfem::core::hyperelastic
