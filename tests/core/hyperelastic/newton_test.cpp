// Newton's method of the accurate tier against closed forms: the incompressible
// neo-Hookean thick sphere under inner pressure (its pressure-stretch relation and its
// limit point), a cantilever under follower pressure converging quadratically.

#include "core/hyperelastic/newton.hpp"

#include "core/box_generator.hpp"
#include "core/hyperelastic/curved_placement.hpp"
#include "core/lv_ellipsoid.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <set>

namespace fiberfem::core::hyperelastic {
namespace {

constexpr double kInner = 0.010, kOuter = 0.015, kMu = 10e3;

// Closed form (incompressible neo-Hookean sphere, W = mu/2 (I1 - 3)): with lambda = r/R,
// the equilibrium d sigma_rr/dr = 2 (sigma_tt - sigma_rr)/r = 2 mu (lambda^2 - lambda^-4)/r
// and r^3 - R^3 fixed give p = 2 mu [1/l_b + 1/(4 l_b^4) - 1/l_a - 1/(4 l_a^4)], with l_a
// the inner and l_b the outer stretch.
double sphere_pressure(double lambda_a) {
  const double a = lambda_a * kInner;
  const double b = std::cbrt(kOuter * kOuter * kOuter + a * a * a - kInner * kInner * kInner);
  const double lb = b / kOuter;
  auto g = [](double l) { return 1 / l + 0.25 / std::pow(l, 4); };
  return 2 * kMu * (g(lb) - g(lambda_a));
}

// A hemispherical shell (the lv_ellipsoid generator with equal radii and the base at the
// equator): the equator plane is a plane of symmetry (u_z = 0); the nodes on the z axis
// keep x and y, one equator node keeps y (no rigid motion).
struct Sphere {
  Problem problem;
  std::vector<int> endo_nodes;
};

Sphere sphere(int order, double pressure_pa) {
  LvEllipsoidSpec spec;
  spec.endo_rs_m = spec.endo_rl_m = kInner;
  spec.epi_rs_m = spec.epi_rl_m = kOuter;
  spec.base_z_m = 0;
  spec.circumferential = 12;
  spec.longitudinal = 5;
  spec.transmural = 2;
  const TetMesh corners = make_lv_ellipsoid(spec);
  auto mesh = std::make_shared<const ElementMesh>(corners, order, lv_ellipsoid_edge_placement(spec, corners));
  Sphere s{Problem(mesh), {}};
  Problem& p = s.problem;
  LawParameters law;
  law.kind = LawKind::neo_hookean;
  law.mu_pa = kMu;
  law.incompressible = true;
  p.region_laws = {law};
  p.element_region.assign(static_cast<size_t>(mesh->num_elements()), 0);
  const Positions& X = mesh->rest_positions();
  const std::set<int> endo(corners.node_set("endo").begin(), corners.node_set("endo").end());
  PressureLoad load;
  load.pressure_pa = pressure_pa;
  for (size_t f = 0; f < mesh->boundary_faces().size(); ++f) {
    const auto& n = mesh->boundary_faces()[f];
    if (endo.count(n[0]) && endo.count(n[1]) && endo.count(n[2]) && (X.col(n[0]) + X.col(n[1]) + X.col(n[2])).z() < -1e-9)
      load.faces.push_back(static_cast<int>(f));
  }
  p.pressures = {load};
  p.fixed_dofs.assign(static_cast<size_t>(3 * mesh->num_nodes()), 0);
  int equator_node = -1;
  for (int n = 0; n < mesh->num_nodes(); ++n) {
    const Vec3 x = X.col(n);
    if (std::abs(x.z()) < 1e-12) p.fixed_dofs[static_cast<size_t>(3 * n + 2)] = 1;
    if (std::hypot(x.x(), x.y()) < 1e-12) p.fixed_dofs[static_cast<size_t>(3 * n)] = p.fixed_dofs[static_cast<size_t>(3 * n + 1)] = 1;
    if (std::abs(x.z()) < 1e-12 && equator_node < 0) equator_node = n;
    if (std::abs(x.norm() - kInner) < 1e-9 * kInner) s.endo_nodes.push_back(n);
  }
  p.fixed_dofs[static_cast<size_t>(3 * equator_node + 1)] = 1;
  return s;
}

double mean_inner_stretch(const Sphere& s, const Positions& x) {
  double sum = 0;
  for (int n : s.endo_nodes) sum += x.col(n).norm();
  return sum / static_cast<double>(s.endo_nodes.size()) / kInner;
}

TEST(NewtonStatic, TheThickSphereFollowsItsClosedFormPressureStretch) {
  const double lambda = 1.25;
  const double p = sphere_pressure(lambda);
  const Sphere s = sphere(2, p);
  Positions x;
  Eigen::VectorXd pr;
  NewtonSettings settings;
  settings.load_steps = 4;
  const NewtonReport r = solve_static(s.problem, x, pr, settings);
  ASSERT_TRUE(r.converged) << r.message;
  // The inner radius's change within 1% of the closed form's.
  std::printf("sphere: stretch ratio %.5f, %d iterations\n", (mean_inner_stretch(s, x) - 1) / (lambda - 1), r.iterations);
  EXPECT_NEAR((mean_inner_stretch(s, x) - 1) / (lambda - 1), 1.0, 0.01) << "pressure " << p << " Pa";
}

// The increments before the last are solved to solver.newton.increment_tolerance only:
// the answer is the fully converged one's (both to the final tolerance at full load), in
// fewer iterations, and the closed form's.
TEST(NewtonStatic, LooseIncrementsBeforeTheLastGiveTheSameAnswerInFewerIterations) {
  const double lambda = 1.25;
  const Sphere s = sphere(2, sphere_pressure(lambda));
  std::vector<Positions> answers;
  std::vector<int> iterations;
  for (double increment_tolerance : {1e-9, 1e-3}) {
    Positions x;
    Eigen::VectorXd pr;
    NewtonSettings settings;
    settings.load_steps = 4;
    settings.increment_tolerance = increment_tolerance;
    const NewtonReport r = solve_static(s.problem, x, pr, settings);
    ASSERT_TRUE(r.converged) << r.message;
    EXPECT_LE(r.relative_residual, settings.tolerance);
    EXPECT_NEAR((mean_inner_stretch(s, x) - 1) / (lambda - 1), 1.0, 0.01);
    answers.push_back(x);
    iterations.push_back(r.iterations);
  }
  std::printf("sphere: %d iterations with every increment to 1e-9, %d with the first three to 1e-3\n", iterations[0],
              iterations[1]);
  EXPECT_LT(iterations[1], iterations[0]);
  EXPECT_LT((answers[1] - answers[0]).cwiseAbs().maxCoeff(), 1e-9 * kOuter);
}

TEST(NewtonStatic, ALoadBeyondTheLimitPointIsReportedWithTheLoadFactorReached) {
  // The closed form's pressure maximum (thick sphere inflation limit).
  double p_max = 0;
  for (double l = 1.0; l < 4.0; l += 1e-4) p_max = std::max(p_max, sphere_pressure(l));
  const double applied = 1.25 * p_max;
  const Sphere s = sphere(2, applied);
  Positions x;
  Eigen::VectorXd pr;
  NewtonSettings settings;
  settings.load_steps = 4;
  settings.max_cutbacks = 6;
  settings.max_iterations = 8;
  const NewtonReport r = solve_static(s.problem, x, pr, settings);
  EXPECT_FALSE(r.converged);
  EXPECT_NE(r.message.find("cannot be carried"), std::string::npos) << r.message;
  EXPECT_TRUE(x.allFinite());
  std::printf("limit: reached %.4f of p_max, %d iterations, %d cut-backs\n", r.load_factor * applied / p_max, r.iterations, r.cutbacks);
  // Newton stops short of the limit (the tangent turns singular there): within 5% below it.
  EXPECT_GT(r.load_factor * applied, 0.95 * p_max);
  EXPECT_LT(r.load_factor * applied, 1.02 * p_max);
}

// Land et al. 2015 problem 1's set-up on a box of `cells` quadratic cells: 10 x 1 x 1 mm,
// x = 0 held, 4 Pa of follower pressure on z = 0, under `law`.
Problem land_beam(const std::array<int, 3>& cells, const LawParameters& law) {
  BoxSpec spec;
  spec.size_m = Vec3(0.010, 0.001, 0.001);
  spec.cells = cells;
  auto mesh = std::make_shared<const ElementMesh>(make_box(spec), 2);
  Problem p(mesh);
  p.region_laws = {law};
  p.element_region.assign(static_cast<size_t>(mesh->num_elements()), 0);
  PressureLoad load;
  load.pressure_pa = 4.0;
  const Positions& X = mesh->rest_positions();
  for (size_t f = 0; f < mesh->boundary_faces().size(); ++f) {
    const auto& n = mesh->boundary_faces()[f];
    if ((X.col(n[0]) + X.col(n[1]) + X.col(n[2])).z() < 1e-12) load.faces.push_back(static_cast<int>(f));
  }
  p.pressures = {load};
  p.fixed_dofs.assign(static_cast<size_t>(3 * mesh->num_nodes()), 0);
  for (int n = 0; n < mesh->num_nodes(); ++n)
    if (X(0, n) < 1e-12) p.fixed_dofs[static_cast<size_t>(3 * n)] = p.fixed_dofs[static_cast<size_t>(3 * n + 1)] = p.fixed_dofs[static_cast<size_t>(3 * n + 2)] = 1;
  return p;
}

TEST(NewtonStatic, AFollowerPressureCantileverConvergesQuadratically) {
  LawParameters law;
  law.kind = LawKind::guccione;
  law.incompressible = true;
  const Problem p = land_beam({10, 1, 1}, law);
  const ElementMesh* mesh = p.mesh.get();
  const Positions& X = mesh->rest_positions();
  Positions x;
  Eigen::VectorXd pr;
  NewtonSettings settings;
  settings.load_steps = 1;
  settings.tolerance = 1e-12;
  const NewtonReport r = solve_static(p, x, pr, settings);
  ASSERT_TRUE(r.converged) << r.message;
  const std::vector<double>& h = r.residual_history;
  ASSERT_GE(h.size(), 3u);
  // Quadratic convergence: once the residual is small, each iteration squares it (up to a
  // constant): log r_{k+1} / log r_k approaches 2.
  bool quadratic = false;
  for (size_t k = 0; k + 1 < h.size(); ++k)
    if (h[k] < 1e-2 && h[k + 1] > 1e-15 && std::log(h[k + 1]) / std::log(h[k]) > 1.7) quadratic = true;
  EXPECT_TRUE(quadratic) << "residual history: " << ::testing::PrintToString(h);
  // The tip moves up by millimetres (the benchmark's order of magnitude).
  EXPECT_GT(x(2, mesh->num_corner_nodes() - 1) - X(2, mesh->num_corner_nodes() - 1), 1e-3);
}


// A stiff penalty leaves the residual a round-off floor above the tolerance (Land's beam
// with a bulk modulus 500 times the shear modulus stalls at about 1e-9). Newton accepts the
// floor where an exact solve no longer moves the nodes; the looser linear solves of its
// last iterations (NewtonSettings::forcing_floor, the time steps' setting) must not hide
// that floor (they did: 2 cut-backs and 183 iterations here, where 2 increments of about
// 25 iterations each converge).
TEST(NewtonStatic, AStiffPenaltyConvergesAtItsRoundOffFloorWithoutCutBacks) {
  LawParameters law;
  law.kind = LawKind::guccione;
  law.incompressible = false;
  law.bulk_modulus_pa = 1e6;
  const Problem p = land_beam({12, 1, 1}, law);
  Positions x;
  Eigen::VectorXd pr;
  NewtonSettings settings;
  settings.load_steps = 2;
  settings.threads = 1;
  settings.forcing_floor = true;  // the time steps' setting, here where its floor is reached
  const NewtonReport r = solve_static(p, x, pr, settings);
  ASSERT_TRUE(r.converged) << r.message;
  EXPECT_EQ(r.cutbacks, 0);
  EXPECT_LE(r.iterations, 80);
  std::printf("stiff penalty: %d Newton iterations, %d cut-backs, relative residual %.2e\n", r.iterations, r.cutbacks,
              r.relative_residual);
}

// A solve whose residual stays above where it started gives up after give_up_after
// iterations (the time steps then take the step in substeps) instead of spending its whole
// budget; 0 never gives up early; a solve that makes progress is not stopped. Newton is
// made to fail by handing it the tangent's negative, whose directions climb the residual.
TEST(NewtonIterate, GivesUpOnASolveThatMakesNoProgress) {
  BoxSpec spec;
  spec.size_m = Vec3(0.010, 0.002, 0.002);
  spec.cells = {4, 1, 1};
  auto mesh = std::make_shared<const ElementMesh>(make_box(spec), 2);
  Problem p(mesh);
  LawParameters law;
  law.kind = LawKind::neo_hookean;
  law.mu_pa = 5e6;  // stiff: the tip deflects by 0.03% of the length, and Newton from rest
  law.bulk_modulus_pa = 5e7;  // converges without passing through larger residuals
  p.region_laws = {law};
  p.region_density_kg_m3 = {1000};
  p.element_region.assign(static_cast<size_t>(mesh->num_elements()), 0);
  p.gravity_m_s2 = Vec3(0, 0, -9.81);
  p.fixed_dofs.assign(static_cast<size_t>(3 * mesh->num_nodes()), 0);
  for (int n = 0; n < mesh->num_nodes(); ++n)
    if (mesh->rest_positions()(0, n) < 1e-12)
      for (int i = 0; i < 3; ++i) p.fixed_dofs[static_cast<size_t>(3 * n + i)] = 1;
  Assembler assembler(p);
  auto solve = [&](int give_up_after, bool climb) {
    NewtonSettings s;
    s.max_iterations = 12;
    s.give_up_after = give_up_after;
    const ResidualFn residual = [&](const Positions& x, const Eigen::VectorXd& pr, Eigen::VectorXd& R, SparseMatrix* K) {
      const Evaluation ev = assembler.evaluate(x, pr, 1.0, R, K);
      if (K != nullptr && climb) *K *= -1.0;
      return ev;
    };
    TangentSolver linear;
    Positions x = mesh->rest_positions();
    Eigen::VectorXd pr = Eigen::VectorXd::Zero(assembler.num_pressures()), R;
    SparseMatrix K;
    Evaluation ev = residual(x, pr, R, &K);
    NewtonReport rep;
    bool singular = false;
    const bool converged = newton_iterate(assembler, linear, residual, s, x, pr, R, K, ev, rep, singular);
    return std::make_pair(converged, rep);
  };
  const auto [gave_up, early] = solve(4, true);
  EXPECT_FALSE(gave_up);
  EXPECT_EQ(early.iterations, 4);
  EXPECT_NE(early.message.find("no progress"), std::string::npos) << early.message;
  const auto [failed, whole] = solve(0, true);
  EXPECT_FALSE(failed);
  EXPECT_GT(whole.iterations, 4) << whole.message;
  const auto [converged, fine] = solve(1, false);
  EXPECT_TRUE(converged) << fine.message << ::testing::PrintToString(fine.residual_history);
}

}  // namespace
}  // namespace fiberfem::core::hyperelastic
