// Simulator::checkpoint / restore: a run restored from a checkpoint continues bit-for-bit
// like the uninterrupted run (compared with ==), for the contracting default heart and
// for the palm tree under a drag, both with PCG and the lagged Cholesky preconditioner.
// The shipped scenes are read through io (the core itself reads no files).

#include "core/amg_preconditioner.hpp"
#include "core/box_generator.hpp"
#include "core/rotation.hpp"
#include "core/simulator.hpp"
#include "io/scene.hpp"
#include "step_trace.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <functional>

namespace fiberfem {
namespace {

using testing::expect_invalid;

using Trace = testing::StepTrace;

void run(core::Simulator& sim, int steps, Trace& t) { testing::record_steps(sim, steps, t); }

// `tweak` changes the scene's engine settings before both runs; `refreshes` asks that the
// continuation refactorise at least once (the restored refresh count then matters).
void expect_resume_is_exact(const std::string& scene_file, int before, int after,
                            const std::function<void(core::SimulatorSettings&)>& tweak = {}, bool refreshes = false) {
  io::Scene scene = io::load_scene(std::string(FIBERFEM_SOURCE_DIR) + "/configs/scenes/" + scene_file);
  if (tweak) tweak(scene.settings);
  ASSERT_EQ(scene.settings.solver.method, core::LinearSolverKind::pcg);
  ASSERT_NE(scene.settings.solver.preconditioner, core::PreconditionerKind::block_jacobi) << "a lagged preconditioner";
  core::Simulator whole(scene.model, scene.settings);
  Trace head, tail;
  run(whole, before, head);
  const core::SimulatorCheckpoint c = whole.checkpoint();
  EXPECT_EQ(c.step_count, before);
  EXPECT_FALSE(c.solver.factors.empty()) << "the checkpoint should carry a lagged factor";
  bool restored_factor_used = false;  // else the continuation would rebuild it at once
  for (const auto& f : c.solver.factors) restored_factor_used = restored_factor_used || (f.factored && !f.stale);
  EXPECT_TRUE(restored_factor_used) << "every factor in the checkpoint is stale: the test would not see a restored one";
  run(whole, after, tail);
  if (refreshes) {
    int n = 0;
    for (int f : tail.factorizations) n += f;
    EXPECT_GT(n, 0) << "no refactorisation after the checkpoint: the test would not see the refresh state";
  }

  core::Simulator resumed(scene.model, scene.settings);  // fresh: no history, no factor
  resumed.restore(c);
  EXPECT_EQ(resumed.time_s(), c.time_s);
  EXPECT_EQ(resumed.step_count(), before);
  Trace again;
  run(resumed, after, again);
  ASSERT_EQ(again.x.size(), tail.x.size());
  for (size_t i = 0; i < tail.x.size(); ++i) {
    EXPECT_TRUE(again.x[i] == tail.x[i]) << "positions differ at step " << before + i + 1 << " by "
                                         << (again.x[i] - tail.x[i]).cwiseAbs().maxCoeff();
    EXPECT_TRUE(again.v[i] == tail.v[i]) << "velocities differ at step " << before + i + 1;
    EXPECT_EQ(again.iterations[i], tail.iterations[i]) << "step " << before + i + 1;
    EXPECT_EQ(again.factorizations[i], tail.factorizations[i]) << "step " << before + i + 1;
    EXPECT_EQ(again.times[i], tail.times[i]);
  }
  if (scene.model.contraction.enabled()) {
    EXPECT_TRUE(resumed.active_tension() == whole.active_tension());
  }

  // A restart without the solver state (positions and velocities only) is NOT exact:
  // the test would catch a restore that forgot the solver's memory.
  core::Simulator plain(scene.model, scene.settings);
  core::SimulatorCheckpoint bare = c;
  bare.solver = core::Simulator(scene.model, scene.settings).checkpoint().solver;
  plain.restore(bare);
  Trace differs;
  run(plain, after, differs);
  bool all_equal = true;
  for (size_t i = 0; i < tail.x.size(); ++i) all_equal = all_equal && differs.x[i] == tail.x[i];
  EXPECT_FALSE(all_equal) << "dropping the solver state changed nothing: the test has no teeth";
}

TEST(SimulatorCheckpoint, ContractingHeartResumesBitForBit) { expect_resume_is_exact("heart.yaml", 17, 15); }

// With the budget refresh rule (the interactive preset's, a smaller budget so that the
// window sees refreshes): the factor's baseline and excess iterations are part of the
// checkpoint, so the resumed run refactorises at the same steps.
TEST(SimulatorCheckpoint, BudgetRefreshResumesBitForBit) {
  expect_resume_is_exact(
      "heart.yaml", 17, 15,
      [](core::SimulatorSettings& s) {
        s.solver.refresh_iterations = 32;
        s.solver.refresh_budget = 0.05;
      },
      true);
}

// The amg preconditioner's hierarchy is rebuilt on restore from the matrix and the
// positions it was set up at (both in the checkpoint), so the resumed run takes the same
// iterations and refreshes at the same steps (refresh_iterations 5, checkpoint after step
// 45, in the quiet diastole, before the beat's onset makes the next hierarchy: the
// checkpoint holds a hierarchy in use and the window sees refreshes, both asserted; a restore that perturbs the setup positions fails it).
TEST(SimulatorCheckpoint, AmgResumesBitForBit) {
  if (!core::has_amg()) GTEST_SKIP() << "built without AMGCL";
  expect_resume_is_exact(
      "heart.yaml", 45, 10,
      [](core::SimulatorSettings& s) {
        s.solver.preconditioner = core::PreconditionerKind::amg;
        s.solver.refresh_iterations = 5;
      },
      true);
}

// A soft body (a 3 m beam under gravity, its mass dominating each step's matrix) solves
// with block Jacobi first (solver.jacobi_first, the default) and makes no factor; a
// checkpoint taken then carries that state and the count towards the switch, and the
// resumed run takes the same iterations to the bit. Restored as if the run had switched
// (the state's flag false), it factorises at once: the flag is what keeps it on block Jacobi.
TEST(SimulatorCheckpoint, ACheckpointTakenOnBlockJacobiFirstResumesBitForBit) {
  core::CantileverSpec spec;
  spec.box.cells = {20, 4, 4};
  spec.box.size_m = {3.0, 0.3, 0.3};
  const core::Model model = core::make_cantilever(spec);
  core::SimulatorSettings settings;
  settings.threads = 1;
  core::Simulator whole(model, settings);
  Trace head, tail;
  run(whole, 6, head);
  const core::SimulatorCheckpoint c = whole.checkpoint();
  ASSERT_TRUE(c.solver.jacobi_first) << "the beam should still be on block Jacobi";
  EXPECT_GT(c.solver.jacobi_first_excess, 0) << "the first solves' extra iterations are part of the state";
  for (int f : head.factorizations) EXPECT_EQ(f, 0);
  run(whole, 8, tail);
  core::Simulator resumed(model, settings);
  resumed.restore(c);
  Trace again;
  run(resumed, 8, again);
  for (size_t i = 0; i < tail.x.size(); ++i) {
    EXPECT_TRUE(again.x[i] == tail.x[i]) << "step " << 7 + i;
    EXPECT_EQ(again.iterations[i], tail.iterations[i]) << "step " << 7 + i;
    EXPECT_EQ(again.factorizations[i], 0) << "step " << 7 + i;
  }
  core::SimulatorCheckpoint switched = c;
  switched.solver.jacobi_first = false;
  core::Simulator factored(model, settings);
  factored.restore(switched);
  EXPECT_EQ(factored.step().solver_factorizations, 1);
}

TEST(SimulatorCheckpoint, PalmUnderDragResumesBitForBit) { expect_resume_is_exact("palm-drag.yaml", 23, 20); }

TEST(SimulatorCheckpoint, RestoreInPlaceRewindsTheSameSimulator) {
  const io::Scene scene = io::load_scene(std::string(FIBERFEM_SOURCE_DIR) + "/configs/scenes/palm-drag.yaml");
  core::Simulator sim(scene.model, scene.settings);
  Trace a, b, c;
  run(sim, 5, a);
  const core::SimulatorCheckpoint cp = sim.checkpoint();
  run(sim, 8, b);
  sim.restore(cp);  // the service's in-memory checkpoint/restore commands
  run(sim, 8, c);
  for (size_t i = 0; i < b.x.size(); ++i) EXPECT_TRUE(b.x[i] == c.x[i]) << "step " << i;
}

TEST(SimulatorCheckpoint, MismatchedCheckpointsAreRefusedByName) {
  const io::Scene palm = io::load_scene(std::string(FIBERFEM_SOURCE_DIR) + "/configs/scenes/palm-drag.yaml");
  core::Simulator sim(palm.model, palm.settings);
  sim.step();
  const core::SimulatorCheckpoint good = sim.checkpoint();
  core::Simulator target(palm.model, palm.settings);
  const Eigen::VectorXd x_before = Eigen::Map<const Eigen::VectorXd>(target.positions().data(), target.positions().size());

  core::SimulatorCheckpoint c = good;
  c.num_nodes += 1;
  expect_invalid([&] { target.restore(c); }, {"restore", "nodes"});
  c = good;
  c.dt_s *= 2;
  expect_invalid([&] { target.restore(c); }, {"restore", "time step"});
  c = good;
  c.x(4) = std::nan("");
  expect_invalid([&] { target.restore(c); }, {"non-finite"});
  c = good;
  c.q.pop_back();
  expect_invalid([&] { target.restore(c); }, {"rotations"});
  c = good;
  c.solver.solver_name = "cholmod";
  expect_invalid([&] { target.restore(c); }, {"solver", "cholmod"});
  c = good;
  ASSERT_FALSE(c.solver.factors.empty());
  c.solver.factors[0].matrix_values.conservativeResize(3);
  expect_invalid([&] { target.restore(c); }, {"factor"});
  // Refused restores leave the target untouched.
  EXPECT_TRUE(Eigen::Map<const Eigen::VectorXd>(target.positions().data(), target.positions().size()) == x_before);
  EXPECT_EQ(target.step_count(), 0);
}

// An amg checkpoint whose hierarchy lacks its setup positions is refused before the
// solver changes: the target then steps exactly as an untouched twin (a restore that
// replaced the recycled solutions or the hierarchy before refusing would not).
TEST(SimulatorCheckpoint, AmgCheckpointWithoutSetupPositionsIsRefusedUntouched) {
  if (!core::has_amg()) GTEST_SKIP() << "built without AMGCL";
  io::Scene scene = io::load_scene(std::string(FIBERFEM_SOURCE_DIR) + "/configs/scenes/heart.yaml");
  scene.settings.solver.preconditioner = core::PreconditionerKind::amg;
  core::Simulator source(scene.model, scene.settings);
  Trace ignored;
  run(source, 6, ignored);
  core::SimulatorCheckpoint c = source.checkpoint();
  bool any = false;
  for (auto& f : c.solver.factors)
    if (f.factored) {
      ASSERT_EQ(f.setup_positions.size(), 3 * static_cast<Eigen::Index>(f.at_factor.size()));
      f.setup_positions.conservativeResize(3);
      any = true;
    }
  ASSERT_TRUE(any) << "no hierarchy in the checkpoint";
  core::Simulator target(scene.model, scene.settings), twin(scene.model, scene.settings);
  Trace t0, w0;
  run(target, 3, t0);
  run(twin, 3, w0);
  expect_invalid([&] { target.restore(c); }, {"amg", "setup positions"});
  Trace t, w;
  run(target, 4, t);
  run(twin, 4, w);
  for (size_t i = 0; i < w.x.size(); ++i) EXPECT_TRUE(t.x[i] == w.x[i]) << "step " << i;
}

// Checkpoints hold free-DOF data in the mesh's node order whatever numbering the engine
// uses inside (SimulatorSettings::dof_order): on the default heart (gmsh's numbering,
// renumbered by the engine) a run in each numbering saves the same checkpoint up to the
// solver's tolerance, and a checkpoint of either continues in the other as its own run
// does. A checkpoint saved in the engine's numbering would differ by whole entries (the
// vectors permuted), far beyond the tolerance.
TEST(SimulatorCheckpoint, CheckpointsDoNotDependOnTheEnginesDofNumbering) {
  for (core::PreconditionerKind pre : {core::PreconditionerKind::cholesky, core::PreconditionerKind::amg}) {
    if (pre == core::PreconditionerKind::amg && !core::has_amg()) continue;
    io::Scene scene = io::load_scene(std::string(FIBERFEM_SOURCE_DIR) + "/configs/scenes/heart.yaml");
    scene.settings.solver.preconditioner = pre;
    scene.settings.solver.tolerance = 1e-10;
    core::SimulatorSettings by_nodes = scene.settings, by_bandwidth = scene.settings;
    by_nodes.dof_order = core::DofOrder::nodes;
    by_bandwidth.dof_order = core::DofOrder::bandwidth;
    core::Simulator a(scene.model, by_nodes), b(scene.model, by_bandwidth);
    ASSERT_EQ(a.system().dof_order(), core::DofOrder::nodes);
    ASSERT_EQ(b.system().dof_order(), core::DofOrder::bandwidth) << "the heart's numbering should be replaced";
    Trace ta, tb;
    run(a, 12, ta);
    run(b, 12, tb);
    const core::SimulatorCheckpoint ca = a.checkpoint(), cb = b.checkpoint();
    const auto close = [](const Eigen::VectorXd& p, const Eigen::VectorXd& q, const char* what) {
      ASSERT_EQ(p.size(), q.size()) << what;
      EXPECT_LE((p - q).norm(), 1e-6 * p.norm()) << what;
    };
    close(ca.vfree, cb.vfree, "vfree");
    close(ca.vfree_prev, cb.vfree_prev, "vfree_prev");
    ASSERT_EQ(ca.block_R.size(), cb.block_R.size());
    for (size_t k = 0; k < ca.block_R.size(); ++k) EXPECT_LE((ca.block_R[k] - cb.block_R[k]).norm(), 1e-6) << "block " << k;
    ASSERT_EQ(ca.solver.history_rows, cb.solver.history_rows);
    ASSERT_EQ(ca.solver.history_count, cb.solver.history_count);
    close(ca.solver.history, cb.solver.history, "recycled solutions");
    ASSERT_EQ(ca.solver.factors.size(), cb.solver.factors.size());
    for (size_t k = 0; k < ca.solver.factors.size(); ++k) {
      const auto &fa = ca.solver.factors[k], &fb = cb.solver.factors[k];
      ASSERT_EQ(fa.factored, fb.factored);
      if (!fa.factored) continue;
      close(fa.matrix_values, fb.matrix_values, "factorised matrix");
      for (size_t j = 0; j < fa.at_factor.size(); ++j) EXPECT_LE((fa.at_factor[j] - fb.at_factor[j]).norm(), 1e-6);
      close(fa.setup_positions, fb.setup_positions, "amg setup positions");
    }
    // Crossed restores continue as the saving run does.
    Trace ra, rb;
    run(a, 6, ra);
    run(b, 6, rb);
    core::Simulator a_from_b(scene.model, by_nodes), b_from_a(scene.model, by_bandwidth);
    a_from_b.restore(cb);
    b_from_a.restore(ca);
    Trace xa, xb;
    run(a_from_b, 6, xa);
    run(b_from_a, 6, xb);
    const core::Positions& rest = scene.model.mesh.rest_positions();
    const Eigen::Map<const Eigen::VectorXd> x0(rest.data(), rest.size());
    for (size_t i = 0; i < ra.x.size(); ++i) {
      const double scale = (ra.x[i] - x0).norm();
      EXPECT_LE((xb.x[i] - ra.x[i]).norm(), 1e-6 * scale) << "step " << i << (pre == core::PreconditionerKind::amg ? " amg" : " cholesky");
      EXPECT_LE((xa.x[i] - rb.x[i]).norm(), 1e-6 * scale) << "step " << i;
      // (amg aggregates nodes in their numbering's order: another hierarchy, other counts.)
      if (pre == core::PreconditionerKind::cholesky) {
        EXPECT_LE(std::abs(xb.iterations[i] - ra.iterations[i]), 1) << "step " << i;
      }
    }
  }
}

// The engine keeps each element's rotation by its position in the element loop, which on a
// mesh generator's element order (the heart's) differs from the element numbering; a
// checkpoint keeps them by element: rotation e is the polar factor of element e's
// deformation gradient at the checkpoint's positions (the energy check computed them
// there), and a restored run continues bit for bit (expect_resume_is_exact, above).
TEST(SimulatorCheckpoint, CheckpointsKeepTheRotationsByElement) {
  io::Scene scene = io::load_scene(std::string(FIBERFEM_SOURCE_DIR) + "/configs/scenes/heart.yaml");
  core::Simulator sim(scene.model, scene.settings);
  const std::vector<int>& order = sim.system().element_order();
  int moved = 0;
  for (size_t k = 0; k < order.size(); ++k) moved += order[k] != static_cast<int>(k);
  ASSERT_GT(moved, static_cast<int>(order.size()) / 2) << "the loop follows the element numbering: the test has no teeth";
  Trace t;
  run(sim, 12, t);
  const core::SimulatorCheckpoint c = sim.checkpoint();
  ASSERT_TRUE(c.rotations_current) << "the rotations should belong to the checkpoint's positions";
  const core::TetMesh& mesh = scene.model.mesh;
  double worst = 0, largest_angle = 0;
  for (int e = 0; e < mesh.num_elements(); ++e) {
    const core::Tet& tet = mesh.tets()[static_cast<size_t>(e)];
    core::Mat3 Dm, Ds;
    for (int j = 0; j < 3; ++j) {
      Dm.col(j) = mesh.rest_positions().col(tet[j + 1]) - mesh.rest_positions().col(tet[0]);
      Ds.col(j) = c.x.segment<3>(3 * tet[j + 1]) - c.x.segment<3>(3 * tet[0]);
    }
    const core::Mat3 R = core::rotation_svd(Ds * Dm.inverse());
    worst = std::max(worst, (c.R[static_cast<size_t>(e)] - R).cwiseAbs().maxCoeff());
    largest_angle = std::max(largest_angle, std::acos(std::clamp((R.trace() - 1) / 2, -1.0, 1.0)));
  }
  EXPECT_GT(largest_angle, 1e-3) << "the heart should have turned its elements";
  EXPECT_LT(worst, 1e-5) << "a checkpoint's rotation is not its element's";
}

}  // namespace
}  // namespace fiberfem
