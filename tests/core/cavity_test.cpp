// Cavity volumes (core/cavity.hpp): the endocardial cavity of the benchmark ellipsoid
// against the analytic truncated ellipsoid (converging as the faceting refines), the
// closed-polyhedron identities (rigid motions change nothing, scaling by s multiplies by
// s^3), the volume swept by moving one rim-free vertex, and bad input.

#include "core/box_generator.hpp"
#include "core/cavity.hpp"
#include "core/lv_ellipsoid.hpp"
#include "test_support.hpp"

#include <cmath>
#include <random>

namespace core = fiberfem::core;
using core::Vec3;

namespace {


constexpr auto truncated_ellipsoid = fiberfem::testing::truncated_ellipsoid_volume;

core::TetMesh lv(int c, int l, int t) { return core::make_lv_ellipsoid(fiberfem::testing::lv_spec(c, l, t)); }

}  // namespace

// The inscribed polyhedron underestimates the cavity by O(h^2): the error must fall about
// fourfold per halving of the spacing and be under 1% at (48, 20, *).
TEST(Cavity, EndocardialVolumeConvergesToTheTruncatedEllipsoid) {
  const double exact = truncated_ellipsoid(0.007, 0.017, 0.005);
  double last = 1;
  for (int k : {1, 2, 4}) {
    const core::TetMesh m = lv(12 * k, 5 * k, 2);
    const core::CavitySurface s = core::cavity_surface(m, m.node_set("endo"));
    EXPECT_EQ(s.rim_nodes.size(), static_cast<size_t>(12 * k));  // the base ring of the endocardium
    const double v = core::cavity_volume(s, m.rest_positions());
    const double err = (exact - v) / exact;
    std::printf("cavity (%d, %d): %.6e m^3 vs %.6e, error %.4f\n", 12 * k, 5 * k, v, exact, err);
    EXPECT_GT(err, 0);
    if (k > 1) {
      EXPECT_GT(last / err, 3.0);
    }
    last = err;
  }
  EXPECT_LT(last, 0.01);
}

TEST(Cavity, RigidMotionsChangeNothingAndScalingCubes) {
  const core::TetMesh m = lv(24, 10, 2);
  const core::CavitySurface s = core::cavity_surface(m, m.node_set("endo"));
  const double v0 = core::cavity_volume(s, m.rest_positions());
  std::mt19937 rng(9);
  const core::Mat3 R = fiberfem::testing::random_rotation(rng);
  const core::Positions moved = (R * m.rest_positions()).colwise() + Vec3(3.0, -2.0, 7.5);
  EXPECT_NEAR(core::cavity_volume(s, moved) / v0, 1.0, 1e-11);
  EXPECT_NEAR(core::cavity_volume(s, 1.7 * m.rest_positions()) / v0, 1.7 * 1.7 * 1.7, 1e-12);
}

// Moving a vertex of a closed polyhedron by d changes its volume by d . A / 3 to first
// order, A the sum of the outward area vectors of the vertex's faces. The cavity's outward
// side is the solid's inward one, so moving the endocardial apex by d changes the cavity
// by -d . A_solid / 3. Checked by a finite difference.
TEST(Cavity, DerivativeIsTheAreaVectorOfTheNodesFaces) {
  const core::TetMesh m = lv(24, 10, 2);
  const core::CavitySurface s = core::cavity_surface(m, m.node_set("endo"));
  const int node = m.node_set("apex_endo").front();
  Vec3 area = Vec3::Zero();  // sum of solid-outward area vectors of the faces at `node`
  for (const core::Tri& t : s.faces)
    if (t[0] == node || t[1] == node || t[2] == node) {
      const Vec3 a = m.rest_positions().col(t[0]), b = m.rest_positions().col(t[1]), c = m.rest_positions().col(t[2]);
      area += 0.5 * (b - a).cross(c - a);
    }
  const Vec3 d(1e-7, -2e-7, 3e-7);
  core::Positions x = m.rest_positions();
  x.col(node) += d;
  const double dv = core::cavity_volume(s, x) - core::cavity_volume(s, m.rest_positions());
  // Moving a vertex by d changes an enclosed volume by d . (sum of its faces' outward area
  // vectors) / 3; the cavity's outward normal is the solid's inward one.
  EXPECT_NEAR(dv / (-d.dot(area) / 3.0), 1.0, 1e-5);
}

// cavity_volume_gradient against central differences of cavity_volume, at every node of a
// randomly deformed ventricle (surface nodes, rim nodes with the lid's centre, and nodes
// off the surface, whose gradient is zero).
TEST(Cavity, VolumeGradientMatchesFiniteDifferences) {
  const core::TetMesh m = lv(12, 6, 2);
  const core::CavitySurface s = core::cavity_surface(m, m.node_set("endo"));
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> jitter(-5e-4, 5e-4);
  core::Positions x = m.rest_positions();
  for (Eigen::Index i = 0; i < x.size(); ++i) x.data()[i] += jitter(rng);
  const core::Positions g = core::cavity_volume_gradient(s, x);
  ASSERT_EQ(g.cols(), x.cols());
  const double h = 1e-6, scale = g.cwiseAbs().maxCoeff();
  ASSERT_GT(scale, 0);
  for (Eigen::Index n = 0; n < x.cols(); ++n)
    for (int i = 0; i < 3; ++i) {
      core::Positions xp = x, xm = x;
      xp(i, n) += h;
      xm(i, n) -= h;
      const double fd = (core::cavity_volume(s, xp) - core::cavity_volume(s, xm)) / (2 * h);
      ASSERT_NEAR(g(i, n), fd, 1e-6 * scale) << "node " << n << " component " << i;
    }
}

TEST(Cavity, BadInput) {
  const core::TetMesh m = lv(12, 4, 1);
  fiberfem::testing::expect_invalid([&] { core::cavity_surface(m, {0}); }, {"no boundary triangle"});
  fiberfem::testing::expect_invalid([&] { core::cavity_surface(m, {-1}); }, {"out of range"});
}
