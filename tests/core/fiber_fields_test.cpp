// Fiber fields (core/fiber_fields.hpp, PHYSICS.md section 7): the Laplace coordinate
// against an exact harmonic function, the helix rule on the benchmark ellipsoid against
// the analytic field of Land et al. 2015 problem 3 (REFERENCES.md) at every element, the
// sign convention pinned at one point, sign-blind interpolation (a uniform field stays
// uniform; surface samples of the analytic field reproduce it through the wall), and bad
// input.

#include "core/box_generator.hpp"
#include "core/fiber_fields.hpp"
#include "core/lv_ellipsoid.hpp"
#include "test_support.hpp"

#include <cmath>
#include <random>

namespace core = fiberfem::core;
using core::Vec3;
using fiberfem::testing::expect_invalid;

namespace {

constexpr double kPi = 3.14159265358979323846;

Vec3 centroid(const core::TetMesh& m, int e) {
  Vec3 c = Vec3::Zero();
  for (int n : m.tets()[static_cast<size_t>(e)]) c += 0.25 * m.rest_positions().col(n);
  return c;
}

// The analytic field of Land problem 3 at a point of the wall of the ellipsoid `s`: the
// point's own transmural parameter t (radii interpolated linearly, found by bisection),
// its (u, v), a = 90 - 180 t degrees, f = sin(a) e_u + cos(a) e_v.
struct Analytic {
  double t;
  Vec3 fiber, e_u, e_v;
};
Analytic land_field(const core::LvEllipsoidSpec& s, const Vec3& p, double endo_deg = 90, double epi_deg = -90,
                    double t_override = -1) {
  auto level = [&](double t) {
    const double rs = s.endo_rs_m + t * (s.epi_rs_m - s.endo_rs_m), rl = s.endo_rl_m + t * (s.epi_rl_m - s.endo_rl_m);
    return (p.x() * p.x() + p.y() * p.y()) / (rs * rs) + p.z() * p.z() / (rl * rl) - 1.0;
  };
  double lo = -0.5, hi = 1.5;  // level decreases with t
  for (int i = 0; i < 100; ++i) {
    const double mid = 0.5 * (lo + hi);
    (level(mid) > 0 ? lo : hi) = mid;
  }
  const double t_geo = 0.5 * (lo + hi);
  const double t = t_override >= 0 ? t_override : t_geo;
  const double rs = s.endo_rs_m + t * (s.epi_rs_m - s.endo_rs_m), rl = s.endo_rl_m + t * (s.epi_rl_m - s.endo_rl_m);
  const double v = std::atan2(p.y(), p.x());
  const double u = std::acos(std::clamp(p.z() / rl, -1.0, 1.0));
  const Vec3 e_u = Vec3(rs * std::cos(u) * std::cos(v), rs * std::cos(u) * std::sin(v), -rl * std::sin(u)).normalized();
  const Vec3 e_v(-std::sin(v), std::cos(v), 0.0);
  const double a = (endo_deg + (epi_deg - endo_deg) * t) * kPi / 180.0;
  return {t_geo, (std::sin(a) * e_u + std::cos(a) * e_v).normalized(), e_u, e_v};
}

constexpr auto lv = fiberfem::testing::lv_spec;

}  // namespace

// A linear function is harmonic and linear elements represent it: t = x / L exactly.
TEST(LaplaceCoordinate, IsExactForALinearField) {
  core::BoxSpec b;
  b.size_m = Vec3(0.03, 0.01, 0.02);
  b.cells = {6, 2, 3};
  const core::TetMesh m = core::make_box(b);
  const Eigen::VectorXd t = core::laplace_coordinate(m, m.node_set("xmin"), m.node_set("xmax"));
  for (int n = 0; n < m.num_nodes(); ++n) EXPECT_NEAR(t(n), m.rest_positions()(0, n) / 0.03, 1e-12);
}

// On the benchmark ellipsoid the rule with endo 90 and epi -90 degrees is Land's field,
// up to the definition of the transmural coordinate: the rule's is harmonic (Laplace, as
// in the rule-based methods of Bayer et al. 2012), Land's the parameter of the linearly
// interpolated radii. They agree on the surfaces and differ inside (for a cylinder
// ln(r/a)/ln(b/a) against (r-a)/(b-a): 0.044 at mid-wall for this wall), and the helix
// turns 180 degrees across the wall, so that difference alone moves the fiber by
// 180 |dt| degrees. The test separates the two:
//  - the frame (e_n from grad t, e_l, e_c) against Land's directions at the rule's own t:
//    measured mean 0.95, max 18 degrees at (48, 20, 4), the worst at the apex, where the
//    longitudinal direction degenerates and the faceted cap tilts grad t;
//  - the whole field against Land's, per element, within the frame error plus 180 |dt|.
TEST(HelixRule, MatchesLandProblem3OnTheBenchmarkEllipsoid) {
  const core::LvEllipsoidSpec spec = lv(48, 20, 4);
  const core::TetMesh m = core::make_lv_ellipsoid(spec);
  const Eigen::VectorXd t = core::laplace_coordinate(m, m.node_set("endo"), m.node_set("epi"));
  core::HelixRule rule;
  rule.endo_angle_deg = 90;
  rule.epi_angle_deg = -90;
  const core::FiberField f = core::helix_rule_fibers(m, t, rule);
  double frame_sum = 0, frame_max = 0, sum = 0, worst = 0;
  for (int e = 0; e < m.num_elements(); ++e) {
    const size_t i = static_cast<size_t>(e);
    const Vec3 c = centroid(m, e);
    const double frame = core::fiber_angle_deg(f.fiber[i], land_field(spec, c, 90, -90, f.transmural[i]).fiber);
    const Analytic a = land_field(spec, c);
    const double err = core::fiber_angle_deg(f.fiber[i], a.fiber);
    frame_sum += frame;
    frame_max = std::max(frame_max, frame);
    sum += err;
    worst = std::max(worst, err);
    EXPECT_LE(err, frame + 180.0 * std::abs(f.transmural[i] - a.t) + 0.5) << "element " << e;
    EXPECT_NEAR(f.fiber[i].norm(), 1.0, 1e-12);
    EXPECT_NEAR(f.sheet[i].dot(f.fiber[i]), 0.0, 1e-12);
  }
  const double ne = m.num_elements();
  std::printf("helix rule vs Land problem 3 at %d tets: frame error mean %.2f max %.2f deg; "
              "whole field (harmonic vs radius-parameter t) mean %.2f max %.2f deg\n",
              m.num_elements(), frame_sum / ne, frame_max, sum / ne, worst);
  RecordProperty("frame_mean_deg", std::to_string(frame_sum / ne));
  RecordProperty("field_mean_deg", std::to_string(sum / ne));
  RecordProperty("field_max_deg", std::to_string(worst));
  EXPECT_LT(frame_sum / ne, 2.0);
  EXPECT_LT(frame_max, 25.0);
}

// The sign convention, pinned at one element: on the +x side near the equator of the
// inner wall, e_c is +y (counter-clockwise seen from the base) and e_l is -z (towards the
// apex), so the default +60 degrees at the endocardium is (0, cos 60, -sin 60), a
// right-handed helix, and not its mirror (0, cos 60, +sin 60).
TEST(HelixRule, SignConventionAtTheEndocardium) {
  const core::LvEllipsoidSpec spec = lv(48, 20, 4);
  const core::TetMesh m = core::make_lv_ellipsoid(spec);
  const Eigen::VectorXd t = core::laplace_coordinate(m, m.node_set("endo"), m.node_set("epi"));
  const core::FiberField f = core::helix_rule_fibers(m, t, core::HelixRule{});
  int best = -1;
  double best_d = 1e300;
  for (int e = 0; e < m.num_elements(); ++e) {
    const double d = (centroid(m, e) - Vec3(spec.endo_rs_m, 0, 0)).norm();
    if (d < best_d) best_d = d, best = e;
  }
  ASSERT_GE(best, 0);
  // The element is a little into the wall: its helix angle is 60 - 120 t.
  const double alpha = (60.0 - 120.0 * f.transmural[static_cast<size_t>(best)]) * kPi / 180.0;
  ASSERT_GT(alpha, 30.0 * kPi / 180.0);
  const Vec3 expected(0, std::cos(alpha), -std::sin(alpha));
  const Vec3 mirror(0, std::cos(alpha), std::sin(alpha));
  const Vec3 got = f.fiber[static_cast<size_t>(best)];
  EXPECT_LT(core::fiber_angle_deg(got, expected), 4.0) << got.transpose();
  EXPECT_GT(core::fiber_angle_deg(got, mirror), 55.0) << got.transpose();
  EXPECT_GT(f.sheet[static_cast<size_t>(best)].x(), 0.95);  // outward
}

TEST(InterpolateDirections, UniformFieldStaysUniformWhateverTheSigns) {
  const core::TetMesh m = core::make_lv_ellipsoid(lv(24, 10, 3));
  const Vec3 d = Vec3(0.3, -0.5, 0.8).normalized();
  std::mt19937 rng(3);
  std::vector<int> nodes;
  std::vector<Vec3> dirs;
  for (int n : m.node_set("endo")) {
    nodes.push_back(n);
    dirs.push_back((rng() % 2 ? 1.0 : -2.5) * d);
  }
  const std::vector<Vec3> f = core::interpolate_directions(m, nodes, dirs);
  ASSERT_EQ(f.size(), static_cast<size_t>(m.num_elements()));
  for (const Vec3& x : f) EXPECT_LT(core::fiber_angle_deg(x, d), 1e-6);
}

// Strokes on the two surfaces only (an analytic helix field sampled at the endocardial and
// epicardial nodes), interpolated through the wall and compared with the field there.
// Sign-blind interpolation (structure tensors) turns from one surface's axis to the other's
// the short way, through their acute bisector. The true helix turns through the
// circumferential direction, which is that bisector only when the two surface axes are
// less than 90 degrees apart:
//  - +40 to -40 (80 degrees apart): the interpolation follows the helix, though not
//    linearly: the principal axis of a blend (1-s) d1 d1^T + s d2 d2^T of axes at +-40
//    degrees turns as tan(2 phi) = (1 - 2s) tan 80, 35 degrees at s = 1/4 where a linear
//    turn is at 20, and the harmonic coordinate is not Land's (above). Measured mean
//    12.4, mid-wall 13.7 degrees at (48, 20, 4); bound 16;
//  - +60 to -60 (the usual range; 120 degrees as vectors, 60 as axes) and Land's +90 to -90
//    (the same axis on both surfaces) turn through the longitudinal direction instead:
//    mid-wall errors near 80 degrees. Such fields need strokes inside the wall too, or the
//    rule. Reported; the Land case is checked to be that degenerate one.
double strokes_error(const core::LvEllipsoidSpec& spec, const core::TetMesh& m, double endo, double epi, double* mid) {
  std::vector<int> nodes;
  std::vector<Vec3> dirs;
  for (const char* set : {"endo", "epi"})
    for (int n : m.node_set(set)) {
      nodes.push_back(n);
      dirs.push_back(land_field(spec, m.rest_positions().col(n), endo, epi).fiber);
    }
  const std::vector<Vec3> f = core::interpolate_directions(m, nodes, dirs);
  double sum = 0, mid_sum = 0;
  int mid_n = 0;
  for (int e = 0; e < m.num_elements(); ++e) {
    const Vec3 c = centroid(m, e);
    const Analytic a = land_field(spec, c, endo, epi);
    const double err = core::fiber_angle_deg(f[static_cast<size_t>(e)], a.fiber);
    sum += err;
    if (std::abs(a.t - 0.5) < 0.1) mid_sum += err, ++mid_n;
  }
  *mid = mid_sum / std::max(1, mid_n);
  return sum / m.num_elements();
}

TEST(InterpolateDirections, SurfaceStrokesThroughTheWall) {
  const core::LvEllipsoidSpec spec = lv(48, 20, 4);
  const core::TetMesh m = core::make_lv_ellipsoid(spec);
  double mid40 = 0, mid60 = 0, mid90 = 0;
  const double mean40 = strokes_error(spec, m, 40, -40, &mid40);
  const double mean60 = strokes_error(spec, m, 60, -60, &mid60);
  const double mean90 = strokes_error(spec, m, 90, -90, &mid90);
  std::printf("surface strokes at %d tets, mean (mid-wall) angle error: +40/-40 %.2f (%.2f), +60/-60 %.2f (%.2f), "
              "Land +90/-90 %.2f (%.2f) deg\n",
              m.num_elements(), mean40, mid40, mean60, mid60, mean90, mid90);
  RecordProperty("helix40_mean_deg", std::to_string(mean40));
  RecordProperty("helix60_mean_deg", std::to_string(mean60));
  RecordProperty("land90_mean_deg", std::to_string(mean90));
  EXPECT_LT(mean40, 16.0);
  EXPECT_LT(mid40, 16.0);
  EXPECT_GT(mid90, 75.0);
}

TEST(FiberFields, BadInputIsRefusedByName) {
  const core::TetMesh m = core::make_lv_ellipsoid(lv(12, 4, 1));
  const auto& endo = m.node_set("endo");
  expect_invalid([&] { core::laplace_coordinate(m, {}, endo); }, {"zero_nodes", "no nodes"});
  expect_invalid([&] { core::laplace_coordinate(m, endo, {m.num_nodes()}); }, {"one_nodes", "out of range"});
  expect_invalid([&] { core::laplace_coordinate(m, endo, {endo[0]}); }, {"in both sets"});
  {  // two separate boxes, held values on one only: the other is undetermined
    core::Positions X(3, 8);
    X << 0, 1, 0, 0, 5, 6, 5, 5, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 1;
    const core::TetMesh two(X, {{0, 1, 2, 3}, {4, 5, 6, 7}});
    expect_invalid([&] { core::laplace_coordinate(two, {0}, {1}); }, {"4 nodes are not connected"});
  }
  core::HelixRule r;
  r.apex_to_base = Vec3::Zero();
  expect_invalid([&] { core::helix_rule_fibers(m, Eigen::VectorXd::Zero(m.num_nodes()), r); }, {"apex_to_base"});
  expect_invalid([&] { core::helix_rule_fibers(m, Eigen::VectorXd::Zero(3), core::HelixRule{}); }, {"3 transmural values"});
  expect_invalid([&] { core::interpolate_directions(m, {0, 1}, {Vec3::UnitX(), Vec3::Zero()}); }, {"direction 1", "node 1"});
  expect_invalid([&] { core::interpolate_directions(m, {0, 0}, {Vec3::UnitX(), Vec3::UnitX()}); }, {"twice"});
}
