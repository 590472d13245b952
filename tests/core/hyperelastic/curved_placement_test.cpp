// Mid-edge nodes on the generator's curved surfaces (core/hyperelastic/curved_placement.hpp):
// nodes of endo and epi edges on their ellipsoids, the base flat, other nodes in the wall
// near their chords, no element tangled from the coarsest meshes on; the cavity enclosed by the quadratic endocardium and the wall volume against
// the analytic truncated ellipsoids, far closer than the linear mesh's at the same corners.

#include "core/hyperelastic/curved_placement.hpp"
#include "core/hyperelastic/quadrature.hpp"
#include "core/hyperelastic/shape_functions.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <tuple>

namespace core = fiberfem::core;
namespace hyper = fiberfem::core::hyperelastic;
using core::Vec3;
using fiberfem::testing::expect_invalid;
using fiberfem::testing::lv_spec;
using fiberfem::testing::truncated_ellipsoid_volume;

namespace {

bool in(const std::vector<int>& sorted, int i) { return std::binary_search(sorted.begin(), sorted.end(), i); }

double ellipsoid(const Vec3& p, double rs, double rl) {
  return (p.x() * p.x() + p.y() * p.y()) / (rs * rs) + p.z() * p.z() / (rl * rl);
}

// Volume enclosed by the boundary faces whose corners are all in `set`, closed by the base
// plane z = b: by the divergence theorem with F = (0, 0, z - b) (no flux through the base),
// V = |sum over faces of int (z - b) n_z dA|, with n dA = dx/dxi1 x dx/dxi2 dxi on each
// face mapped by its 3 or 6 nodes. The integrand has degree <= 4: the 7-point rule is exact.
double enclosed_volume(const hyper::ElementMesh& m, const std::vector<int>& set, double b) {
  const hyper::TriangleRule& rule = hyper::triangle_rule(7);
  const int n = m.order() == 1 ? 3 : 6;
  double v = 0;
  for (const auto& face : m.boundary_faces()) {
    if (!(in(set, face[0]) && in(set, face[1]) && in(set, face[2]))) continue;
    Eigen::Matrix<double, 3, 6> X = Eigen::Matrix<double, 3, 6>::Zero();
    for (int a = 0; a < n; ++a) X.col(a) = m.rest_positions().col(face[static_cast<size_t>(a)]);
    for (size_t q = 0; q < rule.points.size(); ++q) {
      const hyper::TriangleShape s = hyper::triangle_shape(m.order(), rule.points[q]);
      const Vec3 x = X * s.N, t1 = X * s.dN.col(0), t2 = X * s.dN.col(1);
      v += rule.weights[q] * (x.z() - b) * t1.cross(t2).z();
    }
  }
  return std::abs(v);
}

double total(const std::vector<double>& v) { return std::accumulate(v.begin(), v.end(), 0.0); }

}  // namespace

TEST(LvEllipsoidEdgePlacement, SurfaceEdgeNodesOnTheirEllipsoidsBaseFlat) {
  const core::LvEllipsoidSpec spec = lv_spec(12, 5, 2);
  const core::TetMesh m = core::make_lv_ellipsoid(spec);
  const hyper::ElementMesh e(m, 2, hyper::lv_ellipsoid_edge_placement(spec, m));
  const std::vector<int>&endo = m.node_set("endo"), &epi = m.node_set("epi"), &base = m.node_set("base");
  int on_endo = 0, on_epi = 0, on_base = 0, inside = 0;
  for (size_t i = 0; i < e.edge_ends().size(); ++i) {
    const auto [a, b] = e.edge_ends()[i];
    const Vec3 p = e.rest_positions().col(e.num_corner_nodes() + static_cast<int>(i));
    const bool both_base = in(base, a) && in(base, b);
    if (both_base) {
      EXPECT_EQ(p.z(), spec.base_z_m) << "edge " << a << "-" << b;
      ++on_base;
    }
    if (in(endo, a) && in(endo, b)) {
      EXPECT_NEAR(ellipsoid(p, spec.endo_rs_m, spec.endo_rl_m), 1.0, 1e-13);
      ++on_endo;
    } else if (in(epi, a) && in(epi, b)) {
      EXPECT_NEAR(ellipsoid(p, spec.epi_rs_m, spec.epi_rl_m), 1.0, 1e-13);
      ++on_epi;
    } else {
      // In the wall (outside the endocardium, inside the epicardium), near the chord (the
      // sagitta over the chord is c / (8 R), about 0.2 at this coarse mesh's apex).
      EXPECT_GT(ellipsoid(p, spec.endo_rs_m, spec.endo_rl_m), 1.0);
      EXPECT_LT(ellipsoid(p, spec.epi_rs_m, spec.epi_rl_m), 1.0);
      const Vec3 ab = m.rest_positions().col(b) - m.rest_positions().col(a);
      EXPECT_LT((p - 0.5 * (m.rest_positions().col(a) + m.rest_positions().col(b))).norm(), 0.25 * ab.norm());
      ++inside;
    }
  }
  EXPECT_GT(on_endo, 0);
  EXPECT_GT(on_epi, 0);
  EXPECT_GT(on_base, 0);
  EXPECT_GT(inside, 0);
  // Surface nodes really moved off the chords (the surfaces are convex).
  double largest_move = 0;
  for (size_t i = 0; i < e.edge_ends().size(); ++i) {
    const auto [a, b] = e.edge_ends()[i];
    largest_move = std::max(largest_move, (e.rest_positions().col(e.num_corner_nodes() + static_cast<int>(i)) -
                                           0.5 * (m.rest_positions().col(a) + m.rest_positions().col(b)))
                                              .norm());
  }
  EXPECT_GT(largest_move, 1e-5);
}

// The faceted endocardium's cavity error is O(h^2); the quadratic one's is of higher order.
// At every resolution the quadratic error is at least 5 times smaller (measured: the table
// printed below), and so is the wall's volume error.
TEST(LvEllipsoidEdgePlacement, CurvedSurfacesEncloseTheAnalyticVolumes) {
  const core::LvEllipsoidSpec d;
  const double cavity = truncated_ellipsoid_volume(d.endo_rs_m, d.endo_rl_m, d.base_z_m);
  const double wall = truncated_ellipsoid_volume(d.epi_rs_m, d.epi_rl_m, d.base_z_m) - cavity;
  std::printf("%-14s %14s %14s %14s %14s\n", "resolution", "cavity P1", "cavity P2", "wall P1", "wall P2");
  double last_p2 = 1;
  for (const auto& [c, l] : {std::pair{12, 4}, {24, 7}, {48, 13}}) {
    const core::LvEllipsoidSpec spec = lv_spec(c, l, 2);
    const core::TetMesh m = core::make_lv_ellipsoid(spec);
    const hyper::ElementMesh linear(m, 1), quadratic(m, 2, hyper::lv_ellipsoid_edge_placement(spec, m));
    const double e1 = std::abs(enclosed_volume(linear, m.node_set("endo"), d.base_z_m) - cavity) / cavity;
    const double e2 = std::abs(enclosed_volume(quadratic, m.node_set("endo"), d.base_z_m) - cavity) / cavity;
    const double w1 = std::abs(total(hyper::element_volumes(linear)) - wall) / wall;
    const double w2 = std::abs(total(hyper::element_volumes(quadratic)) - wall) / wall;
    std::printf("(%3d,%3d,%2d)   %14.3e %14.3e %14.3e %14.3e\n", c, l, 2, e1, e2, w1, w2);
    EXPECT_GT(e1 / e2, 5) << c << "," << l;
    EXPECT_GT(w1 / w2, 5) << c << "," << l;
    EXPECT_LT(e2, last_p2 / 4) << c << "," << l;
    last_p2 = e2;
  }
}

// The constructor refuses tangled elements (det J <= 0 at a node or quadrature point), so
// building the mesh is the test. Measured over circumferential 6..48, longitudinal 2..16,
// transmural 1..5: only longitudinal 2 (one step from the apex to the base) tangles.
TEST(LvEllipsoidEdgePlacement, NoElementTangledAtCoarseResolutions) {
  for (const auto& [c, l, t] : {std::tuple{6, 3, 1}, {12, 3, 1}, {12, 4, 1}, {12, 5, 2}, {24, 10, 3}, {8, 6, 4}}) {
    const core::LvEllipsoidSpec spec = lv_spec(c, l, t);
    const core::TetMesh m = core::make_lv_ellipsoid(spec);
    EXPECT_NO_THROW(hyper::ElementMesh(m, 2, hyper::lv_ellipsoid_edge_placement(spec, m))) << c << "," << l << "," << t;
  }
  const core::LvEllipsoidSpec one_step = lv_spec(12, 2, 1);
  const core::TetMesh m = core::make_lv_ellipsoid(one_step);
  expect_invalid([&] { hyper::ElementMesh(m, 2, hyper::lv_ellipsoid_edge_placement(one_step, m)); }, {"tangled"});
}

TEST(LvEllipsoidEdgePlacement, RefusesAMeshOfAnotherSpec) {
  core::Positions x(3, 4);
  x << 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1;
  const core::TetMesh m(x, {{0, 1, 2, 3}});
  expect_invalid([&] { hyper::lv_ellipsoid_edge_placement(core::LvEllipsoidSpec{}, m); }, {"node 0", "wall"});
  core::LvEllipsoidSpec bad;
  bad.epi_rs_m = 0.001;
  const core::TetMesh lv = core::make_lv_ellipsoid(core::LvEllipsoidSpec{});
  expect_invalid([&] { hyper::lv_ellipsoid_edge_placement(bad, lv); }, {"epi_rs_m"});
}
