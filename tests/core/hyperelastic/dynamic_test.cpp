// Backward-Euler steps of the accurate tier against closed forms: a body in free fall
// follows backward Euler's own recurrence exactly (x_n = x_0 - g h^2 n (n + 1)/2), with a
// penalty or an exactly incompressible law; a heavily damped cantilever settles onto the
// static solution that solve_static finds independently.

#include "core/hyperelastic/dynamic.hpp"

#include "core/box_generator.hpp"

#include <gtest/gtest.h>

namespace fiberfem::core::hyperelastic {
namespace {

Problem box_problem(bool incompressible, bool clamped) {
  BoxSpec spec;
  spec.size_m = Vec3(0.010, 0.002, 0.002);
  spec.cells = {4, 1, 1};
  auto mesh = std::make_shared<const ElementMesh>(make_box(spec), 2);
  Problem p(mesh);
  LawParameters law;
  law.kind = incompressible ? LawKind::guccione : LawKind::neo_hookean;
  law.mu_pa = 5e4;
  law.guccione_c_pa = 5e4;
  law.incompressible = incompressible;
  law.bulk_modulus_pa = incompressible ? 0 : 5e5;
  p.region_laws = {law};
  p.region_density_kg_m3 = {1000};
  p.element_region.assign(static_cast<size_t>(mesh->num_elements()), 0);
  p.gravity_m_s2 = Vec3(0, 0, -9.81);
  if (clamped) {
    p.fixed_dofs.assign(static_cast<size_t>(3 * mesh->num_nodes()), 0);
    for (int n = 0; n < mesh->num_nodes(); ++n)
      if (mesh->rest_positions()(0, n) < 1e-12)
        for (int i = 0; i < 3; ++i) p.fixed_dofs[static_cast<size_t>(3 * n + i)] = 1;
  }
  return p;
}

TEST(DynamicSolver, AFreeBodyFallsAsBackwardEulerPredicts) {
  for (bool incompressible : {false, true}) {
    const Problem problem = box_problem(incompressible, false);
    DynamicSettings settings;
    settings.dt_s = 0.01;
    DynamicSolver solver(problem, settings);
    const int n = 20;
    for (int s = 0; s < n; ++s) ASSERT_TRUE(solver.step(Loading{}).converged) << "step " << s;
    const double expected = -9.81 * settings.dt_s * settings.dt_s * n * (n + 1) / 2;
    const Positions u = solver.positions() - problem.mesh->rest_positions();
    EXPECT_NEAR(u.row(2).minCoeff(), expected, 1e-9 * std::abs(expected)) << "incompressible " << incompressible;
    EXPECT_NEAR(u.row(2).maxCoeff(), expected, 1e-9 * std::abs(expected));
    EXPECT_LT(u.topRows(2).cwiseAbs().maxCoeff(), 1e-9 * std::abs(expected));
    EXPECT_NEAR(solver.time_s(), n * settings.dt_s, 1e-12);
  }
}

TEST(DynamicSolver, AHeavilyDampedCantileverSettlesOnTheStaticSolution) {
  const Problem problem = box_problem(false, true);
  Positions xs;
  Eigen::VectorXd ps;
  NewtonSettings ns;
  ns.load_steps = 1;
  ns.tolerance = 1e-11;
  ASSERT_TRUE(solve_static(problem, xs, ps, ns).converged);
  DynamicSettings settings;
  settings.dt_s = 0.002;
  settings.mass_damping_1_s = 500;  // about twice the first bending frequency, rad/s
  DynamicSolver solver(problem, settings);
  for (int s = 0; s < 150; ++s) ASSERT_TRUE(solver.step(Loading{}).converged) << "step " << s;
  const Positions us = xs - problem.mesh->rest_positions();
  const Positions ud = solver.positions() - problem.mesh->rest_positions();
  const double tip = us.row(2).cwiseAbs().maxCoeff();
  EXPECT_GT(tip, 1e-5);  // it sags visibly
  EXPECT_LT((ud - us).cwiseAbs().maxCoeff(), 1e-4 * tip);
  EXPECT_LT(solver.velocities().cwiseAbs().maxCoeff() * 0.01, 1e-4 * tip);
}

TEST(DynamicSolver, RefusesABodyWithoutMass) {
  Problem problem = box_problem(false, true);
  problem.region_density_kg_m3 = {0.0};
  EXPECT_THROW(DynamicSolver(problem, DynamicSettings{}), std::invalid_argument);
  DynamicSettings bad;
  bad.dt_s = 0;
  EXPECT_THROW(DynamicSolver(box_problem(false, true), bad), std::invalid_argument);
}

}  // namespace
}  // namespace fiberfem::core::hyperelastic
