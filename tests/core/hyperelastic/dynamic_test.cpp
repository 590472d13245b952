// Backward-Euler steps of the accurate tier against closed forms: a body in free fall
// follows backward Euler's own recurrence exactly (x_n = x_0 - g h^2 n (n + 1)/2), with a
// penalty or an exactly incompressible law; a heavily damped cantilever settles onto the
// static solution that solve_static finds independently, with the strain energy
// Clapeyron's theorem gives.

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

// Substeps (a step that failed whole is retried so): n substeps of dt/n are backward Euler
// at dt/n, and count as one step.
TEST(DynamicSolver, SubstepsAreBackwardEulerAtTheSubstepAndCountAsOneStep) {
  const Problem problem = box_problem(false, false);
  DynamicSettings settings;
  settings.dt_s = 0.02;
  DynamicSolver solver(problem, settings);
  const int steps = 5, n = 4;
  for (int s = 0; s < steps; ++s) {
    solver.set_substeps(n);
    for (int i = 0; i < n; ++i) {
      ASSERT_TRUE(solver.step(Loading{}).converged);
      if (i == 1) {
        EXPECT_THROW(solver.set_substeps(1), std::invalid_argument);  // only between steps
      }
    }
    EXPECT_EQ(solver.steps(), s + 1);
    solver.set_substeps(1);
  }
  const double h = settings.dt_s / n;
  const int k = steps * n;
  const double expected = -9.81 * h * h * k * (k + 1) / 2;
  const Positions u = solver.positions() - problem.mesh->rest_positions();
  EXPECT_NEAR(u.row(2).minCoeff(), expected, 1e-9 * std::abs(expected));
  EXPECT_NEAR(solver.time_s(), steps * settings.dt_s, 1e-12);
  EXPECT_THROW(solver.set_substeps(0), std::invalid_argument);
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

  // Its stored energy against Clapeyron's theorem (small strain: half the work of the
  // weight on the settled displacement, f . u with f the consistent body force; measured
  // 4e-4 apart, the strain of a sag of 1e-3 of the length).
  const Assembler assembler(problem);
  Eigen::VectorXd R, p0 = Eigen::VectorXd::Zero(assembler.num_pressures());
  const Evaluation at_rest = assembler.evaluate(problem.mesh->rest_positions(), p0, Loading{}, R, nullptr);
  Positions f = Positions::Zero(3, assembler.num_nodes());
  assembler.add_increment(R, -1.0, f, p0);  // R = -f at rest
  const double clapeyron = 0.5 * (f.array() * ud.array()).sum();
  EXPECT_GT(clapeyron, 0);
  EXPECT_LT(std::abs(at_rest.energy_j), 1e-9 * clapeyron);  // round-off
  EXPECT_NEAR(solver.elastic_energy_j(), clapeyron, 2e-3 * clapeyron) << "elastic " << solver.elastic_energy_j();
  // A restored state has the same energy, evaluated anew.
  DynamicSolver restored(problem, settings);
  EXPECT_EQ(restored.elastic_energy_j(), 0.0);
  restored.restore(solver.state());
  EXPECT_NEAR(restored.elastic_energy_j(), solver.elastic_energy_j(), 1e-12 * clapeyron);
}

TEST(DynamicSolver, RefusesABodyWithoutMass) {
  Problem problem = box_problem(false, true);
  problem.region_density_kg_m3 = {0.0};
  EXPECT_THROW(DynamicSolver(problem, DynamicSettings{}), std::invalid_argument);
  DynamicSettings bad;
  bad.dt_s = 0;
  EXPECT_THROW(DynamicSolver(box_problem(false, true), bad), std::invalid_argument);
}


// A checkpoint (state with the lagged factor's matrices) restored into a new solver of the
// same problem continues exactly as the run it was taken from: every later position,
// velocity and pressure equal to the last bit, incompressible (pressures) and clamped.
TEST(DynamicSolver, ARestoredStateContinuesBitForBit) {
  const Problem problem = box_problem(true, true);
  DynamicSettings settings;
  settings.dt_s = 0.004;
  DynamicSolver uninterrupted(problem, settings);
  for (int s = 0; s < 5; ++s) ASSERT_TRUE(uninterrupted.step(Loading{}).converged);
  const DynamicState saved = uninterrupted.state();
  ASSERT_GT(saved.linear.factored.nonZeros(), 0);  // a lagged factor is part of it
  for (int s = 0; s < 6; ++s) ASSERT_TRUE(uninterrupted.step(Loading{}).converged);

  DynamicSolver resumed(problem, settings);
  resumed.restore(saved);
  EXPECT_EQ(resumed.steps(), 5);
  for (int s = 0; s < 6; ++s) ASSERT_TRUE(resumed.step(Loading{}).converged);
  EXPECT_EQ((resumed.positions() - uninterrupted.positions()).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ((resumed.velocities() - uninterrupted.velocities()).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ((resumed.pressures() - uninterrupted.pressures()).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ(resumed.time_s(), uninterrupted.time_s());
  // A restore that starts without the lagged factor takes another path (a fresh
  // factorisation at its first solve): the same answer only to Newton's tolerance, which
  // is why the factor is saved.
  DynamicState without = saved;
  without.linear = {};
  DynamicSolver cold(problem, settings);
  cold.restore(without);
  for (int s = 0; s < 6; ++s) ASSERT_TRUE(cold.step(Loading{}).converged);
  const double tip = (uninterrupted.positions() - problem.mesh->rest_positions()).cwiseAbs().maxCoeff();
  EXPECT_LT((cold.positions() - uninterrupted.positions()).cwiseAbs().maxCoeff(), 1e-6 * tip);

  DynamicState wrong = saved;
  wrong.p.conservativeResize(wrong.p.size() + 1);
  EXPECT_THROW(resumed.restore(wrong), std::invalid_argument);
}

// The element loop on 1 and on 2 threads gives the same bits (elements assembled by colour).
TEST(DynamicSolver, StepsDoNotDependOnTheThreadCount) {
  const Problem problem = box_problem(true, true);
  Positions x[2];
  for (int threads : {1, 2}) {
    DynamicSettings settings;
    settings.dt_s = 0.004;
    settings.newton.threads = threads;
    DynamicSolver solver(problem, settings);
    for (int s = 0; s < 4; ++s) ASSERT_TRUE(solver.step(Loading{}).converged);
    x[threads - 1] = solver.positions();
  }
  EXPECT_EQ((x[0] - x[1]).cwiseAbs().maxCoeff(), 0.0);
}

// A nodal force enters the residual as minus itself on the node's free rows (and nowhere
// else), and a damped cantilever held by it comes to rest deflected along it.
TEST(DynamicSolver, ANodalForceIsAnExternalLoad) {
  Problem problem = box_problem(false, true);
  problem.gravity_m_s2 = Vec3::Zero();
  const ElementMesh& mesh = *problem.mesh;
  Positions f = Positions::Zero(3, mesh.num_nodes());
  int tip = 0;
  for (int n = 0; n < mesh.num_corner_nodes(); ++n)
    if (mesh.rest_positions()(0, n) > mesh.rest_positions()(0, tip) - 1e-12) tip = n;
  f(2, tip) = -1e-3;
  // The residual of the rest state is exactly minus the force on the node's free rows.
  Assembler assembler(problem);
  Eigen::VectorXd R0, R1;
  Loading with;
  with.nodal_forces_n = &f;
  assembler.evaluate(mesh.rest_positions(), Eigen::VectorXd::Zero(0), Loading{}, R0, nullptr);
  assembler.evaluate(mesh.rest_positions(), Eigen::VectorXd::Zero(0), with, R1, nullptr);
  EXPECT_NEAR((R1 - R0).sum(), 1e-3, 1e-15);
  EXPECT_NEAR((R1 - R0).cwiseAbs().sum(), 1e-3, 1e-15);
  // Stepped with heavy damping, the body comes to rest pulled down at that node.
  DynamicSettings settings;
  settings.dt_s = 0.002;
  settings.mass_damping_1_s = 500;
  DynamicSolver solver(problem, settings);
  for (int s = 0; s < 150; ++s) ASSERT_TRUE(solver.step(with).converged) << "step " << s;
  EXPECT_LT(solver.positions()(2, tip) - mesh.rest_positions()(2, tip), -1e-6);
  EXPECT_LT(solver.velocities().cwiseAbs().maxCoeff() * 0.01, 1e-8);
}

}  // namespace
}  // namespace fiberfem::core::hyperelastic
