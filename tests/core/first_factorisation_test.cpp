// The first Cholesky factor made beside the steps (SolverSettings::first_factorisation
// beside): the steps solve with block Jacobi meanwhile, the factor takes over at the step
// the iteration count names (never the clock), so runs on any thread count, runs whose
// factorisation finishes early or late, and a run restored from a checkpoint taken while
// the factor was being made all step bit for bit alike; and the result is the waited-for
// factor's within the solver tolerance. With block Jacobi first (the default) the factor
// is held past its turn where block Jacobi has stayed cheap.

#include "core/builtin_scenes.hpp"
#include "core/simulator.hpp"
#include "io/scene.hpp"
#include "step_trace.hpp"

#include <gtest/gtest.h>

#include <limits>
#include <numeric>

namespace fiberfem {
namespace {

using Trace = testing::StepTrace;

io::Scene heart(core::FirstFactorisation first, int threads) {
  io::Scene scene = io::load_scene(std::string(FIBERFEM_SOURCE_DIR) + "/configs/scenes/heart.yaml");
  scene.settings.solver.first_factorisation = first;
  scene.settings.solver.jacobi_first = 0;  // `wait` factorises at the first solve, as `beside` starts to
  scene.settings.threads = threads;
  return scene;
}

// A box of 49 x 12 x 12 cells (24,000 free DOFs), `length` m long and a quarter of it
// wide: at 10 m block Jacobi converges in about 100 iterations, at 10 cm not in 500.
core::Model box(double length) {
  core::CantileverSpec spec;
  spec.box.cells = {49, 12, 12};
  spec.box.size_m = {length, length / 4, length / 4};
  return core::make_cantilever(spec);
}

Trace steps(const io::Scene& scene, int n) {
  core::Simulator sim(scene.model, scene.settings);
  Trace t;
  testing::record_steps(sim, n, t);
  return t;
}

// The step at which the factor takes over, from the rule: the factorisation starts after
// the run's second solve (the first has every thread to itself), and the factor takes over
// at the first solve after the block-Jacobi solves from that one on have run
// min(1000, rows / 32) iterations.
size_t expected_takeover(const Trace& t, int rows) {
  const double budget = std::min(static_cast<double>(core::kBesideIterations), rows / 32.0);
  double run = 0;
  for (size_t i = 1; i < t.iterations.size(); ++i) {
    if (run >= budget) return i;
    run += t.iterations[i];
  }
  return t.iterations.size();
}

TEST(FirstFactorisation, TheFactorMadeBesideTakesOverAtTheStepItsCountNames) {
  const io::Scene scene = heart(core::FirstFactorisation::beside, 2);
  const int rows = core::Simulator(scene.model, scene.settings).system().num_free();
  const Trace beside = steps(scene, 14);
  const size_t k = expected_takeover(beside, rows);
  ASSERT_GT(k, 1u) << "the block-Jacobi phase should last more than one step";
  ASSERT_LT(k, beside.iterations.size()) << "the factor never took over";
  const Trace wait = steps(heart(core::FirstFactorisation::wait, 2), 14);
  EXPECT_EQ(wait.factorizations[0], 1);
  for (size_t i = 0; i < k; ++i) {
    EXPECT_EQ(beside.factorizations[i], 0) << "step " << i + 1;
    EXPECT_GT(beside.iterations[i], 3 * wait.iterations[i]) << "step " << i + 1 << ": not block Jacobi?";
  }
  EXPECT_EQ(beside.factorizations[k], 1) << "step " << k + 1;
  EXPECT_LE(beside.iterations[k], 2 * wait.iterations[k] + 2) << "step " << k + 1 << ": the factor did not take over";
  // Same trajectory within what the tolerance (1e-6 of each solve) lets through.
  const Eigen::VectorXd& a = beside.x.back();
  const Eigen::VectorXd& b = wait.x.back();
  const Eigen::VectorXd& x0 = core::Simulator(scene.model, scene.settings).positions().reshaped();
  EXPECT_LT((a - b).norm(), 1e-4 * (b - x0).norm());
}

TEST(FirstFactorisation, RunsBesideAreBitForBitOnAnyThreadCountAndFinishTime) {
  const Trace two = steps(heart(core::FirstFactorisation::beside, 2), 10);
  const Trace one = steps(heart(core::FirstFactorisation::beside, 1), 10);
  const Trace again = steps(heart(core::FirstFactorisation::beside, 2), 10);
  for (size_t i = 0; i < two.x.size(); ++i) {
    EXPECT_TRUE(one.x[i] == two.x[i]) << "1 and 2 threads differ at step " << i + 1;
    EXPECT_TRUE(again.x[i] == two.x[i]) << "two runs on 2 threads differ at step " << i + 1;
    EXPECT_EQ(one.factorizations[i], two.factorizations[i]) << "step " << i + 1;
  }
}

TEST(FirstFactorisation, ACheckpointTakenWhileTheFactorIsMadeResumesBitForBit) {
  const io::Scene scene = heart(core::FirstFactorisation::beside, 2);
  core::Simulator whole(scene.model, scene.settings);
  Trace head, tail;
  testing::record_steps(whole, 2, head);  // (the factorisation starts in the second step)
  const core::SimulatorCheckpoint c = whole.checkpoint();
  bool beside = false;
  for (const auto& f : c.solver.factors) beside = beside || f.beside;
  ASSERT_TRUE(beside) << "the checkpoint should hold a factorisation under way";
  testing::record_steps(whole, 10, tail);
  ASSERT_GE(std::accumulate(tail.factorizations.begin(), tail.factorizations.end(), 0), 1) << "the factor should take over after the checkpoint";

  core::Simulator resumed(scene.model, scene.settings);
  resumed.restore(c);
  Trace again;
  testing::record_steps(resumed, 10, again);
  for (size_t i = 0; i < tail.x.size(); ++i) {
    EXPECT_TRUE(again.x[i] == tail.x[i]) << "positions differ at step " << i + 3;
    EXPECT_EQ(again.iterations[i], tail.iterations[i]) << "step " << i + 3;
    EXPECT_EQ(again.factorizations[i], tail.factorizations[i]) << "step " << i + 3;
  }
}

// Automatic: beside from kBesideMinRows free DOFs, on any thread count (the same bits on
// one and two threads); the heart is below the threshold and so waits, like `wait`.
TEST(FirstFactorisation, AutomaticIsBesideFromTheThresholdOnAnyThreadCount) {
  const io::Scene scene = heart(core::FirstFactorisation::automatic, 2);
  ASSERT_LT(core::Simulator(scene.model, scene.settings).system().num_free(), core::kBesideMinRows);
  const Trace automatic = steps(scene, 3);
  const Trace wait = steps(heart(core::FirstFactorisation::wait, 2), 3);
  EXPECT_EQ(automatic.factorizations[0], 1);
  EXPECT_TRUE(automatic.x.back() == wait.x.back());

  // A soft box of 24,000 free DOFs: beside on one and on two threads, the same bits.
  core::SimulatorSettings settings;
  settings.threads = 2;
  const core::Model soft = box(10.0);
  core::Simulator two(soft, settings);
  ASSERT_GE(two.system().num_free(), core::kBesideMinRows);
  EXPECT_EQ(two.step().solver_factorizations, 0) << "two threads: the first step should not wait for a factorisation";
  settings.threads = 1;
  core::Simulator one(soft, settings);
  EXPECT_EQ(one.step().solver_factorizations, 0) << "one thread: the first step should not wait for a factorisation";
  EXPECT_TRUE(one.positions() == two.positions());
}

// A stiff small box where block Jacobi cannot reach the tolerance in max_iterations: the
// factor takes over in that step, from the same guess, and the step is the waited-for one's.
TEST(FirstFactorisation, WhereBlockJacobiFallsShortTheFactorTakesOverAtOnce) {
  core::SimulatorSettings settings;
  settings.threads = 2;
  settings.solver.first_factorisation = core::FirstFactorisation::beside;
  settings.solver.max_iterations = 100;
  settings.solver.jacobi_first = 0;  // `wait` factorises at the first solve
  const core::Model stiff = box(0.1);
  core::Simulator beside(stiff, settings);
  const core::StepReport r = beside.step();
  EXPECT_EQ(r.solver_factorizations, 1);
  EXPECT_GT(r.solver_iterations, settings.solver.max_iterations) << "block Jacobi should have fallen short first";
  settings.solver.first_factorisation = core::FirstFactorisation::wait;
  core::Simulator wait(stiff, settings);
  EXPECT_LT(wait.step().solver_iterations, 10);
  const Eigen::VectorXd a = beside.positions().reshaped(), b = wait.positions().reshaped();
  const Eigen::VectorXd x0 = stiff.mesh.rest_positions().reshaped();
  EXPECT_LT((a - b).norm(), 1e-5 * (b - x0).norm());
}

// Block Jacobi first (SolverSettings::jacobi_first, the default) with the first factor made
// beside the steps: the solves run block Jacobi until the factor's turn as without it;
// where they stayed within the allowance (a 2 m box: 20 to 44 iterations a step against
// a break-even of 29), block Jacobi goes on past the turn and the factor is never used;
// where they did not (a 1 m box: 45 to 94), the factor takes over at its turn, as it does
// with jacobi_first off. The energy check is off: its substeps are matrix families of
// their own, each with its own first factor.
core::SimulatorSettings box_settings(int jacobi_first) {
  core::SimulatorSettings settings;
  settings.threads = 2;
  settings.max_energy_gain = std::numeric_limits<double>::infinity();
  settings.solver.first_factorisation = core::FirstFactorisation::beside;
  settings.solver.jacobi_first = jacobi_first;
  return settings;
}

Trace box_steps(double length, int jacobi_first, int n) {
  core::Simulator sim(box(length), box_settings(jacobi_first));
  Trace t;
  testing::record_steps(sim, n, t);
  return t;
}

// n steps of the box with block Jacobi first and with it off, the box's free DOFs, and the
// step at which the factor takes over with it off.
struct JacobiFirstRuns {
  Trace first, off;
  int rows = 0;
  size_t k = 0;
};
JacobiFirstRuns jacobi_first_runs(double length, int n) {
  JacobiFirstRuns r;
  r.first = box_steps(length, core::kJacobiFirstAuto, n);
  r.off = box_steps(length, 0, n);
  r.rows = core::Simulator(box(length), box_settings(0)).system().num_free();
  r.k = expected_takeover(r.off, r.rows);
  return r;
}

TEST(FirstFactorisation, WithBlockJacobiFirstTheFactorIsHeldWhereBlockJacobiStaysCheap) {
  const int n = 45;
  const auto [first, off, rows, k] = jacobi_first_runs(2.0, n);
  ASSERT_LT(k + 5, static_cast<size_t>(n)) << "the factor's turn should come within the run";
  EXPECT_EQ(off.factorizations[k], 1) << "with jacobi_first off the factor takes over at its turn, step " << k + 1;
  const double even = core::jacobi_first_iterations(rows);
  for (size_t i = 0; i < first.iterations.size(); ++i) {
    EXPECT_EQ(first.factorizations[i], 0) << "step " << i + 1 << ": block Jacobi should go on";
    EXPECT_LE(first.iterations[i], 2 * even) << "step " << i + 1;
    if (i > k) {
      EXPECT_GT(first.iterations[i], 3 * off.iterations[i]) << "step " << i + 1 << ": not block Jacobi?";
    }
  }
  // Both within what the tolerance (1e-6 of each solve) lets through.
  const Eigen::VectorXd x0 = box(2.0).mesh.rest_positions().reshaped();
  EXPECT_LT((first.x.back() - off.x.back()).norm(), 1e-4 * (off.x.back() - x0).norm());
}

TEST(FirstFactorisation, WithBlockJacobiFirstAnExpensiveBlockJacobiGivesWayAtTheFactorsTurn) {
  const int n = 20;
  const auto [first, off, rows, k] = jacobi_first_runs(1.0, n);
  ASSERT_LT(k, static_cast<size_t>(n)) << "the factor's turn should come within the run";
  for (size_t i = 0; i < first.iterations.size(); ++i) {
    EXPECT_EQ(first.factorizations[i], off.factorizations[i]) << "step " << i + 1;
    EXPECT_EQ(first.factorizations[i], i == k ? 1 : 0) << "step " << i + 1;
  }
  const Eigen::VectorXd x0 = box(1.0).mesh.rest_positions().reshaped();
  EXPECT_LT((first.x.back() - off.x.back()).norm(), 1e-5 * (off.x.back() - x0).norm());
}

// A checkpoint taken past the factor's turn while block Jacobi goes on (the factor held)
// resumes bit for bit, still on block Jacobi.
TEST(FirstFactorisation, ACheckpointWithTheFactorHeldResumesBitForBit) {
  const core::Model model = box(2.0);
  const core::SimulatorSettings settings = box_settings(core::kJacobiFirstAuto);
  core::Simulator whole(model, settings);
  Trace head, tail;
  testing::record_steps(whole, 40, head);
  const core::SimulatorCheckpoint c = whole.checkpoint();
  ASSERT_TRUE(c.solver.jacobi_first) << "block Jacobi should still run";
  bool held = false;
  for (const auto& f : c.solver.factors) held = held || (f.beside && f.beside_left <= 0);
  ASSERT_TRUE(held) << "the checkpoint should hold the factor whose turn has come";
  testing::record_steps(whole, 5, tail);
  core::Simulator resumed(model, settings);
  resumed.restore(c);
  Trace again;
  testing::record_steps(resumed, 5, again);
  for (size_t i = 0; i < tail.x.size(); ++i) {
    EXPECT_TRUE(again.x[i] == tail.x[i]) << "positions differ at step " << i + 41;
    EXPECT_EQ(again.iterations[i], tail.iterations[i]) << "step " << i + 41;
    EXPECT_EQ(again.factorizations[i], 0) << "step " << i + 41;
  }
}

}  // namespace
}  // namespace fiberfem
