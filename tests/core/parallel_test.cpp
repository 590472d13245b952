// The engine's results do not depend on the thread count (core/parallel.hpp): the same
// run on one thread and on two gives the same bits, so the thread governor may change the
// count between steps and a checkpoint resumes on any count. Compared with ==, for a
// contracting heart (scene file) and for a beam large enough that every threaded pass of
// the step runs (the PCG's vector passes above 20,000 rows, the block products in parts,
// the recycled projection in parts, the split-tree substitution).

#include "core/amg_preconditioner.hpp"
#include "core/blas_threads.hpp"
#include "core/parallel.hpp"
#include "core/simulator.hpp"
#include "io/scene.hpp"
#include "step_trace.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>
#include <omp.h>

#include <sched.h>

#include <array>
#include <random>

namespace fiberfem {
namespace {

using Trace = testing::StepTrace;

void run(core::Simulator& sim, int steps, Trace& t) { testing::record_steps(sim, steps, t); }

void expect_same(const Trace& a, const Trace& b, const char* what) {
  ASSERT_EQ(a.x.size(), b.x.size());
  for (size_t i = 0; i < a.x.size(); ++i) {
    ASSERT_TRUE(a.x[i] == b.x[i]) << what << ": positions differ at step " << i + 1 << " by "
                                  << (a.x[i] - b.x[i]).cwiseAbs().maxCoeff();
    ASSERT_TRUE(a.v[i] == b.v[i]) << what << ": velocities differ at step " << i + 1;
    EXPECT_EQ(a.iterations[i], b.iterations[i]) << what << ": step " << i + 1;
    EXPECT_EQ(a.elastic[i], b.elastic[i]) << what << ": elastic energy at step " << i + 1;
  }
}

TEST(Parallel, FixedSumHasTheSameBitsOnAnyThreadCount) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<double> v(100003);
  for (double& x : v) x = u(rng) * std::pow(10.0, 8 * u(rng));  // magnitudes 1e-8 .. 1e8: rounding matters
  long double exact = 0;
  for (double x : v) exact += x;
  const int n = static_cast<int>(v.size());
  std::vector<double> sums;
  for (int t : {1, 2, 3, 7}) {
    omp_set_num_threads(t);
    sums.push_back(core::fixed_sum(n, true, [&](int i) { return v[static_cast<size_t>(i)]; }));
  }
  for (double s : sums) EXPECT_EQ(s, sums[0]);
  EXPECT_NEAR(sums[0], static_cast<double>(exact), 1e-6 * std::abs(static_cast<double>(exact)) + 1e-3);
  // A plain OpenMP reduction rounds by thread count: the fixed parts are what make the
  // sums above equal (checked only where it shows, to keep the test honest about it).
  double two = 0;
  omp_set_num_threads(2);
#pragma omp parallel for schedule(static) reduction(+ : two)
  for (int i = 0; i < n; ++i) two += v[static_cast<size_t>(i)];
  double one = 0;
  for (int i = 0; i < n; ++i) one += v[static_cast<size_t>(i)];
  EXPECT_NE(one, two) << "these data do not show thread-count rounding";
}

// The other threads of a team are kept off the CPU the loop's caller runs on
// (core/team_affinity.hpp): a team thread sharing the caller's CPU spins there while the
// caller waits for it. Checked from inside a loop: each other thread's allowed CPUs leave
// out the caller's CPU, the caller's own stay untouched, and the process's other CPUs stay
// allowed.
TEST(Parallel, TheOtherThreadsOfALoopAreKeptOffTheCallersCpu) {
  cpu_set_t process;
  ASSERT_EQ(sched_getaffinity(0, sizeof process, &process), 0);
  if (CPU_COUNT(&process) < 2) GTEST_SKIP() << "the process may use one CPU only";
  omp_set_num_threads(2);
  for (int round = 0; round < 3; ++round) {
    const int caller = sched_getcpu();
    std::array<cpu_set_t, 2> seen{};
    std::array<int, 2> seen_on{-1, -1};
    core::parallel_for(2, [&](int) {
      const int t = omp_get_thread_num();
      sched_getaffinity(0, sizeof seen[static_cast<size_t>(t)], &seen[static_cast<size_t>(t)]);
      seen_on[static_cast<size_t>(t)] = sched_getcpu();
    });
    ASSERT_GE(seen_on[1], 0) << "the loop ran on one thread";
    if (sched_getcpu() != caller) continue;  // the caller moved during the loop: nothing to compare
    EXPECT_FALSE(CPU_ISSET(caller, &seen[1])) << "round " << round << ": the other thread may still run on the caller's CPU " << caller;
    EXPECT_NE(seen_on[1], caller);
    EXPECT_EQ(CPU_COUNT(&seen[1]), CPU_COUNT(&process) - 1) << "every other CPU of the process should stay allowed";
    EXPECT_TRUE(CPU_EQUAL(&seen[0], &process)) << "the caller's own CPUs should be left as they were";
  }
}

// One scene, stepped on 1 thread, on 2, and with the governor (threads 0), compared.
void expect_thread_count_invariant(const core::Model& model, core::SimulatorSettings settings, int steps) {
  Trace one, two, governed;
  {
    settings.threads = 1;
    core::Simulator sim(model, settings);
    run(sim, steps, one);
  }
  {
    settings.threads = 2;
    core::Simulator sim(model, settings);
    run(sim, steps, two);
  }
  expect_same(one, two, "1 against 2 threads");
  {
    settings.threads = 0;
    core::Simulator sim(model, settings);
    run(sim, steps, governed);
  }
  expect_same(one, governed, "1 thread against the governor");
  // The governor probes a second count early in a run, whatever the timings.
  if (steps > 2 * core::ThreadGovernor::kFirstProbe + core::ThreadGovernor::kProbeSteps) {
    EXPECT_EQ(governed.threads.size(), 2u) << "the governed run should have used both counts";
  }
}

io::Scene shipped(const std::string& file) {
  return io::load_scene(std::string(FIBERFEM_SOURCE_DIR) + "/configs/scenes/" + file);
}

TEST(Parallel, ContractingHeartHasTheSameBitsOnOneAndTwoThreads) {
  const io::Scene heart = shipped("heart.yaml");
  expect_thread_count_invariant(heart.model, heart.settings, 80);
}

core::Model large_beam() {
  core::CantileverSpec spec;
  spec.box.size_m = {0.1, 0.01, 0.01};
  spec.box.cells = {60, 11, 10};  // 39,600 tets, 8,784 nodes: 25,740 free rows (> 20,000)
  spec.damping.mass_1_s = 1.0;
  return core::make_cantilever(spec);
}

TEST(Parallel, LargeBeamHasTheSameBitsOnOneAndTwoThreads) {
  core::SimulatorSettings s;  // PCG, lagged Cholesky, eight recycled solutions: the block paths
  s.solver.tolerance = 1e-6;
  expect_thread_count_invariant(large_beam(), s, 8);
}

TEST(Parallel, CheckpointTakenOnTwoThreadsResumesOnOne) {
  const io::Scene heart = shipped("heart.yaml");
  core::SimulatorSettings s = heart.settings;
  s.threads = 2;
  core::Simulator whole(heart.model, s);
  Trace head, tail, again;
  run(whole, 12, head);
  const core::SimulatorCheckpoint c = whole.checkpoint();
  run(whole, 10, tail);
  s.threads = 1;
  core::Simulator resumed(heart.model, s);
  resumed.restore(c);
  run(resumed, 10, again);
  expect_same(tail, again, "resumed on 1 thread");
}

TEST(Parallel, AmgHasTheSameBitsOnOneAndTwoThreads) {
  if (!core::has_amg()) GTEST_SKIP() << "built without AMGCL";
  core::SimulatorSettings s;
  s.solver.preconditioner = core::PreconditionerKind::amg;
  s.solver.tolerance = 1e-6;
  expect_thread_count_invariant(large_beam(), s, 6);
}

// OpenBLAS opened to the engine's threads around one call goes back to its count after it,
// also when the call throws (a factorisation that runs out of memory must not leave BLAS
// spinning beside every later loop); and it is only ever raised, never lowered.
TEST(Parallel, BlasThreadsAreRaisedForOneCallAndRestored) {
  const int start = core::blas::threads();
  if (start == 0) GTEST_SKIP() << "the BLAS linked is not OpenBLAS";
  core::blas::set_threads(1);
  const int wanted = std::min(2, omp_get_num_procs());
  int inside = 0;
  core::blas::with_threads(2, [&] { inside = core::blas::threads(); });
  EXPECT_EQ(inside, wanted);
  EXPECT_EQ(core::blas::threads(), 1);
  EXPECT_THROW(core::blas::with_threads(2, [] { throw std::runtime_error("out of memory"); }), std::runtime_error);
  EXPECT_EQ(core::blas::threads(), 1);
  if (wanted == 2) {
    core::blas::set_threads(2);
    core::blas::with_threads(1, [&] { inside = core::blas::threads(); });
    EXPECT_EQ(inside, 2) << "lowered";
  }
  core::blas::set_threads(start);
}

}  // namespace
}  // namespace fiberfem
