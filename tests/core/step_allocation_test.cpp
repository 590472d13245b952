// The steady step allocates nothing (issue 6: "no allocation in the step"). This test
// executable interposes malloc, calloc, realloc, posix_memalign, aligned_alloc and
// memalign (glibc: the definitions here take precedence over libc's for every library in
// the process, CHOLMOD and OpenMP's included) and counts the calls made while a step runs.
// A step that refactorises the preconditioner or retries with substeps is allowed to
// allocate (CHOLMOD's numeric factorisation takes workspace); every other step must not.

#include "core/amg_preconditioner.hpp"
#include "core/builtin_scenes.hpp"
#include "core/simulator.hpp"
#include "test_support.hpp"

#include <atomic>
#include <cstddef>
#include <cstdlib>

extern "C" {
void* __libc_malloc(size_t);
void* __libc_calloc(size_t, size_t);
void* __libc_realloc(void*, size_t);
void* __libc_memalign(size_t, size_t);
}

namespace {
std::atomic<bool> g_counting{false};
std::atomic<long> g_allocations{0};
inline void count() {
  if (g_counting.load(std::memory_order_relaxed)) g_allocations.fetch_add(1, std::memory_order_relaxed);
}
}  // namespace

extern "C" {
void* malloc(size_t n) {
  count();
  return __libc_malloc(n);
}
void* calloc(size_t n, size_t m) {
  count();
  return __libc_calloc(n, m);
}
void* realloc(void* p, size_t n) {
  count();
  return __libc_realloc(p, n);
}
void* memalign(size_t a, size_t n) {
  count();
  return __libc_memalign(a, n);
}
void* aligned_alloc(size_t a, size_t n) {
  count();
  return __libc_memalign(a, n);
}
int posix_memalign(void** p, size_t a, size_t n) {
  count();
  *p = __libc_memalign(a, n);
  return *p ? 0 : 12;  // ENOMEM
}
}

namespace core = fiberfem::core;

namespace {

struct Tally {
  int steady = 0;        // steps without a factorisation or retry
  long steady_allocations = 0;
  int other = 0;
};

// Steps `n` times and counts the allocations of the steady steps.
Tally count_steps(core::Simulator& sim, int n) {
  Tally t;
  for (int i = 0; i < n; ++i) {
    g_allocations = 0;
    g_counting = true;
    const core::StepReport r = sim.step();
    g_counting = false;
    EXPECT_NE(r.status, core::StepStatus::failed) << r.message;
    if (r.solver_factorizations == 0 && r.attempts == 1) {
      ++t.steady;
      t.steady_allocations += g_allocations;
      EXPECT_EQ(g_allocations, 0) << "step " << i << " allocated " << g_allocations << " times";
    } else {
      ++t.other;
    }
  }
  return t;
}

core::Model paper_beam() {
  core::CantileverSpec spec;
  spec.box.size_m = {0.1, 0.01, 0.01};
  spec.box.cells = {48, 5, 4};  // 5,760 tets, the paper's size
  spec.damping.mass_1_s = 1.0;
  return core::make_cantilever(spec);
}

}  // namespace

// The interposition works: an allocation while counting is seen (else the test below
// would pass vacuously).
TEST(StepAllocation, CounterSeesAllocations) {
  g_allocations = 0;
  g_counting = true;
  void* volatile p = std::malloc(64);
  auto* v = new std::vector<double>(1000);
  g_counting = false;
  std::free(p);
  delete v;
  EXPECT_GE(g_allocations.load(), 2);
}

TEST(StepAllocation, SteadyStepsOfThePaperBeamAllocateNothing) {
  core::Simulator sim(paper_beam(), core::SimulatorSettings{});
  for (int i = 0; i < 5; ++i) sim.step();  // first-use allocations (sizes, thread pools)
  const Tally t = count_steps(sim, 60);
  EXPECT_GE(t.steady, 30) << "too few steady steps to mean anything";
  EXPECT_EQ(t.steady_allocations, 0);
}

// On one thread (what the thread governor picks beside a busy core) the engine's loops
// open no OpenMP region: libgomp would allocate a team of one for each.
TEST(StepAllocation, SteadyStepsOnOneThreadAllocateNothing) {
  core::SimulatorSettings s;
  s.threads = 1;
  core::Simulator sim(paper_beam(), s);
  for (int i = 0; i < 5; ++i) sim.step();
  const Tally t = count_steps(sim, 60);
  EXPECT_GE(t.steady, 30);
  EXPECT_EQ(t.steady_allocations, 0);
}

TEST(StepAllocation, SteadyStepsWithContractionAndDampingAllocateNothing) {
  core::Model m = paper_beam();
  m.contraction.region_peak_pa.assign(m.region_materials.size(), 2000.0);
  m.region_damping.assign(m.region_materials.size(), core::RayleighDamping{1.0, 0.01});
  m.validate();
  core::SimulatorSettings s;
  s.rotation = core::RotationMethod::svd;
  core::Simulator sim(std::move(m), s);
  for (int i = 0; i < 5; ++i) sim.step();
  const Tally t = count_steps(sim, 60);
  EXPECT_GE(t.steady, 30);
  EXPECT_EQ(t.steady_allocations, 0);
}

TEST(StepAllocation, SteadyStepsWithBlockJacobiAllocateNothing) {
  core::SimulatorSettings s;
  s.solver.preconditioner = core::PreconditionerKind::block_jacobi;
  s.solver.max_iterations = 2000;
  core::CantileverSpec spec;
  spec.box.cells = {12, 2, 2};
  spec.damping.mass_1_s = 1.0;
  core::Simulator sim(core::make_cantilever(spec), s);
  for (int i = 0; i < 5; ++i) sim.step();
  const Tally t = count_steps(sim, 30);
  EXPECT_GE(t.steady, 20);
  EXPECT_EQ(t.steady_allocations, 0);
}

// The amg preconditioner's V-cycle works in the hierarchy's own vectors: steady steps
// (no setup) allocate nothing either.
TEST(StepAllocation, SteadyStepsWithAmgAllocateNothing) {
  if (!core::has_amg()) GTEST_SKIP() << "built without AMGCL";
  core::SimulatorSettings s;
  s.solver.preconditioner = core::PreconditionerKind::amg;
  s.solver.refresh_iterations = 32;
  // Two threads, fixed: AMGCL opens its own OpenMP regions, and libgomp allocates a team
  // for every region of one thread, so a one-thread step with amg (which the thread
  // governor may choose) allocates; the engine's own loops open no region on one thread.
  s.threads = 2;
  core::Simulator sim(paper_beam(), s);
  for (int i = 0; i < 5; ++i) sim.step();
  const Tally t = count_steps(sim, 60);
  EXPECT_GE(t.steady, 30);
  EXPECT_EQ(t.steady_allocations, 0);
}
